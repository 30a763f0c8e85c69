"""``atemr hw check | echo | emulate``: the robot's hardware from the console.

``check`` opens every configured device and prints one row each (driver, port, model or firmware, the
rate measured over 2 s, health, and what to do about a missing device); it exits 1 when a critical device
is missing. ``echo DEVICE`` prints readings as JSON lines, like ``ros2 topic echo``. ``emulate`` serves
byte-level emulators of the serial devices on pseudo-terminals, fed by a simulated world, and prints a
configuration that points at them.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # only what runs a command imports what it needs: `atemr --help` stays fast
    from atemr.config import Config
from atemr.errors import ConfigError
from atemr.io.devices.config import SIMULATED_DRIVERS

SENSORS = ("lidar", "imu", "camera", "depth")


def range_json(r: float) -> float | str | None:
    """One lidar beam as JSON, keeping what REP 117's non-finite values say (JSON has no infinities): metres,
    ``"inf"`` for a return beyond the range, ``"-inf"`` for one closer than the minimum, ``null`` for no return
    (NaN). ``ros2 topic echo`` prints them ``.inf``, ``-.inf`` and ``.nan``."""
    if math.isfinite(r):
        return round(r, 4)
    if math.isnan(r):
        return None
    return "inf" if r > 0 else "-inf"


def reading_json(kind: str, reading: Any, t: float) -> dict[str, Any]:
    """One reading as ``hw echo`` prints it (the fields: docs/real-robot.md#check-start-power-off)."""
    if kind == "lidar":
        return {"t": round(reading.t, 6), "angle_min": reading.angle_min_rad,
                "angle_increment": reading.angle_increment_rad,
                "ranges": [range_json(float(r)) for r in reading.ranges_m]}
    if kind == "imu":
        return {"t": round(reading.t, 6), "yaw_rate_radps": reading.yaw_rate_radps,
                "acc_mps2": [reading.accel_x_mps2, reading.accel_y_mps2, reading.accel_z_mps2]}
    if kind == "depth":  # a frame is 100 000 readings: what a person checks a depth camera by
        import numpy as np

        seen = reading.depth_m[reading.depth_m > 0]
        height, width = reading.depth_m.shape
        return {"t": round(reading.t, 6), "width": int(width), "height": int(height),
                "valid": round(seen.size / max(1, reading.depth_m.size), 4),
                "min_m": round(float(seen.min()), 3) if seen.size else None,
                "median_m": round(float(np.median(seen)), 3) if seen.size else None,
                "max_m": round(float(seen.max()), 3) if seen.size else None,
                "fx": reading.fx, "fy": reading.fy, "cx": reading.cx, "cy": reading.cy}
    height, width = reading.shape[:2]
    mean = reading.reshape(-1, reading.shape[2]).mean(axis=0)
    return {"t": round(t, 6), "width": int(width), "height": int(height),
            "mean_rgb": [round(float(v), 2) for v in mean[:3]]}


class HwCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="hw_action", metavar="ACTION", required=True)
        check = sub.add_parser("check", help="open every configured device and say what answers (exit 1 when a "
                                             "critical device is missing)")
        check.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        check.add_argument("--seconds", type=float, default=2.0, help="how long each device is read (default 2)")
        check.add_argument("--json", action="store_true", help="print one JSON document")
        echo = sub.add_parser("echo", help="print a device's readings as JSON lines")
        echo.add_argument("device", choices=SENSORS)
        echo.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        echo.add_argument("--count", type=int, help="stop after this many readings (default: until Ctrl-C)")
        echo.add_argument("--timeout", type=float, default=10.0,
                          help="give up after this many seconds without a reading (default 10)")
        echo.add_argument("--json", action="store_true", help="JSON lines (the default and only format)")
        emulate = sub.add_parser("emulate", help="serve an RPLidar and a WT901 on pseudo-terminals, fed by a "
                                                 "simulated world, and print a configuration that uses them")
        emulate.add_argument("--world", default="studio", help="simulated world (default studio)")
        emulate.add_argument("--seed", type=int, default=0, help="seed of the simulation (default 0)")
        emulate.add_argument("--duration", type=float, help="stop after this many seconds (default: until Ctrl-C)")
        emulate.add_argument("--config-out", type=Path, help="also write the printed configuration to this file")

    def run(self, args: argparse.Namespace) -> int:
        if args.hw_action == "check":
            return check_command(args)
        if args.hw_action == "echo":
            return echo_command(args)
        from atemr.cli.hw_emulate import emulate_command

        return emulate_command(args)


def _config(args: argparse.Namespace) -> Config:
    from atemr.config import load_config

    return load_config(args.config, overrides={"log_level": args.log_level})


def check_command(args: argparse.Namespace) -> int:
    """``atemr hw check``: one row per device; exit 1 when a critical one is missing."""
    from atemr.io.devices.check import check_devices, missing_critical

    config = _config(args)
    rows = check_devices(config, seconds=args.seconds)
    missing = missing_critical(rows)
    if args.json:
        print(json.dumps({"ok": not missing, "devices": [r.as_dict() for r in rows]}, indent=2))
    else:
        for row in rows:
            print(row.line())
        if missing:
            print(f"{len(missing)} critical device(s) missing: {', '.join(r.device for r in missing)}")
    return 1 if missing else 0


def echo_command(args: argparse.Namespace) -> int:
    """``atemr hw echo DEVICE``: the device's readings as JSON lines."""
    from atemr.clock import WallClock
    from atemr.io.devices.drivers import DeviceContext, build_device, driver_name

    config = _config(args)
    kind = args.device
    driver = driver_name(config, kind)
    if driver in SIMULATED_DRIVERS:
        raise ConfigError(f"the {kind}'s driver is '{driver}': hw echo reads a device, not the simulator (set "
                          f"devices.{kind}.driver, or point it at 'atemr hw emulate')", path=f"devices.{kind}.driver")
    clock = WallClock()
    device = build_device(DeviceContext(config, clock.now), kind)
    if device is None:
        raise ConfigError(f"no {kind} is configured", path=f"devices.{kind}.driver")
    printed = 0
    seen = device.count
    start = getattr(device, "start", None)
    if start is not None:
        start()
    last_reading = clock.now()
    try:
        while args.count is None or printed < args.count:
            now = clock.now()
            device.tick(now)
            if device.count != seen and device.latest is not None:
                seen = device.count
                last_reading = now
                print(json.dumps(reading_json(kind, device.latest, now)), flush=True)
                printed += 1
                continue
            if now - last_reading > args.timeout:
                print(f"atemr hw echo: no {kind} reading for {args.timeout:.0f} s: {device.health(now).detail}",
                      file=sys.stderr)
                return 1
            time.sleep(0.005)
    except KeyboardInterrupt:
        pass
    finally:
        stop = getattr(device, "shutdown", None)
        if stop is not None:
            stop()
    return 0
