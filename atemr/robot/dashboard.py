"""`add_dashboard`: the operator dashboard wired onto an assembled robot.

``build_robot`` calls it when ``ui.enabled``; tests call it on a robot built with the dashboard off.
"""

from __future__ import annotations

from atemr.robot.core import Robot
from atemr.robot.gateway import RobotGatewayImpl
from atemr.trees.ports import ComponentHealth
from atemr.ui.server import PUSH_RATE_HZ, DashboardServer
from atemr.ui.users import HASH_METHOD


def add_dashboard(robot: Robot, *, hash_method: str = HASH_METHOD) -> DashboardServer:
    """Build the gateway and the dashboard server, schedule the server at its push rate and register the
    ``webserver`` health probe (OK while the server is serving). Call before the robot starts."""
    gateway = RobotGatewayImpl(robot)
    server = DashboardServer(robot.config, gateway, clock=robot.clock, hash_method=hash_method,
                             map_store=gateway.store)
    robot.add(server, PUSH_RATE_HZ)
    robot.extras["gateway"] = gateway
    robot.extras["dashboard"] = server

    def probe(now: float) -> ComponentHealth:
        return ComponentHealth(True) if server.running else ComponentHealth(False, "the dashboard is not serving")

    robot.extras["health"].add("webserver", probe)
    return server


__all__ = ["add_dashboard"]
