"""``atemr can``: look at the robot's CAN bus — decode a log, watch live traffic, find the DBC.

* ``atemr can decode FILE`` prints every frame of a python-can log (.log, .asc, .blf, ...) decoded by
  name and field; ``--json`` prints one JSON object per line.
* ``atemr can monitor --interface IF --channel CH`` prints live traffic decoded, optionally recording
  it with ``--log FILE`` (the suffix picks the format).
* ``atemr can dbc`` prints the path of the shipped DBC (``--print`` prints the file).

Motor frames are decoded in the RMD protocol version the motors speak, which the frames alone do not tell
(a V1.61 reply and a V4.2 request share 0x141): ``--protocol v1|v4``, else the ``devices.motors.protocol``
of ``--config FILE``, else v1.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # only what runs a command imports what it needs: `atemr --help` stays fast
    import can

    from atemr.clock import Clock
    from atemr.io.can.recording import DescribedFrame
    from atemr.io.motors.rmd_protocol import RmdProtocol

from atemr.errors import ProtocolError


def describe_frame(msg: can.Message, protocol: str | RmdProtocol = "v1") -> DescribedFrame:
    """Name and fields of any frame on this robot's bus, motor frames read in ``protocol``; never raises.

    V1.61 frames are what `describe` already knows; a V4.2 motor frame (request on 0x140 + id, reply on
    0x240 + id) is decoded by the V4.2 codec and everything else, the inter-core protocol's 0x150-0x157
    first (motors 16-23 may not use those IDs), is left to `describe`.
    """
    from atemr.io.can.protocol import is_protocol_id
    from atemr.io.can.recording import DescribedFrame, describe
    from atemr.io.motors.rmd_protocol import PROTOCOL_V1, rmd_protocol

    codec = rmd_protocol(protocol)
    motor = codec.motor_of(msg.arbitration_id)
    if (codec is PROTOCOL_V1 or motor is None or is_protocol_id(msg.arbitration_id) or msg.is_extended_id
            or msg.is_error_frame):
        return describe(msg)
    data = bytes(msg.data or b"")
    ts = float(msg.timestamp or 0.0)
    try:
        decoded = codec.decode_any(msg)
    except ProtocolError as exc:
        return DescribedFrame(ts, msg.arbitration_id, data, "invalid", {}, str(exc))
    return DescribedFrame(ts, msg.arbitration_id, data, f"RMD motor {motor} {type(decoded).__name__}",
                          decoded.fields())


def _emit(msg: can.Message, as_json: bool, write: Callable[[str], object], protocol: RmdProtocol) -> bool:
    frame = describe_frame(msg, protocol)
    write(json.dumps(frame.as_dict()) if as_json else frame.line())
    return frame.error is None


def monitor_bus(bus: can.BusABC, write: Callable[[str], object], clock: Clock, *, count: int | None = None,
                duration: float | None = None, as_json: bool = False, logger: can.Listener | None = None,
                poll_s: float = 0.2, protocol: str | RmdProtocol = "v1") -> int:
    """Print frames from ``bus`` until ``count`` frames or ``duration`` seconds (on ``clock``); returns frames seen.

    Blocks in ``bus.recv`` for at most ``poll_s`` at a time, so Ctrl-C and the duration are honoured.
    Motor frames are decoded in ``protocol`` (``v1`` or ``v4``).
    """
    from atemr.io.motors.rmd_protocol import rmd_protocol

    codec = rmd_protocol(protocol)
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
        _emit(msg, as_json, write, codec)
    return seen


def _add_protocol_options(parser: argparse.ArgumentParser) -> None:
    from typing import get_args, get_type_hints

    from atemr.io.devices.config import MotorsDeviceConfig

    versions = get_args(get_type_hints(MotorsDeviceConfig)["protocol"])  # the setting's own choices
    parser.add_argument("--protocol", choices=versions,
                        help="RMD protocol of the motor frames: v1 (V1.61) or v4 (V4.2); "
                             "default: devices.motors.protocol of --config, else v1")
    parser.add_argument("--config", type=Path, metavar="FILE",
                        help="robot configuration whose devices.motors.protocol the motor frames follow")


def chosen_protocol(protocol: str | None, config: Path | None) -> RmdProtocol:
    """``--protocol`` if given, else ``devices.motors.protocol`` of the ``--config`` file, else V1.61."""
    from atemr.config import load_config
    from atemr.io.motors.rmd_protocol import PROTOCOL_V1, rmd_protocol

    if protocol is not None:
        return rmd_protocol(protocol)
    if config is not None:
        return rmd_protocol(load_config(config).devices.motors.protocol)
    return PROTOCOL_V1


class CanCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="can_action", metavar="ACTION", required=True)
        decode = sub.add_parser("decode", help="print every frame of a log file decoded by name and field")
        decode.add_argument("file", type=Path, help="python-can log: .log (candump), .asc, .blf, .csv, .trc, ...")
        decode.add_argument("--json", action="store_true", help="one JSON object per frame")
        _add_protocol_options(decode)
        monitor = sub.add_parser("monitor", help="show live traffic decoded")
        monitor.add_argument("--interface", default="socketcan", help="python-can interface (default socketcan)")
        monitor.add_argument("--channel", default="can0", help="channel (default can0)")
        monitor.add_argument("--bitrate", type=int, default=1_000_000, help="bit rate where the interface sets it")
        monitor.add_argument("--count", type=int, help="stop after this many frames")
        monitor.add_argument("--duration", type=float, help="stop after this many seconds")
        monitor.add_argument("--log", type=Path, help="also record to this file (.log, .asc, .blf, ...)")
        monitor.add_argument("--json", action="store_true", help="one JSON object per frame")
        _add_protocol_options(monitor)
        dbc = sub.add_parser("dbc", help="print the path of the shipped DBC file")
        dbc.add_argument("--print", dest="print_text", action="store_true", help="print the file itself")

    def run(self, args: argparse.Namespace) -> int:
        from atemr.io.can.dbc import dbc_path, dbc_text

        action = args.can_action
        if action == "decode":
            return self._decode(args)
        if action == "monitor":
            return self._monitor(args)
        print(dbc_text() if args.print_text else dbc_path())
        return 0

    def _decode(self, args: argparse.Namespace) -> int:
        from atemr.io.can.recording import read_log

        protocol = chosen_protocol(args.protocol, args.config)
        total = bad = 0
        for msg in read_log(args.file):
            total += 1
            bad += not _emit(msg, args.json, print, protocol)
        print(f"{total} frame(s), {bad} not decodable (motor frames as RMD protocol {protocol.title})",
              file=sys.stderr)
        return 0

    def _monitor(self, args: argparse.Namespace) -> int:
        import can

        from atemr.clock import WallClock
        from atemr.config import CanConfig
        from atemr.io.can.bus import open_bus
        from atemr.io.can.recording import check_log_path

        protocol = chosen_protocol(args.protocol, args.config)
        logger = can.Logger(check_log_path(args.log)) if args.log is not None else None
        config = CanConfig(interface=args.interface, channel=args.channel, bitrate=args.bitrate)
        try:
            with open_bus(config) as bus:
                print(f"monitoring {args.interface}:{args.channel} (Ctrl-C stops)", file=sys.stderr, flush=True)
                seen = monitor_bus(bus, lambda line: print(line, flush=True), WallClock(), count=args.count,
                                   duration=args.duration, as_json=args.json, logger=logger, protocol=protocol)
        finally:
            if logger is not None:
                logger.stop()
        print(f"{seen} frame(s)", file=sys.stderr)
        return 0
