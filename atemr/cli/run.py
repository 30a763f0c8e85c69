"""``atemr run``: start the robot (in simulation by default) until Ctrl-C or SIGTERM."""

from __future__ import annotations

import argparse
from pathlib import Path

from atemr.cli.command import commands
from atemr.cli.signals import stop_on_signals
from atemr.config import load_config
from atemr.logsetup import configure_logging
from atemr.robot import build_robot


class RunCommand:
    help = "start the robot: in simulation by default, or on real hardware with --can-interface socketcan"

    def configure(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        parser.add_argument("--world", help="simulated world: a shipped world's name or a path to its YAML")
        parser.add_argument("--seed", type=int, help="seed of the simulation's random sources")
        parser.add_argument("--speed", type=float, help="simulated seconds per real second (default 1)")
        parser.add_argument(
            "--real", dest="simulation", action="store_const", const=False,
            help="drive real hardware instead of the simulator (use with --can-interface/--can-channel)",
        )
        parser.add_argument("--can-interface", help="python-can interface (virtual, socketcan, ...)")
        parser.add_argument("--can-channel", help="CAN channel (can0 on the robot)")
        parser.add_argument("--host", help="address the dashboard listens on (default 127.0.0.1; 0.0.0.0: every "
                                           "interface, which exposes it to the network)")
        parser.add_argument("--port", type=int, help="the dashboard's TCP port (default 5000; 0: any free port)")
        parser.add_argument(
            "--duration", type=float, help="stop after this many seconds of robot time (default: until Ctrl-C)"
        )

    def run(self, args: argparse.Namespace) -> int:
        config = load_config(
            args.config,
            overrides={
                "log_level": args.log_level,
                "simulation": args.simulation,
                "sim.world": args.world,
                "sim.seed": args.seed,
                "sim.speed": args.speed,
                "can.interface": args.can_interface,
                "can.channel": args.can_channel,
                "ui.host": args.host,
                "ui.port": args.port,
            },
        )
        configure_logging(config.log_level)
        robot = build_robot(config, realtime=True)

        with stop_on_signals(robot.stop), robot:
            can = f"{config.can.interface}:{config.can.channel}"
            mode = "simulation" if config.simulation else f"real hardware on {can}"
            print(f"ATEMR running in {mode}; started: {', '.join(robot.parts)}. Ctrl-C stops.", flush=True)
            control = robot.extras.get("control")
            if control is not None:
                print(f"control socket {control.server.path}: atemr mission run FILE (or status, cancel) "
                      f"from another terminal of this user", flush=True)
            robot.run(duration=args.duration)
        print("ATEMR stopped.", flush=True)
        return 0


commands.add("run", RunCommand())
