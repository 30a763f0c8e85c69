"""``atemr sim``: run the simulated robot in a world and report what happened.

``--headless`` runs as fast as the CPU allows on a `SimClock` (CI, benchmarks); without it the run is
locked to real time with `RealTimeSimClock` (``--speed`` times real time). ``--json`` prints a
machine-readable summary: simulated and wall seconds, real-time factor, collisions, final true pose
and how many scans, IMU samples, cliff readings and camera frames were produced.
"""

from __future__ import annotations

import argparse
import itertools
import json
import logging
import os
import signal
from pathlib import Path
from types import FrameType
from typing import Any

import can

from atemr.cli.command import commands
from atemr.clock import Clock, RealTimeSimClock, SimClock, WallClock
from atemr.config import Config, load_config
from atemr.errors import ConfigError
from atemr.io.motors.driver import RmdDriver
from atemr.io.motors.emulator import RmdMotorEmulator
from atemr.io.motors.model import RmdMotorModel
from atemr.io.sim.base import MountedWheel
from atemr.io.sim.simulation import Simulation, build_simulation, params_from_config
from atemr.msgs import WheelSpeeds
from atemr.scheduler import Component, Scheduler

log = logging.getLogger(__name__)
#: Numbers the virtual CAN channels of runs in one process (python-can's virtual channels are global).
_RUNS = itertools.count()


class TwistCommander:
    """Keeps a constant twist commanded through the motor driver (whose watchdog wants fresh commands)."""

    def __init__(self, driver: RmdDriver, left_radps: float, right_radps: float) -> None:
        self.name = "sim.twist"
        self.driver = driver
        self.speeds = WheelSpeeds(left_radps, right_radps)

    def tick(self, now: float) -> None:
        self.driver.set_speeds(self.speeds, now)


def can_motors(config: Config, channel: str, models: tuple[RmdMotorModel, RmdMotorModel]
               ) -> tuple[list[tuple[Component, float]], RmdDriver]:
    """The RMD driver and two motor emulators (answering for ``models``) on a virtual CAN bus.

    The simulation steps the models (``steps_model=False``); the emulators only answer the driver.
    """
    m = config.motors
    emulators = [
        RmdMotorEmulator(can.Bus(interface="virtual", channel=channel), motor_id, model, steps_model=False,
                         name=f"sim.motor_{side}")
        for side, motor_id, model in (("left", m.left_id, models[0]), ("right", m.right_id, models[1]))
    ]
    driver = RmdDriver.from_config(can.Bus(interface="virtual", channel=channel), m)
    return [(driver, m.rate_hz), *((e, 100.0) for e in emulators)], driver


def summary(sim: Simulation, sim_seconds: float, wall_seconds: float, seed: int) -> dict[str, Any]:
    """What a run did, as plain JSON-able values."""
    pose = sim.pose
    return {
        "world": sim.world.name,
        "seed": seed,
        "sim_seconds": round(sim_seconds, 6),
        "wall_seconds": round(wall_seconds, 6),
        "real_time_factor": round(sim_seconds / wall_seconds, 3) if wall_seconds > 0 else None,
        "collisions": len(sim.collisions),
        "collision_events": [
            {"t": round(c.t, 4), "what": c.what, "x_m": round(c.pose.x_m, 4), "y_m": round(c.pose.y_m, 4)}
            for c in sim.collisions
        ],
        "falls": [{"t": round(f.t, 4), "zone": f.zone} for f in sim.falls],
        "final_pose": {"x_m": pose.x_m, "y_m": pose.y_m, "yaw_rad": pose.yaw_rad},
        "distance_m": round(sim.base.distance_m, 6),
        "scans": sim.lidar_source.count,
        "imu_samples": sim.imu_source.count,
        "cliff_readings": sim.cliff_source.count,
        "frames": sim.camera_source.count,
    }


class SimCommand:
    help = "run the simulated robot in a world (headless as fast as possible, or locked to real time)"

    def configure(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        parser.add_argument("--world", help="a shipped world's name (studio) or a path to a world or map YAML")
        parser.add_argument("--seed", type=int, help="seed of every random source (default 0)")
        parser.add_argument("--headless", action="store_true",
                            help="run as fast as possible on simulated time (no real-time pacing)")
        parser.add_argument("--duration", type=float,
                            help="simulated seconds to run (default: 10 headless, until Ctrl-C otherwise)")
        parser.add_argument("--speed", type=float, help="simulated seconds per real second when not headless")
        parser.add_argument("--camera-hz", type=float, help="camera frames per second (0: camera off)")
        parser.add_argument("--twist", type=float, nargs=2, metavar=("V_MPS", "W_RADPS"), default=(0.0, 0.0),
                            help="drive the base with this constant command (default: stand still)")
        parser.add_argument("--motors", choices=("direct", "can"), default="direct",
                            help="direct: command the wheel models; can: through the RMD driver and two motor "
                                 "emulators on a virtual CAN bus (slower, the whole chain)")
        parser.add_argument("--json", action="store_true", help="print the summary as JSON")

    def run(self, args: argparse.Namespace) -> int:
        config = load_config(args.config, overrides={
            "log_level": args.log_level, "sim.world": args.world, "sim.seed": args.seed,
            "sim.speed": args.speed, "sim.camera_hz": args.camera_hz,
        })
        duration = args.duration if args.duration is not None else (10.0 if args.headless else None)
        if duration is not None and not duration >= 0:
            raise ConfigError(f"must be >= 0 seconds, got {duration}", path="argument --duration")
        params = params_from_config(config.sim)
        v, w = args.twist
        parts: list[tuple[Component, float]] = []
        if args.motors == "can":
            m = config.motors
            models = (RmdMotorModel(), RmdMotorModel())
            wheels = (MountedWheel(models[0], m.left_direction), MountedWheel(models[1], m.right_direction))
            sim = build_simulation(config.sim.world, config.sim.seed, params=params, wheels=wheels)
            parts, driver = can_motors(config, f"atemr-sim-{os.getpid()}-{next(_RUNS)}", models)
            parts.insert(0, (TwistCommander(driver, *sim.wheel_speeds_for(v, w)), m.rate_hz))
        else:
            sim = build_simulation(config.sim.world, config.sim.seed, params=params)
            sim.command_twist(v, w)
        # The clock starts after the (slow) building, so a real-time run is paced from its first tick.
        clock: Clock = SimClock() if args.headless else RealTimeSimClock(speed=config.sim.speed)
        scheduler = Scheduler(clock)
        sim.attach(scheduler)
        for part, rate in parts:
            scheduler.add(part, rate)

        def on_signal(signum: int, frame: FrameType | None) -> None:
            log.info("%s received: stopping", signal.Signals(signum).name)
            scheduler.stop()

        previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
        # Headless, time is simulated: a tick that takes longer than its simulated period is no overrun.
        sched_log = logging.getLogger("atemr.scheduler")
        previous_level = sched_log.level
        if args.headless:
            sched_log.setLevel(logging.ERROR)
        wall = WallClock()
        t0_sim, t0_wall = clock.now(), wall.now()
        try:
            scheduler.start()
            if not args.json:
                mode = "headless" if args.headless else f"real time x{config.sim.speed:g}"
                print(f"simulating world '{sim.world.name}' (seed {config.sim.seed}, {mode})", flush=True)
            scheduler.run(duration=duration)
        finally:
            scheduler.shutdown()
            sched_log.setLevel(previous_level)
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        result = {**summary(sim, clock.now() - t0_sim, wall.now() - t0_wall, config.sim.seed), "motors": args.motors}
        if args.json:
            print(json.dumps(result, indent=2))
        else:
            p = result["final_pose"]
            print(f"{result['sim_seconds']:.2f} s simulated in {result['wall_seconds']:.2f} s "
                  f"({result['real_time_factor']}x real time); collisions: {result['collisions']}; "
                  f"final pose: ({p['x_m']:.3f}, {p['y_m']:.3f}, {p['yaw_rad']:.3f}); "
                  f"scans: {result['scans']}, frames: {result['frames']}")
        return 0


commands.add("sim", SimCommand())
