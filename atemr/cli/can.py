"""``atemr can``: look at the robot's CAN bus — decode a log, watch live traffic, find the DBC.

* ``atemr can decode FILE`` prints every frame of a python-can log (.log, .asc, .blf, ...) decoded by
  name and field; ``--json`` prints one JSON object per line.
* ``atemr can monitor --interface IF --channel CH`` prints live traffic decoded, optionally recording
  it with ``--log FILE`` (the suffix picks the format).
* ``atemr can dbc`` prints the path of the shipped DBC (``--print`` prints the file).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

import can

from atemr.cli.command import commands
from atemr.clock import Clock, WallClock
from atemr.config import CanConfig
from atemr.io.can.bus import open_bus
from atemr.io.can.dbc import dbc_path, dbc_text
from atemr.io.can.recording import check_log_path, describe, read_log


def _emit(msg: can.Message, as_json: bool, write: Callable[[str], object]) -> bool:
    frame = describe(msg)
    write(json.dumps(frame.as_dict()) if as_json else frame.line())
    return frame.error is None


def monitor_bus(bus: can.BusABC, write: Callable[[str], object], clock: Clock, *, count: int | None = None,
                duration: float | None = None, as_json: bool = False, logger: can.Listener | None = None,
                poll_s: float = 0.2) -> int:
    """Print frames from ``bus`` until ``count`` frames or ``duration`` seconds (on ``clock``); returns frames seen.

    Blocks in ``bus.recv`` for at most ``poll_s`` at a time, so Ctrl-C and the duration are honoured.
    """
    start = clock.now()
    seen = 0
    while count is None or seen < count:
        if duration is not None and clock.now() - start >= duration:
            break
        msg = bus.recv(timeout=poll_s)
        if msg is None:
            continue
        seen += 1
        if logger is not None:
            logger.on_message_received(msg)
        _emit(msg, as_json, write)
    return seen


class CanCommand:
    help = "CAN tools: decode a bus log, monitor live traffic, locate the DBC"

    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="can_action", metavar="ACTION", required=True)
        decode = sub.add_parser("decode", help="print every frame of a log file decoded by name and field")
        decode.add_argument("file", type=Path, help="python-can log: .log (candump), .asc, .blf, .csv, .trc, ...")
        decode.add_argument("--json", action="store_true", help="one JSON object per frame")
        monitor = sub.add_parser("monitor", help="show live traffic decoded")
        monitor.add_argument("--interface", default="socketcan", help="python-can interface (default socketcan)")
        monitor.add_argument("--channel", default="can0", help="channel (default can0)")
        monitor.add_argument("--bitrate", type=int, default=1_000_000, help="bit rate where the interface sets it")
        monitor.add_argument("--count", type=int, help="stop after this many frames")
        monitor.add_argument("--duration", type=float, help="stop after this many seconds")
        monitor.add_argument("--log", type=Path, help="also record to this file (.log, .asc, .blf, ...)")
        monitor.add_argument("--json", action="store_true", help="one JSON object per frame")
        dbc = sub.add_parser("dbc", help="print the path of the shipped DBC file")
        dbc.add_argument("--print", dest="print_text", action="store_true", help="print the file itself")

    def run(self, args: argparse.Namespace) -> int:
        action = args.can_action
        if action == "decode":
            return self._decode(args)
        if action == "monitor":
            return self._monitor(args)
        print(dbc_text() if args.print_text else dbc_path())
        return 0

    def _decode(self, args: argparse.Namespace) -> int:
        total = bad = 0
        for msg in read_log(args.file):
            total += 1
            bad += not _emit(msg, args.json, print)
        print(f"{total} frame(s), {bad} not decodable", file=sys.stderr)
        return 0

    def _monitor(self, args: argparse.Namespace) -> int:
        logger = can.Logger(check_log_path(args.log)) if args.log is not None else None
        config = CanConfig(interface=args.interface, channel=args.channel, bitrate=args.bitrate)
        try:
            with open_bus(config) as bus:
                print(f"monitoring {args.interface}:{args.channel} (Ctrl-C stops)", file=sys.stderr, flush=True)
                seen = monitor_bus(bus, lambda line: print(line, flush=True), WallClock(), count=args.count,
                                   duration=args.duration, as_json=args.json, logger=logger)
        finally:
            if logger is not None:
                logger.stop()
        print(f"{seen} frame(s)", file=sys.stderr)
        return 0


commands.add("can", CanCommand())
