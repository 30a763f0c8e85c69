"""``atemr sim``: run the simulated robot in a world and report what happened.

By default the whole robot runs (``--stack robot``): motors over virtual CAN, the secondary core, the
motion pipeline and the agent, exactly as ``atemr run`` wires them, with ``--twist`` held on the
operator's joystick. ``--stack bare`` runs the simulator alone with the wheel models commanded
directly (what the simulator benchmark measures). ``--headless`` runs as fast as the CPU allows on a
`SimClock` (no dashboard, no portal); without it the run is locked to real time with `RealTimeSimClock`
(``--speed`` times real time). ``--json`` prints a machine-readable summary: simulated and wall
seconds, real-time factor, collisions, final true pose, counts of scans, IMU samples, cliff readings
and camera frames, and (whole robot) the agent's final state and transitions.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from atemr.cli.signals import stop_on_signals

if TYPE_CHECKING:  # only what runs a command imports what it needs: `atemr --help` stays fast
    from atemr.io.sim.simulation import Simulation
from atemr.errors import ConfigError


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
        "depth_frames": sim.depth_source.count,
    }


class SimCommand:
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
        parser.add_argument("--depth-hz", type=float,
                            help="depth camera (the D415's) frames per second (0: depth camera off; default 10)")
        parser.add_argument("--twist", type=float, nargs=2, metavar=("V_MPS", "W_RADPS"), default=(0.0, 0.0),
                            help="drive the base with this constant command (default: stand still)")
        parser.add_argument("--stack", choices=("robot", "bare"), default="robot",
                            help="robot: the whole robot (CAN motors, secondary core, motion control, agent), "
                                 "--twist on the operator's joystick; bare: the simulator alone, wheels commanded "
                                 "directly (what the simulator benchmark measures)")
        parser.add_argument("--json", action="store_true", help="print the summary as JSON")

    def run(self, args: argparse.Namespace) -> int:  # noqa: PLR0912, PLR0915  one command read top to bottom: build either stack, run it, report
        from atemr.clock import RealTimeSimClock, SimClock, WallClock
        from atemr.config import load_config
        from atemr.io.sim.simulation import build_simulation, params_from_config
        from atemr.msgs import Twist
        from atemr.robot import Robot, build_robot
        from atemr.robot.core import Ticker
        from atemr.robot.headless import agent_summary, build_headless_robot
        from atemr.robot.inputs import MotionInputs
        from atemr.scheduler import Scheduler

        config = load_config(args.config, overrides={
            "log_level": args.log_level, "sim.world": args.world, "sim.seed": args.seed,
            "sim.speed": args.speed, "sim.camera_hz": args.camera_hz, "sim.depth_hz": args.depth_hz,
        })
        duration = args.duration if args.duration is not None else (10.0 if args.headless else None)
        if duration is not None and not duration >= 0:
            raise ConfigError(f"must be >= 0 seconds, got {duration}", path="argument --duration")
        v, w = args.twist
        robot: Robot | None = None
        if args.stack == "robot":
            robot = build_headless_robot(config) if args.headless else build_robot(config, realtime=True)
            scheduler, clock = robot.scheduler, robot.clock
            if robot.parts.sim is None:
                raise ConfigError("atemr sim needs the simulated world (simulation: true)", path="simulation")
            sim = robot.parts.sim
            if v or w:
                inputs: MotionInputs = robot.parts.inputs
                robot.add(Ticker("sim.joystick", lambda now: inputs.operate(Twist(v, w), now)), 10.0)
        else:
            params = params_from_config(config.sim, config.robot_body())
            sim = build_simulation(config.sim.world, config.sim.seed, params=params)
            sim.command_twist(v, w)
            # The clock starts after the (slow) building, so a real-time run is paced from its first tick.
            clock = SimClock() if args.headless else RealTimeSimClock(speed=config.sim.speed)
            scheduler = Scheduler(clock, realtime=not args.headless)
            sim.attach(scheduler)

        wall = WallClock()
        t0_sim, t0_wall = clock.now(), wall.now()
        with stop_on_signals(scheduler.stop):
            try:
                if robot is not None:
                    robot.start()
                else:
                    scheduler.start()
                if not args.json:
                    mode = "headless" if args.headless else f"real time x{config.sim.speed:g}"
                    print(f"simulating world '{sim.world.name}' (seed {config.sim.seed}, {mode}, {args.stack})",
                          flush=True)
                scheduler.run(duration=duration)
            finally:
                if robot is not None:
                    robot.shutdown()
                else:
                    scheduler.shutdown()
        result = {**summary(sim, clock.now() - t0_sim, wall.now() - t0_wall, config.sim.seed), "stack": args.stack}
        if robot is not None:
            result.update(agent_summary(robot))
        if args.json:
            print(json.dumps(result, indent=2))
        else:
            p = result["final_pose"]
            print(f"{result['sim_seconds']:.2f} s simulated in {result['wall_seconds']:.2f} s "
                  f"({result['real_time_factor']}x real time); collisions: {result['collisions']}; "
                  f"final pose: ({p['x_m']:.3f}, {p['y_m']:.3f}, {p['yaw_rad']:.3f}); "
                  f"scans: {result['scans']}, frames: {result['frames']}, depth frames: {result['depth_frames']}"
                  + (f"; agent: {result['agent_state']}" if "agent_state" in result else ""))
        return 0
