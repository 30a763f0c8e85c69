"""``atemr replay FILE --slam [--save-map NAME]`` / ``atemr replay FILE --localize --map NAME``: a recording fed
back into SLAM or localization (`atemr.robot.replay`), to tune them on what the robot really saw.

``--slam`` rebuilds the map of the recording's mapping session (``--all-scans``: from every scan) with the
configured ``mapping`` parameters and prints its size (and, for a simulated run, how it agrees with the world's
map); ``--save-map NAME`` stores it in the data directory's maps. ``--localize`` re-runs odometry and AMCL on
map ``NAME`` and prints the pose error against the recorded pose and, when the recording came from the
simulator, against the ground truth. ``--speed X`` paces the replay at X times the recorded time (default: as
fast as possible); a progress bar goes to stderr. Exit 1 when the file was damaged (read up to the damage).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from atemr.cli.command import report_and_warn
from atemr.clock import WallClock
from atemr.errors import ConfigError


class ReplayCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("file", type=Path, metavar="FILE", help="an MCAP recording (data_dir/traces, --trace)")
        what = parser.add_mutually_exclusive_group(required=True)
        what.add_argument("--slam", action="store_true", help="rebuild the map from the scans, odometry and IMU")
        what.add_argument("--localize", action="store_true", help="re-run localization on --map NAME")
        parser.add_argument("--save-map", metavar="NAME", help="--slam: store the map as NAME")
        parser.add_argument("--all-scans", action="store_true",
                            help="--slam: map every scan, not only the recording's mapping session")
        parser.add_argument("--map", metavar="NAME", help="--localize: the stored map to localize on")
        parser.add_argument("--speed", type=float, metavar="X",
                            help="replay at X times the recorded pace (default: as fast as possible)")
        parser.add_argument("--json", action="store_true", help="print the result as JSON")
        parser.add_argument("--config", type=Path, help="YAML configuration (the mapping/localization parameters)")
        parser.add_argument("--data-dir", type=Path, help="where maps are read and saved (default: from config)")

    def run(self, args: argparse.Namespace) -> int:
        from atemr.config import load_config
        from atemr.io.map_store import MapStore
        from atemr.robot.replay import Replay, replay_slam

        if args.speed is not None and not args.speed > 0:
            raise ConfigError(f"must be a number > 0, got {args.speed}", path="--speed")
        if args.localize and not args.map:
            raise ConfigError("--localize needs the map to localize on: give --map NAME", path="--map")
        if args.save_map is not None and not args.slam:
            raise ConfigError("goes with --slam", path="--save-map")
        config = load_config(args.config, overrides={"data_dir": args.data_dir})
        store = MapStore(config.data_dir)
        if args.save_map is not None:  # before the replay, which may take minutes
            new_map_name(store, args.save_map)
        bar = ProgressBar(sys.stderr)
        options: dict[str, Any] = {"progress": bar.update, "pace": Pacer(args.speed) if args.speed else None}
        if args.slam:
            result = replay_slam(args.file, config.localization.slam_params(), all_scans=args.all_scans, **options)
        else:
            try:
                grid = store.load(args.map)
            except ConfigError as exc:
                if exc.path != "map.name":
                    raise
                raise ConfigError(exc.reason, path="--map") from None
            result = Replay(args.file, grid=grid, localizer=config.localization.localizer_params(),
                            seed=config.localization.seed, **options).run()
        bar.done()
        report = summary(result)
        if args.slam and args.save_map:
            assert result.grid is not None
            report["saved_as"] = store.save(args.save_map, result.grid, activate=False)
        return report_and_warn(report, as_json=args.json, printer=print_report, warnings=result.warnings)


def new_map_name(store: Any, name: str) -> str:
    """``name`` as ``--save-map`` takes it: a map name the store keeps as given (not one it would change: "my map"
    would have been saved as my_map, and "" nowhere) that no stored or built-in map has."""
    try:
        clean = store.name_to_save(name)
    except ConfigError as exc:
        raise ConfigError(exc.reason, path="--save-map") from None
    if clean != name:
        raise ConfigError(f"{name!r} is not a map name: use 1-64 letters, digits, '.', '_' or '-', starting with a "
                          f"letter or digit (for example {clean!r})", path="--save-map")
    return name


def summary(result: Any) -> dict[str, Any]:
    """The JSON report of a replay."""
    report: dict[str, Any] = {"file": str(result.file), "messages": result.messages, "scans": result.scans,
                              "start_t": result.start_t, "end_t": result.end_t}
    if result.grid is not None:
        grid = result.grid
        report["map"] = {"width": grid.width, "height": grid.height, "resolution_m": grid.resolution_m,
                         "occupied_cells": int(grid.occupied.sum()), "slam_updates": result.slam_updates,
                         "sessions": result.sessions}
    else:
        report["localized_scans"] = result.localized_scans
        report["pose_error_vs_recorded"] = result.against_recorded.report()
        report["pose_error_vs_ground_truth"] = result.against_truth.report()
    return report


def print_report(report: dict[str, Any]) -> None:
    span = "" if report["start_t"] is None else f", {report['start_t']:.1f}-{report['end_t']:.1f} s"
    print(f"{report['file']}: {report['messages']} messages, {report['scans']} scans{span}")
    if "map" in report:
        m = report["map"]
        print(f"  map {m['width']} x {m['height']} cells at {m['resolution_m']} m, {m['occupied_cells']} occupied, "
              f"{m['slam_updates']} SLAM updates" + (f"; saved as {report['saved_as']}" if "saved_as" in report
                                                      else ""))
        return
    print(f"  localized at {report['localized_scans']} scans")
    for name, key in (("recorded pose", "pose_error_vs_recorded"), ("ground truth", "pose_error_vs_ground_truth")):
        err = report[key]
        if err["samples"]:
            print(f"  against the {name}: RMSE {err['rmse_m']:.3f} m, max {err['max_m']:.3f} m, "
                  f"heading RMSE {err['rmse_yaw_rad']:.3f} rad ({err['samples']} samples)")


class ProgressBar:
    """A one-line bar on a terminal (nothing when the stream is not one), at most ten redraws a second."""

    def __init__(self, stream: Any, width: int = 30) -> None:
        self.stream = stream
        self.width = width
        self.enabled = bool(getattr(stream, "isatty", lambda: False)())
        self._clock = WallClock()
        self._last = float("-inf")

    def update(self, share: float, t: float) -> None:
        now = self._clock.now()
        if not self.enabled or now - self._last < 0.1:
            return
        self._last = now
        filled = round(self.width * min(max(share, 0.0), 1.0))
        self.stream.write(f"\r[{'#' * filled}{' ' * (self.width - filled)}] {share:4.0%}  t = {t:.1f} s")
        self.stream.flush()

    def done(self) -> None:
        if self.enabled:
            self.stream.write("\n")


class Pacer:
    """Waits so that recorded time passes ``speed`` times faster than wall time."""

    def __init__(self, speed: float) -> None:
        self.speed = speed
        self._clock = WallClock()
        self._origin: float | None = None

    def __call__(self, t: float) -> None:
        if self._origin is None:
            self._origin = t
        self._clock.sleep_until((t - self._origin) / self.speed)
