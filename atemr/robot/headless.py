"""Headless runs of the whole robot in simulation (``atemr sim --headless``, ``atemr mission run``).

A headless robot runs on a `SimClock` as fast as the CPU allows, with no dashboard, no captive
portal, no control socket (nothing listens on a port or a socket, so it never collides with a robot
running beside it) and nothing published to a message queue, on a CAN channel of its own so several
runs in one process never hear each other.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
from collections.abc import Callable
from typing import Any

import numpy as np

from atemr.clock import SimClock
from atemr.config import Config
from atemr.robot.assembly import build_robot
from atemr.robot.core import Robot

_RUNS = itertools.count()


def headless_config(config: Config) -> Config:
    """``config`` for a headless run: dashboard, Foxglove server, message queue, portal and control socket off, a
    private virtual CAN channel, and a recording only when ``trace.file`` names one (``--trace``): headless runs
    do not fill ``data_dir/traces``."""
    if not config.simulation:
        raise ValueError("a headless run is a simulation")
    return dataclasses.replace(
        config,
        ui=dataclasses.replace(config.ui, enabled=False, message_queue=None,
                               foxglove=dataclasses.replace(config.ui.foxglove, enabled=False)),
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
    agent = robot.components.get("agent")
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


class TruthWatch:
    """What a simulated run did against ground truth: pose error, collisions, falls, localization events.

    `atemr mission run` wraps the scheduler's ``step`` with `wrap`; every ``period_s`` of simulated time
    the localized map pose (what the navigator steers by) is compared with the simulator's true pose.
    Samples while the robot is not localized are counted, not compared (there is no estimate to judge).
    ``kidnap`` (seconds after the watch starts, pose) teleports the robot then, as the simulation panel
    does: the covariance monitor has to notice it and the localizer has to find the robot again.
    """

    def __init__(self, robot: Robot, *, period_s: float = 0.1, kidnap: tuple[float, Any] | None = None) -> None:
        sim, localization = robot.parts.sim, robot.parts.localization
        if sim is None or localization is None:
            raise ValueError("watching ground truth needs the simulated robot with localization")
        self.sim = sim
        self.localization = localization
        self.clock = robot.clock
        self.period_s = period_s
        self.t0 = robot.clock.now()
        self._next = self.t0
        self._collisions0 = len(sim.collisions)
        self._errors: list[tuple[float, float]] = []  # (position error m, heading error rad)
        self._unlocalized = 0
        self._events: list[dict[str, Any]] = []
        self._lowest: float | None = None  # the lowest confidence sampled
        self._kidnap = kidnap
        self.kidnapped_at: float | None = None

    def wrap(self, step: Callable[[], float]) -> Callable[[], float]:
        """``step`` followed by a look at the truth when a sample (or the kidnapping) is due."""
        def watched() -> float:
            due = step()
            now = self.clock.now()
            if self._kidnap is not None and self.kidnapped_at is None and now - self.t0 >= self._kidnap[0]:
                self.sim.kidnap(self._kidnap[1])
                self.kidnapped_at = now
            if now >= self._next:
                self._next = now + self.period_s
                self.sample()
            return due
        return watched

    def sample(self) -> None:
        estimate = self.localization.map_pose()
        confidence = self.localization.confidence
        self._lowest = confidence if self._lowest is None else min(self._lowest, confidence)
        for event in self.localization.drain_events():
            self._events.append({"t": round(event.t, 3), "kind": event.kind, "detail": event.detail})
        if estimate is None:
            self._unlocalized += 1
            return
        truth = self.sim.pose
        yaw = math.atan2(math.sin(estimate.yaw_rad - truth.yaw_rad), math.cos(estimate.yaw_rad - truth.yaw_rad))
        self._errors.append((math.hypot(estimate.x_m - truth.x_m, estimate.y_m - truth.y_m), abs(yaw)))

    def report(self) -> dict[str, Any]:
        """The JSON part of a run's result: ``collisions`` (count and each), ``falls``, ``pose_error`` (RMSE and
        max of position and heading over the localized samples), ``localization`` (at the end: the confidence,
        its limit, localized, the state; and the lowest confidence sampled), ``localization_events``,
        ``kidnapped_s``."""
        errors = np.array(self._errors, dtype=np.float64).reshape(-1, 2)
        hits = self.sim.collisions[self._collisions0:]
        truth = self.sim.pose
        return {
            "collisions": len(hits),
            "collision_list": [{"t": round(c.t, 3), "what": c.what, "part": c.part, "x_m": round(c.pose.x_m, 3),
                                "y_m": round(c.pose.y_m, 3)} for c in hits],
            "falls": [{"t": round(f.t, 3), "zone": f.zone} for f in self.sim.falls],
            "true_pose": {"x_m": truth.x_m, "y_m": truth.y_m, "yaw_rad": truth.yaw_rad},
            "pose_error": {
                "samples": len(errors),
                "unlocalized_samples": self._unlocalized,
                "period_s": self.period_s,
                "rmse_m": float(np.sqrt(np.mean(errors[:, 0] ** 2))) if len(errors) else None,
                "max_m": float(errors[:, 0].max()) if len(errors) else None,
                "rmse_yaw_rad": float(np.sqrt(np.mean(errors[:, 1] ** 2))) if len(errors) else None,
            },
            "localization": {**self.localization.status.as_dict(),
                             "lowest_confidence": None if self._lowest is None else round(self._lowest, 4)},
            "localization_events": self._events,
            "kidnapped_s": self.kidnapped_at,
        }
