"""``atemr hw emulate``: KAY's serial devices without the hardware.

It runs a simulated world in real time and serves, on pseudo-terminals, an RPLidar A2M8 and a WT901 that
speak their devices' own bytes, fed by the world's lidar and IMU. It prints a configuration that points the
real drivers at them, so ``atemr hw check``, ``atemr hw echo`` and ``atemr run`` read a simulated world
through the real protocols. The robot in this world stands still: its wheels belong to this process, not to
the robot reading the devices (a robot that drives on emulated serial devices runs in one process, as the
whole-robot test ``tests/robot/test_real_path.py`` does).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from atemr.cli.signals import stop_on_signals
from atemr.clock import WallClock
from atemr.io.devices.rplidar_emulator import RplidarEmulator
from atemr.io.devices.wt901_emulator import Wt901Emulator
from atemr.io.sim.simulation import Simulation, build_simulation
from atemr.scheduler import Scheduler


def emulated_config(lidar_port: str, imu_port: str, sim: Simulation) -> str:
    """The configuration (YAML) of a robot whose lidar and IMU are the emulators on these ports."""
    mount = sim.params.lidar.mount
    return "\n".join([
        f"# atemr hw emulate: world {sim.world.name}; serial devices on pseudo-terminals",
        "simulation: false",
        "devices:",
        f"  lidar: {{driver: rplidar, port: {lidar_port}, baudrate: 115200, "
        f"pose: [{mount.x_m}, {mount.y_m}, {mount.yaw_rad}]}}",
        f"  imu: {{driver: wt901, port: {imu_port}, baudrate: 9600}}",
        "  camera: {driver: none}",
        "  motors: {driver: emulated}",
        "  secondary: {driver: emulated}",
        "",
    ])


def emulate_command(args: argparse.Namespace) -> int:
    """Serve the emulators until Ctrl-C (or ``--duration``); print the configuration first."""
    sim = build_simulation(args.world, args.seed)
    scheduler = Scheduler(WallClock(), realtime=True)
    sim.attach(scheduler)
    with tempfile.TemporaryDirectory(prefix="atemr-hw-") as folder, \
            RplidarEmulator(lambda: sim.lidar_source.latest, directory=folder) as lidar, \
            Wt901Emulator(lambda: sim.imu_source.latest, directory=folder) as imu:
        text = emulated_config(lidar.port, imu.port, sim)
        if args.config_out is not None:
            Path(args.config_out).write_text(text, encoding="utf-8")
        print(text, flush=True)
        until = f"for {args.duration:g} s" if args.duration is not None else "until Ctrl-C"
        print(f"# serving {until}; try: atemr hw check --config {args.config_out or 'FILE'}", flush=True)
        with stop_on_signals(scheduler.stop):
            scheduler.start()
            try:
                scheduler.run(duration=args.duration)
            finally:
                scheduler.shutdown()
    return 0
