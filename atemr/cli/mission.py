"""``atemr mission validate FILE...``, ``atemr mission run``, ``atemr mission status`` and ``cancel``.

``validate`` checks missions and says whether this build can run them. ``run`` runs one mission (a file,
or ``--goal X,Y,YAW`` repeated) on the robot that is already running (``./run``; through its control socket,
`atemr.cli.mission_attach`) or, with ``--headless``, in a fresh headless simulation of the whole robot that
exits when the mission ends. Either way it prints the result (``--json``: outcome, each step's status,
time, final pose, position and heading error, and the agent's state trace; ``--headless`` adds the
simulator's ground truth: collisions, falls, the true final pose, the localization's pose error (RMSE, max)
and its events, see `atemr.robot.headless.TruthWatch`); the exit code is 0 only when the mission was
completed. ``status`` and ``cancel`` ask the running robot.

A mission is valid when its document is right (kinds, parameters, poses, timeouts) and every place it
names is on its map: ``--map``, else the map named by its ``world`` (the studio world's map is
``studio``), else the active map of the robot's data directory; a missing place is an error with the
closest names. Whether it can run here is a separate answer: a step whose behaviour this build lacks (a
plugin kind, or ``GoToPose`` in a build without it) is reported with the behaviour it needs; ``--strict``
makes that an error (exit 1).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from atemr.cli.arguments import kidnap_argument, pose_argument

if TYPE_CHECKING:  # only what runs a command imports what it needs: `atemr --help` stays fast
    from atemr.msgs import Pose2D
from atemr.errors import ConfigError


class MissionCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="mission_action", metavar="ACTION", required=True)
        validate = sub.add_parser("validate", help="check mission files; exit 2 on an error, with file:line:col")
        validate.add_argument("files", type=Path, nargs="+", metavar="FILE")
        validate.add_argument("--json", action="store_true", help="print one JSON report for all files")
        validate.add_argument("--strict", action="store_true",
                              help="exit 1 when a valid mission cannot run in this build (missing behaviours)")
        validate.add_argument("--map", help="check the places a mission names against this map (default: the "
                                            "mission's world, else the active map)")
        validate.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        validate.add_argument("--data-dir", type=Path, help="the robot's data directory, where its maps are "
                                                            "(default: from config)")
        run = sub.add_parser("run", help="run a mission on the running robot (or --headless: in a fresh "
                                         "simulation) and report how it went")
        run.add_argument("file", type=Path, nargs="?", metavar="FILE", help="mission file (or give --goal)")
        run.add_argument("--goal", action="append", type=pose_argument, default=[], metavar="X,Y,YAW",
                         help="visit this pose (map frame, metres and radians); repeat to visit several in order")
        run.add_argument("--start", type=pose_argument, metavar="X,Y,YAW",
                         help="--headless only: place the robot here first")
        run.add_argument("--world",
                         help="--headless only: simulated world, a shipped world's name or a world/map YAML")
        run.add_argument("--seed", type=int, help="--headless only: seed of the simulation's random sources")
        run.add_argument("--timeout", type=float, default=600.0, help="robot seconds before the mission is cancelled")
        run.add_argument("--headless", action="store_true",
                         help="run in a fresh simulation without the dashboard, instead of on the running robot")
        run.add_argument("--kidnap", type=kidnap_argument, metavar="T,X,Y,YAW",
                         help="--headless only: teleport the robot to X,Y,YAW T robot seconds after the start "
                              "(the localizer must notice and find it again)")
        run.add_argument("--json", action="store_true", help="print the full result as JSON")
        run.add_argument("--trace", type=Path, metavar="FILE",
                         help="--headless only: record the run to FILE, an MCAP recording (scans, odometry, IMU, "
                              "camera and depth frames, CAN, the agent's transitions, node statuses and blackboard; "
                              "see docs/recording.md): 'atemr trace show FILE', 'atemr replay FILE', the dashboard's "
                              "Agent page or Foxglove read it")
        _robot_options(run, headless=True)
        status = sub.add_parser("status", help="the running robot's agent: state, mode, task and its progress")
        status.add_argument("--json", action="store_true", help="print the full status as JSON")
        _robot_options(status)
        cancel = sub.add_parser("cancel", help="cancel the mission (or the dashboard's task) on the running robot")
        _robot_options(cancel)

    def run(self, args: argparse.Namespace) -> int:
        from atemr.trees.missions import load_mission

        if args.mission_action == "run":
            return run_command(args)
        if args.mission_action in ("status", "cancel"):
            from atemr.cli.mission_attach import cancel_command, status_command

            return status_command(args) if args.mission_action == "status" else cancel_command(args)
        reports: list[dict[str, Any]] = []
        worst = 0
        maps = _PlaceBook(args)
        for path in args.files:
            try:
                mission = load_mission(path)
                if mission.place_names():
                    name = maps.map_for(mission.world)
                    mission.check_places(maps.places(name), f"map {name}")
            except ConfigError as exc:
                reports.append({"file": str(path), "valid": False, "error": str(exc), "line": exc.line,
                                "column": exc.column, "path": exc.path})
                worst = 2
                continue
            report = {"valid": True, **mission.report()}
            reports.append(report)
            if not report["runnable"] and args.strict:
                worst = max(worst, 1)
        if args.json:
            print(json.dumps(reports if len(reports) > 1 else reports[0], indent=2))
            return worst
        for report in reports:
            if not report["valid"]:
                print(f"error: {report['error']}", file=sys.stderr)
                continue
            print(f"{report['file']}: OK, mission '{report['name']}', {len(report['steps'])} steps")
            blocked = [s for s in report["steps"] if not s["runnable"]]
            if blocked:
                steps = ", ".join(f"{s['index']} ({s['kind']}, line {s['line']})" for s in blocked)
                print(f"  not runnable in this build: needs {', '.join(report['missing_behaviours'])}; "
                      f"steps {steps}")
        return worst


def _robot_options(parser: argparse.ArgumentParser, *, headless: bool = False) -> None:
    """Where the running robot's control socket is: from the configuration, or given (``headless``: the run
    command, which can also build its own robot)."""
    parser.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
    also = " (with --headless: where captured images go)" if headless else ""
    parser.add_argument("--data-dir", type=Path,
                        help=f"the robot's data directory: its control socket is there{also}; default: from config")
    parser.add_argument("--socket", type=Path, help="the running robot's control socket (default: from config, "
                                                    "data_dir/control.sock)")


def run_command(args: argparse.Namespace) -> int:
    """``atemr mission run``: on the running robot, or build the simulated robot, place it, run the mission,
    report."""
    from atemr.config import load_config
    from atemr.fsm.agent import Agent
    from atemr.fsm.mission_run import run_mission
    from atemr.robot.headless import TruthWatch, build_headless_robot
    from atemr.trees.missions import load_mission, mission_from_goals

    if (args.file is None) == (not args.goal):
        raise ConfigError("give a mission FILE or one or more --goal X,Y,YAW (not both)", path="atemr mission run")
    if not args.headless:
        from atemr.cli.mission_attach import run_attached

        return run_attached(args)
    if args.socket is not None:
        raise ConfigError("--socket is for the running robot; a --headless run has no socket",
                          path="atemr mission run")
    mission = load_mission(args.file) if args.file is not None else mission_from_goals(args.goal)
    config = load_config(args.config, overrides={
        "simulation": True, "ui.enabled": False, "sim.world": args.world, "sim.seed": args.seed,
        "data_dir": args.data_dir, "trace.file": args.trace,
        # the run is this mission alone: no routine of the data directory starts or is written down in its history
        "agent.routines": False,
    })
    robot = build_headless_robot(config)  # no dashboard, no portal, a private CAN channel
    with robot:
        if args.start is not None:
            place(robot, args.start)
        agent = robot.components.get("agent")
        if not isinstance(agent, Agent):
            raise ConfigError("this robot has no agent wired", path="atemr mission run")
        watch = TruthWatch(robot, kidnap=args.kidnap)
        result = run_mission(agent, watch.wrap(robot.scheduler.step), mission, timeout_s=args.timeout)
        result.update(watch.report())
    result["world"] = config.sim.world
    result["seed"] = config.sim.seed
    writer = robot.parts.trace
    if writer is not None:
        result["trace_files"] = [str(p) for p in writer.parts]  # "trace" is the agent's state trace
        if writer.error:
            result["trace_error"] = writer.error
    if args.json:
        print(json.dumps(result, indent=2, default=str))
    else:
        print_summary(result)
    return 0 if result["outcome"] == "reached" else 1


def place(robot: Any, pose: Pose2D) -> None:
    """Teleport the simulated robot to ``pose`` and tell localization it is there (the operator's click)."""
    sim, localization = robot.parts.sim, robot.parts.localization
    if sim is None or localization is None:
        raise ConfigError("--start needs the simulated robot with localization", path="--start")
    try:
        sim.kidnap(pose)
    except ConfigError as exc:
        raise ConfigError(f"cannot start there: {exc.reason}", path="--start") from None
    localization.set_initial_pose(robot.clock.now(), pose)


def print_summary(result: dict[str, Any]) -> None:
    """A few readable lines: outcome, each step, where the robot ended."""
    print(f"mission '{result['mission']}': {result['outcome']}" + (f" ({result['reason']})" if result["reason"]
                                                                     else ""))
    for step in result["steps"]:
        took = "" if step["duration_s"] is None else f" in {step['duration_s']:.1f} s"
        errors = ""
        if step["position_error_m"] is not None:
            errors = f", {step['position_error_m']:.2f} m / {math.degrees(step['heading_error_rad']):.1f} deg off"
        print(f"  {step['index']}: {step['name']}: {step['status']}{took}{errors}")
    if result.get("trace_files"):
        print(f"  trace: {', '.join(result['trace_files'])}"
              + (f" ({result['trace_error']})" if result.get("trace_error") else ""))
    pose = result["final_pose"]
    if pose is not None:
        print(f"  final pose ({pose['x_m']:.2f}, {pose['y_m']:.2f}, {pose['yaw_rad']:.2f}); "
              f"state {result['state']}")
    else:
        print(f"  final pose unknown: not localized on the map; state {result['state']}")
    error = result.get("pose_error") or {}
    if error.get("rmse_m") is not None:
        print(f"  pose error against ground truth: RMSE {error['rmse_m']:.3f} m, max {error['max_m']:.3f} m; "
              f"collisions {result['collisions']}")


class _PlaceBook:
    """The maps whose places ``validate`` checks missions against, opened only when a mission names a place."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self._store: Any = None

    def store(self) -> Any:
        if self._store is None:
            from atemr.config import load_config
            from atemr.io.map_store import MapStore

            config = load_config(self.args.config, overrides={"data_dir": self.args.data_dir})
            self._store = MapStore(config.data_dir)
        return self._store

    def map_for(self, world: str | None) -> str:
        """``--map``, else the mission's world when the store has a map of that name, else the active map."""
        store = self.store()
        if self.args.map is not None:
            return str(self.args.map)
        if world is not None and store.exists(world):
            return world
        active = store.active_name()
        if active is None:
            raise ConfigError("the mission names places and there is no map to find them on: give --map",
                              path="atemr mission validate")
        return str(active)

    def places(self, name: str) -> Any:
        return self.store().places(name)
