"""`RecordingWriter`: a run's messages to MCAP files, rotated by size, never holding up the control loop.

The robot hands over ``(topic, log time, bytes)`` with `write`. What happens then depends on ``threaded``:

* threaded (a paced run: ``./run``, the real robot): the message joins a bounded queue and a writer thread
  adds it to the file, compresses chunks (LZ4: several times faster than zstd for a
  little more disk) and writes them. When the disk is slower than the robot the
  queue fills and new messages are dropped and counted (``dropped``): a tick never waits for the disk.
* inline (a headless simulation as fast as possible): written at once, nothing dropped, so a seeded run
  gives the same file every time.

Chunks are closed at every `tick` (the robot ticks the writer at 1 Hz) and when they reach ``chunk_bytes``,
so a power cut loses about a second: a reader gets everything up to the last complete chunk
(`atemr.io.recording.mcap_reader`). Past ``max_bytes`` a recording continues in ``name.1.mcap``,
``name.2.mcap``, ...; each part begins with the ``preamble`` (the agent's state, the transforms, the map:
what a part needs to be understood on its own) and the ``metadata``. With ``max_files`` the oldest files
of the directory matching ``prune`` (the robot's own ``run-*.mcap``, never an upload) are deleted.
A write that fails (disk full, directory gone) stops the recording with one logged error (``error``); the
robot goes on.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import IO, Any

from mcap.writer import CompressionType, Writer

from atemr.errors import ConfigError
from atemr.io.recording.topics import topic
from atemr.io.rotation import part_path, prune_oldest

log = logging.getLogger(__name__)

SUFFIX = ".mcap"
#: What a writer stamps in the file header (the MCAP "library" field).
LIBRARY = "atemr"
#: A chunk is closed at this size even between two ticks (bytes, before compression).
CHUNK_BYTES = 512 * 1024
#: Messages waiting for the writer thread at most, and their bytes at most: past either, new ones are dropped.
QUEUE_MESSAGES = 4096
QUEUE_BYTES = 64 * 1024 * 1024

#: Bounds of what closing a part adds per schema, channel or chunk (its index records) and once (statistics,
#: footer), for the size check before rotating.
_RECORD_BYTES = 64
_FOOTER_BYTES = 1024

#: A message to write: topic, log time (ns), encoded bytes.
Entry = tuple[str, int, bytes]


class _Part:
    """One open MCAP file: its writer, the channels registered in it, and an estimate of its size."""

    def __init__(self, path: Path, metadata: dict[str, str], chunk_bytes: int) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.file: IO[bytes] = open(path, "wb")  # noqa: SIM115 (open across calls; closed in close)
        self.writer = Writer(self.file, chunk_size=chunk_bytes, compression=CompressionType.LZ4)
        self.writer.start(profile="ros2", library=LIBRARY)
        if metadata:
            self.writer.add_metadata("atemr", metadata)
        self.channels: dict[str, int] = {}
        self.body = 0
        self._written = self.file.tell()
        self._pending = 0
        self._summary = _FOOTER_BYTES  # what `close` adds: schemas and channels again, indexes, statistics

    def add(self, name: str, log_time: int, data: bytes) -> None:
        channel = self.channels.get(name)
        if channel is None:
            t = topic(name)
            schema = self.writer.register_schema(t.schema_name, t.schema_encoding, t.schema_data)
            channel = self.writer.register_channel(name, t.message_encoding, schema)
            self.channels[name] = channel
            self._summary += len(t.schema_data) + 2 * (len(t.schema_name) + len(name)) + _RECORD_BYTES
        self.writer.add_message(channel, log_time=log_time, data=data, publish_time=log_time)
        written = self.file.tell()
        if written != self._written:  # a chunk went to the file
            self._written, self._pending = written, 0
            self._summary += _RECORD_BYTES * (1 + len(self.channels))
        self._pending += len(data) + 32

    @property
    def size(self) -> int:
        """What the file will weigh once closed, at most: the bytes written, the open chunk (uncompressed) and
        the summary `close` adds."""
        return self._written + self._pending + self._summary

    def flush(self) -> None:
        before = self._written
        self.writer.flush()
        self._written, self._pending = self.file.tell(), 0
        if self._written != before:
            self._summary += _RECORD_BYTES * (1 + len(self.channels))

    def close(self) -> None:
        try:
            self.writer.finish()
        finally:
            self.file.close()


class RecordingWriter:
    """Writes entries to ``path`` and its parts (see the module docstring).

    ``preamble`` gives the entries that open every part (called on the robot's thread); ``metadata`` the
    key-value pairs stored in every part; ``max_files`` bounds the files matching ``prune``.
    """

    name = "recording_writer"
    #: Takes encoded messages (`write`); `atemr.io.recording.writer_process` takes them as built.
    encodes = False

    def __init__(self, path: str | Path, *, max_bytes: int = 64 * 1024 * 1024, max_files: int | None = None,
                 prune: str = f"*{SUFFIX}", preamble: Callable[[], Iterable[Entry]] | None = None,
                 metadata: dict[str, str] | None = None, threaded: bool = False, chunk_bytes: int = CHUNK_BYTES,
                 queue_messages: int = QUEUE_MESSAGES, queue_bytes: int = QUEUE_BYTES) -> None:
        if max_bytes < 4096:
            raise ConfigError(f"a recording part must be allowed at least 4096 bytes, got {max_bytes}", path="trace")
        self.base = Path(path)
        self.max_bytes = max_bytes
        self.max_files = max_files
        self.prune = prune
        self.preamble = preamble
        self.metadata = dict(metadata or {})
        self.threaded = threaded
        self.chunk_bytes = min(chunk_bytes, max(1024, max_bytes // 4))
        self.parts: list[Path] = []
        self.error: str | None = None
        self.messages = 0
        self.dropped = 0
        self._part: _Part | None = None
        self._opened = 0  # parts asked for (the writer thread may not have opened the last one yet)
        self._size = 0  # the current part's size as the writing side last saw it
        self._rotating = False
        self._queue: queue.Queue[tuple[Any, ...]] = queue.Queue(maxsize=queue_messages)
        self._queue_bytes = queue_bytes
        self._queued = 0
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._closed = False

    @property
    def writing(self) -> Path | None:
        """The part being written now: None before the first is opened and once the recording stopped (closed, or
        an error such as a full disk: that part is closed then, and its space may be wanted back). Any thread may
        read it."""
        parts = self.parts[-1:]
        return parts[0] if parts and self.error is None and not self._closed else None

    # -- the robot's side -------------------------------------------------------------------------------------
    def wants(self, topic: str) -> bool:
        """A recording keeps every topic (while it is not stopped by an error)."""
        return self.error is None and not self._closed

    def write(self, name: str, log_time: int, data: bytes) -> None:
        """Record ``data`` on topic ``name`` at ``log_time`` (ns); never blocks in threaded mode."""
        if self.error is not None or self._closed:
            return
        if self._opened == 0 or (self._size + len(data) > self.max_bytes and not self._rotating
                                 and self._size > 0):
            self._open_next()
        self._put(("msg", name, log_time, data), len(data))

    def write_message(self, name: str, log_time: int, message: Any) -> None:
        """Only for sinks that encode (`encodes`); this writer takes bytes."""
        raise TypeError("RecordingWriter takes encoded messages: use write()")

    def _open_next(self) -> None:
        """Ask for a new part and queue its preamble (the robot's thread builds it: it reads the robot)."""
        entries = list(self.preamble()) if self.preamble is not None else []
        self._opened += 1
        self._rotating = True
        if not self._put(("open", entries), sum(len(e[2]) for e in entries)):
            self._opened -= 1  # the queue is full: the current part goes on, the next write asks again
            self._rotating = False

    def _put(self, item: tuple[Any, ...], size: int) -> bool:
        """Hand ``item`` to the writing side; False (and counted as dropped) when the queue is full."""
        if not self.threaded:
            self._handle(item)
            return True
        with self._lock:
            full = self._queued + size > self._queue_bytes
            if not full:
                self._queued += size
        if not full:
            try:
                self._queue.put_nowait(item)
                return True
            except queue.Full:
                with self._lock:
                    self._queued -= size
        self.dropped += 1
        if self.dropped == 1:
            log.warning("recording: the disk does not keep up, messages are dropped (counted in 'dropped')")
        return False

    # -- the writing side ---------------------------------------------------------------------------------------
    def _handle(self, item: tuple[Any, ...]) -> None:
        kind = item[0]
        try:
            if kind == "msg":
                self._add(item[1], item[2], item[3])
            elif kind == "open":
                self._open_part(item[1])
            elif kind == "flush":
                if self._part is not None:
                    self._part.flush()
                    self._size = self._part.size
                if len(item) > 1:
                    item[1].set()
            elif kind == "close":
                self._close_part()
        except OSError as exc:
            self._fail(exc)

    def _add(self, name: str, log_time: int, data: bytes) -> None:
        if self._part is None or self.error is not None:
            return
        self._part.add(name, log_time, data)
        self._part.body += 1
        self.messages += 1
        self._size = self._part.size

    def _open_part(self, entries: list[Entry]) -> None:
        if self.error is not None:
            return
        self._close_part()
        path = part_path(self.base, len(self.parts))
        self._part = _Part(path, self.metadata, self.chunk_bytes)
        self.parts.append(path)
        for name, log_time, data in entries:
            self._part.add(name, log_time, data)
        self._size = self._part.size
        self._rotating = False
        self._prune()

    def _close_part(self) -> None:
        part, self._part = self._part, None
        if part is not None:
            part.close()

    def _prune(self) -> None:
        if self.max_files is not None:
            prune_oldest(self.base.parent, self.prune, self.max_files, self.parts)

    def _fail(self, exc: OSError) -> None:
        where = self.parts[-1] if self.parts else self.base
        self.error = f"recording stopped: cannot write {where}: {exc.strerror or exc}"
        log.error("%s", self.error)
        part, self._part = self._part, None
        if part is not None:
            with contextlib.suppress(Exception):  # closing after a failed write: nothing more to save
                part.file.close()

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item[0] == "msg":
                with self._lock:
                    self._queued -= len(item[3])
            elif item[0] == "open":
                with self._lock:
                    self._queued -= sum(len(e[2]) for e in item[1])
            self._handle(item)
            if item[0] == "close":
                return

    # -- scheduler component --------------------------------------------------------------------------------
    def start(self) -> None:
        """Start the writer thread (threaded mode)."""
        if self.threaded and self._thread is None and not self._closed:
            self._thread = threading.Thread(target=self._run, name="atemr-recording", daemon=True)
            self._thread.start()

    def flush(self, timeout_s: float = 5.0) -> None:
        """Close the open chunk and wait until it is in the file (for a reader of the running recording; not for
        the control loop, which `tick` serves without waiting)."""
        if not self._opened or self.error is not None:
            return
        done = threading.Event()
        if self._put(("flush", done), 0) and self.threaded:
            done.wait(timeout_s)

    def tick(self, now: float) -> None:
        """Close the open chunk, so a crash loses about one tick's worth (the robot ticks this at 1 Hz)."""
        if self._opened and self.error is None:
            self._put(("flush",), 0)

    def shutdown(self) -> None:
        """Write what is queued, finish the file (its index and summary) and stop; idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._thread is None:
            self._handle(("close",))
            return
        self._queue.put(("close",))
        self._thread.join(timeout=10.0)
        if self._thread.is_alive():
            log.warning("recording: the writer thread did not finish within 10 s")
        self._thread = None

    def __enter__(self) -> RecordingWriter:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()


__all__ = ["CHUNK_BYTES", "SUFFIX", "Entry", "RecordingWriter", "part_path"]
