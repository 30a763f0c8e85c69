"""`ProcessRecordingWriter`: the MCAP writer in a process of its own, for a paced robot.

Encoding ROS 2 messages with `mcap-ros2-support` is pure Python: a few hundred messages a second would cost the
robot's own interpreter a third of its time, and a thread would not help (the GIL). So on a paced robot the
recorder hands over the messages themselves (plain dicts and lists, cheap to pickle), in batches, through a
bounded queue to a writer process that encodes them (`atemr.io.recording.codec`), compresses and writes them on
the other core. When the process does not keep up the queue fills and batches are dropped and counted: the
robot never waits. Rotation stays on the robot's side, as in `RecordingWriter`: it knows the part's size from
the process and builds the next part's preamble itself, from the robot's state at that moment.
"""

from __future__ import annotations

import logging
import multiprocessing
import queue
from pathlib import Path
from typing import Any

from atemr.io.recording.codec import Codec
from atemr.io.recording.mcap_writer import RecordingWriter
from atemr.io.rotation import part_path

log = logging.getLogger(__name__)

#: Items sent in one batch at most (a batch also leaves at every tick, flush, new part and close).
BATCH_ITEMS = 64
#: Batches waiting for the process at most (about 10 s of a robot's messages): past that, batches are dropped.
QUEUE_BATCHES = 256


def _child_main(requests: Any, status: Any, size: Any, parts: Any, options: dict[str, Any]) -> None:
    """The writer process: an inline `RecordingWriter`, fed item by item, encoding what comes unencoded."""
    writer = RecordingWriter(options["path"], max_bytes=options["max_bytes"], max_files=options["max_files"],
                             prune=options["prune"], metadata=options["metadata"])
    codec = Codec()
    while True:
        batch = requests.get()
        for request in batch:
            item = request
            if item[0] == "msg" and not isinstance(item[3], bytes):
                try:
                    item = ("msg", item[1], item[2], codec.encode(item[1], item[3]))
                except Exception as exc:  # a message that cannot be encoded is reported, not fatal
                    status.put(("bad", f"{item[1]}: {exc}"))
                    continue
            if item[0] == "flush" and len(item) > 1:
                writer._handle(("flush",))
                status.put(("flushed",))
                continue
            writer._handle(item)
            if item[0] == "close":
                status.put(("done", writer.messages, writer.error))
                return
        size.value = writer._size
        parts.value = len(writer.parts)
        if writer.error is not None:
            status.put(("error", writer.error))


class ProcessRecordingWriter(RecordingWriter):
    """`RecordingWriter` whose writing side is a process (see the module docstring); same settings."""

    #: Take messages unencoded (`write_message`): the process encodes them.
    encodes = True

    def __init__(self, path: str | Path, **kwargs: Any) -> None:
        kwargs.pop("threaded", None)
        super().__init__(path, threaded=True, **kwargs)
        ctx = multiprocessing.get_context("spawn")  # never fork a robot's threads (CAN, devices, servers)
        self._requests: Any = ctx.Queue(maxsize=QUEUE_BATCHES)
        self._status: Any = ctx.Queue()
        self._shared_size: Any = ctx.Value("q", 0, lock=False)
        self._shared_parts: Any = ctx.Value("q", 0, lock=False)
        self._process = ctx.Process(
            target=_child_main, name="atemr-recording", daemon=True,
            args=(self._requests, self._status, self._shared_size, self._shared_parts,
                  {"path": str(self.base), "max_bytes": self.max_bytes, "max_files": self.max_files,
                   "prune": self.prune, "metadata": self.metadata}))
        self._batch: list[tuple[Any, ...]] = []
        self._sent = 0  # items sent since the last size report was read

    def write_message(self, name: str, log_time: int, message: Any) -> None:
        """Record ``message`` (a dict as `atemr.io.recording.ros2_convert` builds it) on topic ``name``."""
        if self.error is not None or self._closed:
            return
        if self._opened == 0 or (self._size > self.max_bytes and not self._rotating):
            self._open_next()
        self._put(("msg", name, log_time, message), 0)

    def write(self, name: str, log_time: int, data: bytes) -> None:
        self.write_message(name, log_time, data)

    def _put(self, item: tuple[Any, ...], size: int) -> bool:
        self._batch.append(item)
        if item[0] == "open":
            self.parts.append(part_path(self.base, len(self.parts)))
            self._size = 0
            self._rotating = False
        if len(self._batch) >= BATCH_ITEMS or item[0] != "msg":
            return self._send()
        return True

    def _send(self) -> bool:
        batch, self._batch = self._batch, []
        if not batch:
            return True
        try:
            self._requests.put_nowait(batch)
        except queue.Full:
            self.dropped += sum(1 for item in batch if item[0] == "msg")
            if self.dropped == len(batch):
                log.warning("recording: the writer process does not keep up, messages are dropped")
            return False
        self.messages += sum(1 for item in batch if item[0] == "msg")
        return True

    def _read_status(self, until_flushed: float | None = None) -> None:
        if int(self._shared_parts.value) == len(self.parts):  # a size of the part now written, not the last one
            self._size = int(self._shared_size.value)
        while True:
            try:
                if until_flushed is None:
                    kind, *rest = self._status.get_nowait()
                else:
                    kind, *rest = self._status.get(timeout=until_flushed)
            except queue.Empty:
                return
            if kind == "flushed" and until_flushed is not None:
                return
            if kind == "error" and self.error is None:
                self.error = str(rest[0])
                log.error("%s", self.error)
            elif kind == "bad":
                log.error("recording: a message could not be encoded: %s", rest[0])

    # -- scheduler component ------------------------------------------------------------------------------------
    def start(self) -> None:
        if not self._process.is_alive() and self._process.exitcode is None and not self._closed:
            self._process.start()

    def tick(self, now: float) -> None:
        if self._opened and self.error is None:
            self._put(("flush",), 0)
        self._read_status()

    def flush(self, timeout_s: float = 5.0) -> None:
        """Send what is batched, and wait until the process has closed its chunk (for a reader of the running
        recording; not for the control loop, which `tick` serves without waiting)."""
        if self._opened and self._put(("flush", "wait"), 0):
            self._read_status(until_flushed=timeout_s)

    def shutdown(self) -> None:
        """Send the rest, let the process finish the file, and wait for it (at most 10 s); idempotent."""
        if self._closed:
            return
        self._closed = True
        if not self._process.is_alive():
            return
        self._batch.append(("close",))
        try:
            self._requests.put(self._batch, timeout=5.0)
        except queue.Full:
            log.warning("recording: the writer process does not answer; the file may lack its summary")
        self._batch = []
        self._process.join(timeout=10.0)
        if self._process.is_alive():
            log.warning("recording: the writer process did not finish within 10 s")
            self._process.terminate()
        self._read_status()
        self._requests.close()
        self._status.close()


__all__ = ["ProcessRecordingWriter"]
