"""The drive camera as an aiortc video track: the newest camera frame, paced by `FramePacer`.

aiortc's sender awaits `CameraTrack.recv` for each frame and encodes it in the loop's executor. `recv`
looks at the frame source every `POLL_S` (reading the newest frame is one attribute read on the robot's
camera: nothing waits on the control loop, and the control loop waits on nothing here), so a new frame
leaves at most `POLL_S` after it was captured. Timestamps are the monotonic time of sending, on the 90 kHz
clock of RTP video.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from fractions import Fraction

import numpy as np
from aiortc import MediaStreamTrack
from aiortc.mediastreams import MediaStreamError
from av import VideoFrame

from atemr.ui.drive_video.pacing import FramePacer, Frames

#: How often the track looks for a new camera frame (seconds).
POLL_S = 0.005
#: The RTP clock of video (RFC 3551).
VIDEO_CLOCK_HZ = 90_000

class CameraTrack(MediaStreamTrack):
    """Video of the frames ``frames()`` returns (H x W x 3 RGB uint8, or None while there is none)."""

    kind = "video"

    def __init__(self, frames: Frames, *, pacer: FramePacer | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        self._frames = frames
        self._pacer = pacer or FramePacer()
        self._clock = clock
        self._start: float | None = None
        self.sent = 0

    async def recv(self) -> VideoFrame:
        while True:
            if self.readyState != "live":
                raise MediaStreamError
            frame = self._frames()
            now = self._clock()
            if self._pacer.take(frame, now):
                break
            await asyncio.sleep(POLL_S)
        assert frame is not None
        if self._start is None:
            self._start = now
        video = VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")
        video.pts = round((now - self._start) * VIDEO_CLOCK_HZ)
        video.time_base = Fraction(1, VIDEO_CLOCK_HZ)
        self.sent += 1
        return video
