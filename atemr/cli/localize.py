"""``atemr localize --world W [--seed N] --true-pose X,Y,YAW [--json]``: FIND POSITION on the simulated robot.

The whole robot (CAN motors, secondary core, agent, localization) starts headless in the world as usual, on its
map, localized at the world's start. Then, within one instant, the simulator puts it at ``--true-pose``
without telling it, and global localization is started exactly as the dashboard's FIND POSITION starts it
(`Localizer.start_global`); the robot runs until the search has answered. An ambiguous answer turns the robot in
place, as FIND POSITION does (at most one revolution, `DriveJoystick`), and the robot runs on until the turn
has decided or ended. The answer:

    {"outcome": "localized" | "ambiguous" | "failed", "pose", "confidence", "candidates", "error_m", "error_rad",
     "reason", "true_pose", "world", "seed", "sim_seconds"}

``pose`` only when localized; ``candidates`` the places considered (for ambiguous: the ones it cannot tell
apart), each with its agreement and its error; the errors come from the simulator's ground truth. Exit code:
0 localized, 1 ambiguous or failed (the robot does not know where it is), 2 on a bad argument.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from atemr.cli.arguments import pose_argument
from atemr.cli.command import commands
from atemr.errors import ConfigError

if TYPE_CHECKING:  # only what runs a command imports what it needs: `atemr --help` stays fast
    from atemr.msgs import Pose2D

#: Robot seconds the robot runs on its map before it is moved (sensors, odometry and the agent come up).
SETTLE_S = 1.0
#: States in which a search has answered.
ANSWERED = ("localized", "ambiguous", "failed")


class LocalizeCommand:
    help = "put the simulated robot somewhere without telling it, run FIND POSITION, report what it found"

    def configure(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--world", help="simulated world: a shipped world's name or a world/map YAML "
                                            "(default: from config, studio)")
        parser.add_argument("--seed", type=int, help="seed of the simulation's random sources")
        parser.add_argument("--true-pose", type=pose_argument, required=True, metavar="X,Y,YAW",
                            help="where the robot really is (map frame, metres and radians)")
        parser.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        parser.add_argument("--timeout", type=float, default=30.0,
                            help="robot seconds to wait for the answer (a look around takes up to 16)")
        parser.add_argument("--json", action="store_true", help="print the result as JSON")

    def run(self, args: argparse.Namespace) -> int:
        result = localize(args.true_pose, world=args.world, seed=args.seed, config_file=args.config,
                          timeout_s=args.timeout)
        if args.json:
            print(json.dumps(result, indent=2))
        else:
            print_summary(result)
        return 0 if result["outcome"] == "localized" else 1


commands.add("localize", LocalizeCommand())


def _error(pose: Pose2D, truth: Pose2D) -> tuple[float, float]:
    return (round(math.hypot(pose.x_m - truth.x_m, pose.y_m - truth.y_m), 4),
            round(abs(math.remainder(pose.yaw_rad - truth.yaw_rad, 2 * math.pi)), 4))


def _pose(pose: Pose2D) -> dict[str, float]:
    return {"x_m": round(pose.x_m, 4), "y_m": round(pose.y_m, 4), "yaw_rad": round(pose.yaw_rad, 4)}


def localize(truth: Pose2D, *, world: str | None = None, seed: int | None = None, config_file: Path | None = None,
             timeout_s: float = 30.0) -> dict[str, Any]:
    """Run FIND POSITION on the headless simulated robot put at ``truth``; the JSON-able result (module
    docstring)."""
    from atemr.config import load_config
    from atemr.robot.headless import build_headless_robot

    if not (math.isfinite(timeout_s) and timeout_s > 0):
        raise ConfigError(f"must be a positive number of seconds, got {timeout_s!r}", path="--timeout")
    config = load_config(config_file, overrides={"simulation": True, "ui.enabled": False, "sim.world": world,
                                                 "sim.seed": seed, "sim.camera_hz": 0.0})
    robot = build_headless_robot(config)
    with robot:
        sim, localization = robot.parts.sim, robot.parts.localization
        if sim is None:
            raise ConfigError("atemr localize needs the simulated robot", path="atemr localize")
        robot.run(until=SETTLE_S)
        try:
            sim.kidnap(truth)
        except ConfigError as exc:
            raise ConfigError(f"cannot put the robot there: {exc.reason}", path="--true-pose") from None
        started = robot.clock.now()
        localization.start_global(started, "requested by the operator (atemr localize)", look_around=True)
        while ((localization.state not in ANSWERED or localization.wants_a_look)
               and robot.clock.now() < started + timeout_s):
            robot.run(until=robot.clock.now() + 0.1)
        truth = sim.pose  # as the simulator has it now (the robot may have turned to look)
        localizer = localization.localizer
        result = None if localizer is None else localizer.result
        pose = localization.map_pose() if localization.localized else None
        places = result.candidates if result is not None and localization.state != "localized" else ()
        error = _error(pose, truth) if pose is not None else (None, None)
        return {
            "outcome": localization.state if localization.state in ANSWERED else "failed",
            "pose": None if pose is None else _pose(pose),
            "confidence": round(localization.confidence, 4),
            "limit": localization.min_confidence,
            "candidates": [{**_pose(h.pose), "agreement": round(h.agreement, 4),
                            **dict(zip(("error_m", "error_rad"), _error(h.pose, truth), strict=True))}
                           for h in places],
            "error_m": error[0],
            "error_rad": error[1],
            "reason": (result.reason if result is not None else
                       f"no answer within {timeout_s:g} s (state {localization.state})"),
            "true_pose": _pose(truth),
            "world": config.sim.world,
            "seed": config.sim.seed,
            "sim_seconds": round(robot.clock.now() - started, 3),
        }


def print_summary(result: dict[str, Any]) -> None:
    print(f"{result['outcome']} (confidence {result['confidence']:.0%}, needs {result['limit']:.0%}): "
          f"{result['reason']}")
    if result["pose"] is not None:
        p = result["pose"]
        print(f"  pose ({p['x_m']:.2f}, {p['y_m']:.2f}, {p['yaw_rad']:.2f}); error {result['error_m']:.3f} m, "
              f"{math.degrees(result['error_rad']):.1f}°")
    for c in result["candidates"]:
        print(f"  candidate ({c['x_m']:.2f}, {c['y_m']:.2f}, {c['yaw_rad']:.2f}) {c['agreement']:.0%} of the scan; "
              f"{c['error_m']:.2f} m, {math.degrees(c['error_rad']):.0f}° from the truth")
    t = result["true_pose"]
    print(f"  truth ({t['x_m']:.2f}, {t['y_m']:.2f}, {t['yaw_rad']:.2f}) in {result['world']}, seed {result['seed']}")
