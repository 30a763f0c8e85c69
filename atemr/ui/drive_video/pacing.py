"""Which camera frames go out as video: each new one at once, at most `MAX_FPS` a second, and the last one
again after `REPEAT_S` without a new one.

Frames are told apart by identity (a camera hands out a new array for each frame), as the MJPEG stream
does. Repeating the last frame keeps the connection's video alive while the camera shows nothing new (a
still simulation, a camera that stopped), so a page that joins late or asks for a key frame gets a picture
within `REPEAT_S`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

#: Where the frames come from: the newest camera frame (H x W x 3 RGB), or None while there is none.
Frames = Callable[[], "NDArray[np.uint8] | None"]
#: Most frames per second sent (a faster camera is thinned).
MAX_FPS = 30.0
#: Longest time without a frame sent: the last one goes again after it.
REPEAT_S = 1.0


class FramePacer:
    """Decides, each time the sender looks, whether the newest frame goes out now."""

    def __init__(self, *, max_fps: float = MAX_FPS, repeat_s: float = REPEAT_S) -> None:
        self.min_interval_s = 1.0 / max_fps
        self.repeat_s = repeat_s
        self._last: object = None
        self._sent_at = -float("inf")

    def take(self, frame: object | None, now: float) -> bool:
        """True when ``frame`` (None: no frame yet) should be sent at ``now`` (seconds, monotonic); it then
        counts as sent."""
        if frame is None:
            return False
        since = now - self._sent_at
        fresh = frame is not self._last and since >= self.min_interval_s
        if fresh or since >= self.repeat_s:
            self._last, self._sent_at = frame, now
            return True
        return False
