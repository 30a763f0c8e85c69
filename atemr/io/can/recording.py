"""Recording the bus to python-can's log formats, reading logs back, and naming every frame.

`BusRecorder` is a scheduler component with its own Bus instance on the robot's channel: it sees
every frame the other participants send and writes it with python-can's ``Logger`` — the format
follows the file suffix: candump-style ``.log``, Vector ``.asc``, ``.blf`` (also ``.csv``, ``.trc``
and the others python-can knows). In simulation it is polled and stamps frames with the simulated
time, so a recording is repeatable; on the robot (``threaded=True``) a Notifier thread writes frames
with their hardware timestamps.

`describe` turns any frame of this robot's bus into a name and fields, for ``atemr can decode`` and
``atemr can monitor``.
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

import can

from atemr.config import CanConfig
from atemr.errors import ConfigError, ProtocolError
from atemr.io.can.bus import open_bus
from atemr.io.can.protocol import decode as decode_protocol
from atemr.io.can.protocol import id_name, is_protocol_id
from atemr.io.motors.rmd_codec import RMD_BASE_ID, decode_any, is_rmd_id

log = logging.getLogger(__name__)

#: Suffixes of the formats the issue names; python-can accepts a few more (see `log_formats`).
PREFERRED_FORMATS = (".log", ".asc", ".blf")


def log_formats(*, reading: bool = False) -> list[str]:
    """Every log-file suffix python-can can write (or read)."""
    return sorted(can.io.MESSAGE_READERS if reading else can.io.MESSAGE_WRITERS)


def check_log_path(path: Path, *, reading: bool = False) -> Path:
    """``path`` if python-can can write (read) its format, else a `ConfigError` listing the formats."""
    known = log_formats(reading=reading)
    suffixes = [s.lower() for s in path.suffixes if s.lower() != ".gz"]
    if not suffixes or suffixes[-1] not in known:
        verb = "read" if reading else "record to"
        raise ConfigError(f"cannot {verb} {path.name!r}: the suffix picks the format, one of {', '.join(known)}",
                          path="can.log_file")
    return path


class BusRecorder:
    """Writes every frame seen on ``bus`` to ``path``; closes both on `shutdown`."""

    def __init__(self, bus: can.BusABC, path: str | Path, *, threaded: bool = False, name: str = "can_recorder",
                 close_bus: bool = True) -> None:
        self.path = check_log_path(Path(path))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.bus = bus
        self.name = name
        self.threaded = threaded
        self.close_bus = close_bus
        self.frames = 0
        self._writer: can.Listener = can.Logger(self.path)
        self._notifier: can.Notifier | None = None
        self._closed = False

    def start(self) -> None:
        """In threaded mode, start writing frames as they arrive."""
        if self.threaded and self._notifier is None:
            self._notifier = can.Notifier(self.bus, [self._writer], timeout=0.1)

    def tick(self, now: float) -> None:
        """Polled mode: write every pending frame, stamped with ``now``."""
        if self.threaded or self._closed:
            return
        while (msg := self.bus.recv(timeout=0)) is not None:
            stamped = copy.copy(msg)  # a received frame is shared with the bus's other receivers: never changed
            stamped.timestamp = now
            self._writer.on_message_received(stamped)
            self.frames += 1

    def shutdown(self) -> None:
        """Flush and close the file and the bus; idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._notifier is not None:
            self._notifier.stop()  # also stops (closes) the writer
        else:
            self._writer.stop()
        if self.close_bus:
            self.bus.shutdown()

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()


def read_log(path: str | Path) -> Iterator[can.Message]:
    """The frames of a log file in any python-can format; a missing or unreadable file is a `ConfigError`."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("no such log file", file=path)
    check_log_path(path, reading=True)
    read = 0
    try:
        with can.LogReader(path) as reader:  # closed on a bad line too
            for message in reader:
                yield message
                read += 1
    except (ValueError, OSError, can.CanError) as exc:
        where = f"after its first {read} frames" if read else "at its first frame"
        raise ConfigError(f"cannot read the log {where} (a line that is not a frame?): {exc}", file=path) from exc


@dataclass(frozen=True)
class DescribedFrame:
    """A frame with its name and decoded fields, or the reason it could not be decoded."""

    timestamp: float
    arbitration_id: int
    data: bytes
    name: str
    fields: dict[str, Any]
    error: str | None = None

    def line(self) -> str:
        """One human line: ``  12.345000  0x153 primary status  PrimaryStatus  state=EXEC ...``."""
        head = f"{self.timestamp:12.6f}  {id_name(self.arbitration_id):<24} [{len(self.data)}] {self.data.hex(' '):<23}"
        if self.error is not None:
            return f"{head}  ! {self.error}"
        body = " ".join(f"{k}={v}" for k, v in self.fields.items())
        return f"{head}  {self.name} {body}".rstrip()

    def as_dict(self) -> dict[str, Any]:
        return {"timestamp": self.timestamp, "id": f"0x{self.arbitration_id:03X}", "data": self.data.hex(),
                "name": self.name, "fields": self.fields, "error": self.error}


def describe(msg: can.Message) -> DescribedFrame:
    """Name and fields of any frame on this robot's bus; never raises for bad frames."""
    data = bytes(msg.data or b"")
    ts = float(msg.timestamp or 0.0)
    try:
        if msg.is_error_frame:
            raise ProtocolError("error frame")
        if is_protocol_id(msg.arbitration_id) and not msg.is_extended_id:
            decoded: Any = decode_protocol(msg)
        elif is_rmd_id(msg.arbitration_id) and not msg.is_extended_id:
            decoded = decode_any(msg)
        else:
            return DescribedFrame(ts, msg.arbitration_id, data, "unknown", {}, "not a frame of this robot's bus")
    except ProtocolError as exc:
        return DescribedFrame(ts, msg.arbitration_id, data, "invalid", {}, str(exc))
    name = type(decoded).__name__
    if not is_protocol_id(msg.arbitration_id):
        name = f"RMD motor {msg.arbitration_id - RMD_BASE_ID} {name}"
    return DescribedFrame(ts, msg.arbitration_id, data, name, decoded.fields())


def recorder_from_config(config: CanConfig, *, threaded: bool = False) -> BusRecorder | None:
    """A recorder on its own bus for ``can.log_file``, or None when no log file is configured.

    Schedule it like any component (10 Hz is plenty in polled mode: it drains everything pending).
    """
    if config.log_file is None:
        return None
    check_log_path(config.log_file)  # before opening a bus that would then leak
    return BusRecorder(open_bus(config), config.log_file, threaded=threaded)
