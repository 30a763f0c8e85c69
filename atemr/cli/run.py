"""``atemr run``: start the robot (in simulation by default) until Ctrl-C or SIGTERM."""

from __future__ import annotations

import argparse
import contextlib
import gc
import logging
import shlex
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from atemr.cli.signals import stop_on_signals

if TYPE_CHECKING:  # only what runs a command imports what it needs: `atemr --help` stays fast
    from atemr.config import Config
    from atemr.robot.core import Robot

log = logging.getLogger(__name__)

#: How long the real robot's start-up check waits for its devices to answer, in seconds.
STARTUP_CHECK_S = 5.0


class RunCommand:
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
        from atemr.config import load_config
        from atemr.logsetup import configure_logging
        from atemr.robot import build_robot

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
        if not config.simulation:
            missing = startup_check(config)
            if missing:
                for line in missing:
                    print(f"atemr run: {line}", file=sys.stderr)
                print("atemr run: not started (the robot was not powered off); 'atemr hw check' shows every "
                      "device", file=sys.stderr)
                return 1
        robot = build_robot(config, realtime=True)

        with start_up_heap_frozen(), stop_on_signals(robot.stop), robot:
            can = f"{config.can.interface}:{config.can.channel}"
            mode = "simulation" if config.simulation else f"real hardware on {can}"
            print(f"ATEMR running in {mode}; started: {', '.join(robot.components)}. Ctrl-C stops.", flush=True)
            control = robot.parts.control
            if control is not None:
                print(f"control socket {control.server.path}: atemr mission run FILE (or status, cancel) "
                      f"from another terminal of this user", flush=True)
            robot.run(duration=args.duration)
        print("ATEMR stopped.", flush=True)
        return after_stop(robot)


@contextlib.contextmanager
def start_up_heap_frozen() -> Iterator[None]:
    """While the robot runs, the objects of its start-up (modules, configuration, trees, maps: most of the
    heap) are frozen out of the garbage collector (`gc.freeze`), so a full collection walks only what was made
    since. Otherwise one stalls the control loop for tens of milliseconds (80 ms measured on a simulated robot
    after 30 s), several 50 Hz ticks, longer as the heap grows. Frozen before the robot starts and its signals
    are caught (collecting first takes a moment), unfrozen when it stops. The price: a start-up object that
    becomes garbage in a reference cycle while the robot runs (a behaviour tree replaced by a reload) is kept
    until then, at most the start-up heap."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def after_stop(robot: Robot) -> int:
    """The exit code once the robot has stopped: ``power_off_command``'s when the agent halted on an
    acknowledged power-off and one is configured, else 0."""
    command = robot.config.power_off_command
    if robot.parts.agent.halted and command:
        return power_off(command)
    return 0


def startup_check(config: Config) -> list[str]:
    """One line per critical device that does not answer within a few seconds, before anything starts: a
    robot missing its lidar must not boot into STARTUP, fail there and acknowledge a power-off."""
    from atemr.io.devices.check import check_devices, missing_critical

    rows = check_devices(config, seconds=STARTUP_CHECK_S, until_healthy=True)
    return [f"{r.device} ({r.driver}{', ' + r.port if r.port else ''}) is missing: {r.detail}"
            for r in missing_critical(rows)]


def power_off(command: str) -> int:
    """Run ``power_off_command`` once the power-off is acknowledged (``systemctl poweroff`` on the robot)."""
    argv = shlex.split(command)
    log.warning("power-off acknowledged: running %s", argv)
    try:
        return subprocess.run(argv, check=False).returncode  # the operator's own configured command
    except OSError as exc:
        log.error("power_off_command %r failed: %s", command, exc)
        return 1
