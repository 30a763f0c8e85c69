"""The operator dashboard wired onto an assembled robot: `add_dashboard` (a web server of its own) or
`add_state_publisher` (no web server; the state goes into ``ui.message_queue`` for other dashboards).

``build_robot`` calls the first when ``ui.enabled``, the second when the dashboard is off but a message
queue is set; tests call them on a robot built with both off.
"""

from __future__ import annotations

from dataclasses import replace

from atemr.domain.status import ComponentHealth
from atemr.robot.core import Robot
from atemr.robot.gateway import RobotGatewayImpl
from atemr.ui.message_queue import StatePublisher
from atemr.ui.server import PUSH_RATE_HZ, DashboardServer
from atemr.ui.users import HASH_METHOD


def add_dashboard(robot: Robot, *, hash_method: str = HASH_METHOD) -> DashboardServer:
    """Build the gateway and the dashboard server, schedule the server at its push rate and register the
    ``webserver`` health probe (OK while the server is serving). Call before the robot starts."""
    gateway = RobotGatewayImpl(robot)
    server = DashboardServer(robot.config, gateway, clock=robot.clock, hash_method=hash_method,
                             map_store=gateway.store)
    robot.add(server, PUSH_RATE_HZ)
    robot.parts = replace(robot.parts, gateway=gateway, dashboard=server)

    def probe(now: float) -> ComponentHealth:
        return ComponentHealth(True) if server.running else ComponentHealth(False, "the dashboard is not serving")

    robot.parts.health.add("webserver", probe)
    return server


def add_state_publisher(robot: Robot, url: str) -> StatePublisher:
    """Publish the robot's state into the message queue at ``url`` at the dashboard's push rate, for the
    dashboard workers on that queue; the ``webserver`` health probe is OK while the publisher runs (this
    robot serves no page itself). Call before the robot starts."""
    gateway = RobotGatewayImpl(robot)
    publisher = StatePublisher(url, gateway)
    robot.add(publisher, PUSH_RATE_HZ)
    robot.parts = replace(robot.parts, gateway=gateway, state_publisher=publisher)

    def probe(now: float) -> ComponentHealth:
        if publisher.running:
            return ComponentHealth(True, "no dashboard here: the state goes to the message queue")
        return ComponentHealth(False, "the state publisher is not running")

    robot.parts.health.add("webserver", probe)
    return publisher


__all__ = ["add_dashboard", "add_state_publisher"]
