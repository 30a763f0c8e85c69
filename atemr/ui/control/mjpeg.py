"""The camera as MJPEG: ``multipart/x-mixed-replace`` parts, one JPEG each, for an ``<img>`` to show.

A stream reads frames only while its client is connected (the generator runs in that client's request
thread) and ends when the client leaves (werkzeug's write fails and closes the generator) or the server
stops (the ``stopping`` event). It looks for a new frame `POLLS_PER_FRAME` times per frame period and
sends each new one at once, at most `STREAM_FPS` times a second on average, and repeats the last one every
`REPEAT_S` so a client that left unnoticed is found out. (Looking once per period, as the camera's own
rate, lost a frame whenever writing a part delayed the next look past the next frame: 8-9 fps from a
10 fps camera.)
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator

#: Frames per second a stream aims at (the simulator's camera runs at 10 fps).
STREAM_FPS = 10.0
#: Looks for a new frame per frame period (a new frame waits at most a quarter period).
POLLS_PER_FRAME = 4
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
    clock: Callable[[], float] = time.monotonic,
) -> Iterator[bytes]:
    """Parts of the newest frame from ``frames`` (None: no frame now) until ``stopping`` is set or the
    consumer closes the generator. Frames are compared by identity: a camera that hands out the same
    bytes object again has no new frame. The rate is held to ``fps`` by a token bucket on ``clock``
    (seconds) with room for two parts, so a frame sent late (the thread was kept waiting) does not hold the
    next one back, while a faster camera is thinned to ``fps``."""
    period = 1.0 / fps
    with count:
        last: bytes | None = None
        sent_at = checked_at = clock()
        tokens = 1.0
        while not stopping.is_set():
            frame = frames()
            now = clock()
            tokens = min(2.0, tokens + (now - checked_at) * fps)
            checked_at = now
            if frame is not None and frame is not last and tokens >= 1.0:
                tokens -= 1.0
                yield part(frame)
                last, sent_at = frame, now
            elif frame is not None and now - sent_at >= repeat_s:
                yield part(frame)  # the same frame again: tells a client that left unnoticed
                last, sent_at = frame, now
            if stopping.wait(period / POLLS_PER_FRAME):
                return
