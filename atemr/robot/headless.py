"""Headless runs of the whole robot in simulation (``atemr sim --headless``, ``atemr mission run``).

A headless robot runs on a `SimClock` as fast as the CPU allows, with no dashboard, no captive
portal, no control socket (nothing listens on a port or a socket, so it never collides with a robot
running beside it) and nothing published to a message queue, on a CAN channel of its own so several
runs in one process never hear each other.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from typing import Any

from atemr.clock import SimClock
from atemr.config import Config
from atemr.robot.assembly import build_robot
from atemr.robot.core import Robot

_RUNS = itertools.count()


def headless_config(config: Config) -> Config:
    """``config`` for a headless run: dashboard, message queue, portal and control socket off, a private
    virtual CAN channel, and a trace only when ``trace.file`` names one (``--trace``): headless runs do not
    fill ``data_dir/traces``."""
    if not config.simulation:
        raise ValueError("a headless run is a simulation")
    return dataclasses.replace(
        config,
        ui=dataclasses.replace(config.ui, enabled=False, message_queue=None),
        secondary=dataclasses.replace(config.secondary, portal_serve=False),
        trace=dataclasses.replace(config.trace, enabled=False),
        control=dataclasses.replace(config.control, enabled=False),
        can=dataclasses.replace(config.can, interface="virtual",
                                channel=f"{config.can.channel}-headless-{os.getpid()}-{next(_RUNS)}"),
    )


def build_headless_robot(config: Config) -> Robot:
    """The whole robot on a simulated clock, as fast as possible."""
    return build_robot(headless_config(config), realtime=False, clock=SimClock())


def agent_summary(robot: Robot) -> dict[str, Any]:
    """The agent's final state and its transitions, for a run's JSON report."""
    agent = robot.parts.get("agent")
    if agent is None:
        return {}
    return {
        "agent_state": agent.state,  # type: ignore[attr-defined]
        "agent_trace": [
            {"t": round(r.t, 3), "trigger": r.trigger, "source": r.source, "dest": r.dest,
             "accepted": r.accepted, "reason": r.reason}
            for r in agent.trace  # type: ignore[attr-defined]
        ],
    }
