"""Agent trace files: writing them (rotated by size) and reading them back up to any damage.

Format (``.atrace``): a first line ``ATEMR-TRACE 1``, then one record per line, each
``<crc32 of the JSON, 8 hex digits> <JSON object>``. Line-delimited JSON keeps the file readable with
``grep``/``less`` and lets a reader find the end of a record without trusting a length; the checksum tells a
torn or edited line from a good one. A record's JSON is a flat object with ``k`` (its kind) and ``t`` (robot
time in seconds); what the kinds mean is the recorder's business (`atemr.fsm.recording`), not this module's.

`read_trace` returns every good record up to the first damaged one (a line without its end, a wrong
checksum, not JSON) and a warning naming the file and the byte offset of the damage, so a file cut by a
power loss is still worth reading. `TraceWriter` rotates to a new part when the current one would pass
``max_bytes``; each part begins with the recorder's preamble (what the agent looks like at that moment), so
every part replays on its own. With ``max_files`` the oldest files of the directory matching ``prune`` (the
robot's own ``run-*.atrace``, never an uploaded trace) are deleted.
The writer is a scheduler component: its tick flushes, its shutdown closes.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from atemr.errors import ConfigError
from atemr.io.rotation import files_by_age, part_path, prune_oldest

log = logging.getLogger(__name__)

MAGIC = b"ATEMR-TRACE 1\n"
SUFFIX = ".atrace"
Record = dict[str, Any]


def _finite(value: Any) -> Any:
    """JSON has no NaN or infinity: they become None (a record must stay valid JSON for any reader)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return value


def encode_record(record: Record) -> bytes:
    """One record as its line (checksum, space, compact JSON, newline)."""
    if not isinstance(record, dict) or not isinstance(record.get("k"), str):
        raise ConfigError(f"a trace record is a dict with a 'k' kind, got {record!r:.80}")
    text = json.dumps(_finite(record), separators=(",", ":"), ensure_ascii=False, allow_nan=False, default=str)
    data = text.encode("utf-8")
    return b"%08x " % zlib.crc32(data) + data + b"\n"


@dataclass
class TraceContents:
    """What `read_trace` found: the good records, in file order, and the warnings (damage, with the offset)."""

    path: Path
    records: list[Record] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    size_bytes: int = 0
    #: Bytes read as good records (the offset of the damage, or the file size).
    good_bytes: int = 0


def decode_trace(data: bytes, path: Path) -> TraceContents:
    """Parse a trace's bytes; see `read_trace`."""
    out = TraceContents(path, size_bytes=len(data))
    if not data.startswith(MAGIC):
        raise ConfigError(f"not an ATEMR trace (it does not begin with {MAGIC.strip().decode()!r})", file=path)
    offset = len(MAGIC)
    out.good_bytes = offset
    while offset < len(data):
        end = data.find(b"\n", offset)
        if end < 0:
            out.warnings.append(f"{path}: offset {offset}: the last record is cut short ({len(data) - offset} bytes "
                                f"without an end of line); read {len(out.records)} records up to there")
            break
        line = data[offset:end]
        why = None
        record: Any = None
        if len(line) < 10 or line[8:9] != b" ":
            why = "not a record line"
        else:
            try:
                crc = int(line[:8], 16)
            except ValueError:
                crc = -1
            body = line[9:]
            if crc != zlib.crc32(body):
                why = "checksum mismatch"
            else:
                try:
                    record = json.loads(body)
                except ValueError as exc:  # (UnicodeDecodeError is a ValueError)
                    why = f"not JSON ({exc})"
                if why is None and (not isinstance(record, dict) or not isinstance(record.get("k"), str)):
                    why = "not a record object"
        if why is not None:
            out.warnings.append(f"{path}: offset {offset}: damaged record ({why}); read {len(out.records)} "
                                f"records up to there, the rest of the file ({len(data) - offset} bytes) is skipped")
            break
        out.records.append(record)
        offset = end + 1
        out.good_bytes = offset
    for warning in out.warnings:
        log.warning("%s", warning)
    return out


def read_trace(path: str | Path) -> TraceContents:
    """Every good record of the trace at ``path`` up to the first damage, with a warning naming the file and
    offset of the damage (also logged). Raises `ConfigError` when the file cannot be read or is not a trace."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ConfigError(f"cannot read the trace: {exc.strerror}", file=path) from None
    return decode_trace(data, path)


def trace_files(directory: Path, pattern: str = f"*{SUFFIX}") -> list[Path]:
    """The trace files of ``directory`` matching ``pattern``, oldest first (by modification time, then name)."""
    return files_by_age(directory, pattern)


class TraceWriter:
    """Appends records to ``path``, rotating to a new part past ``max_bytes`` (see the module docstring).

    ``preamble`` gives the records that open every part; ``max_files`` bounds the files matching ``prune``.
    A write that fails (disk full, directory gone) stops the recording with one logged error (``error`` says
    why); the robot goes on.
    """

    name = "trace_writer"

    def __init__(self, path: str | Path, *, max_bytes: int = 8 * 1024 * 1024, max_files: int | None = None,
                 prune: str = f"*{SUFFIX}", preamble: Callable[[], Iterable[Record]] | None = None) -> None:
        if max_bytes < 1024:
            raise ConfigError(f"a trace part must be allowed at least 1024 bytes, got {max_bytes}", path="trace")
        self.base = Path(path)
        self.max_bytes = max_bytes
        self.max_files = max_files
        self.prune = prune
        self.preamble = preamble
        self.parts: list[Path] = []
        self.error: str | None = None
        self.records = 0
        self._file: IO[bytes] | None = None
        self._size = 0
        self._body = 0  # records written to the current part after its preamble

    def write(self, record: Record) -> None:
        """Append one record (rotating first when it would not fit)."""
        if self.error is not None:
            return
        line = encode_record(record)
        try:
            if self._file is None:
                self._open(len(self.parts))
            elif self._body and self._size + len(line) > self.max_bytes:
                self._close_file()
                self._open(len(self.parts))
            self._put(line)
            self._body += 1
            self.records += 1
        except OSError as exc:
            self.error = f"trace recording stopped: cannot write {self.parts[-1] if self.parts else self.base}: " \
                         f"{exc.strerror}"
            log.error("%s", self.error)
            self._close_file()

    def _put(self, line: bytes) -> None:
        assert self._file is not None
        self._file.write(line)
        self._size += len(line)

    def _open(self, index: int) -> None:
        path = part_path(self.base, index)
        path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(path, "wb")  # noqa: SIM115 (kept open across calls; closed in _close_file)
        self.parts.append(path)
        self._size, self._body = 0, 0
        self._put(MAGIC)
        for record in (self.preamble() if self.preamble is not None else ()):
            self._put(encode_record(record))
        self._prune()

    def _prune(self) -> None:
        if self.max_files is not None:
            prune_oldest(self.base.parent, self.prune, self.max_files, self.parts)

    def flush(self) -> None:
        if self._file is not None:
            try:
                self._file.flush()
            except OSError as exc:
                self.error = f"trace recording stopped: cannot write {self.parts[-1]}: {exc.strerror}"
                log.error("%s", self.error)
                self._close_file()

    def _close_file(self) -> None:
        if self._file is not None:
            with contextlib.suppress(OSError):  # closing after a failed write: nothing more to save
                self._file.close()
            self._file = None

    # -- scheduler component -----------------------------------------------------------------------
    def tick(self, now: float) -> None:
        """Flush what was written (the robot adds the writer at 1 Hz: a crash loses about a second)."""
        self.flush()

    def shutdown(self) -> None:
        """Flush and close (idempotent)."""
        self.flush()
        self._close_file()

    def __enter__(self) -> TraceWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()
