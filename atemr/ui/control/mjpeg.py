"""The camera as MJPEG: ``multipart/x-mixed-replace`` parts, one JPEG each, for an ``<img>`` to show.

A stream reads frames only while its client is connected (the generator runs in that client's request
thread) and ends when the client leaves (werkzeug's write fails and closes the generator) or the server
stops (the ``stopping`` event). It sends a frame when a new one is there, at most `STREAM_FPS` times a
second, and repeats the last one every `REPEAT_S` so a client that left unnoticed is found out.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator

#: Frames per second a stream aims at (the simulator's camera runs at 10 fps).
STREAM_FPS = 10.0
#: Longest time without a part: the last frame is sent again after it.
REPEAT_S = 1.0
BOUNDARY = "atemrframe"
MIMETYPE = f"multipart/x-mixed-replace; boundary={BOUNDARY}"


class StreamCount:
    """How many camera streams are open (thread-safe), for the log and the server's health."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._open = 0

    def __enter__(self) -> StreamCount:
        with self._lock:
            self._open += 1
        return self

    def __exit__(self, *exc: object) -> None:
        with self._lock:
            self._open -= 1

    @property
    def open(self) -> int:
        with self._lock:
            return self._open


def part(jpeg: bytes) -> bytes:
    """One multipart part holding ``jpeg``."""
    head = f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(jpeg)}\r\n\r\n".encode("ascii")
    return head + jpeg + b"\r\n"


def mjpeg_parts(
    frames: Callable[[], bytes | None],
    stopping: threading.Event,
    count: StreamCount,
    *,
    fps: float = STREAM_FPS,
    repeat_s: float = REPEAT_S,
) -> Iterator[bytes]:
    """Parts of the newest frame from ``frames`` (None: no frame now) until ``stopping`` is set or the
    consumer closes the generator. Frames are compared by identity: a camera that hands out the same
    bytes object again has no new frame."""
    period = 1.0 / fps
    with count:
        last: bytes | None = None
        waited = 0.0
        while not stopping.is_set():
            frame = frames()
            if frame is not None and (frame is not last or waited >= repeat_s):
                yield part(frame)
                last, waited = frame, 0.0
            if stopping.wait(period):
                return
            waited += period
