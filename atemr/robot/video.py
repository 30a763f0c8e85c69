"""`VideoRecorder`: the camera recorded as Motion-JPEG while the operator's RECORD is on.

A scheduler component ticked at the camera's rate: each tick that finds a new frame appends its JPEG to
the open ``data_dir/media/videos/<time>.mjpeg`` (a plain concatenation of JPEG images, which players such
as ffplay/VLC and the dashboard's media page accept). `start` and `stop` come from the web server's
threads; the file is opened and closed under a lock, and frames are written only by `tick`.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import BinaryIO

from atemr.errors import HardwareError

log = logging.getLogger(__name__)

#: A frame and its JPEG: ``(key, jpeg)`` where ``key`` changes with every new camera frame.
FrameSource = Callable[[], "tuple[object, bytes] | None"]


class VideoRecorder:
    """Writes camera frames to ``videos_dir`` as ``.mjpeg`` while recording (see the module docstring)."""

    name = "video_recorder"

    def __init__(self, videos_dir: Path, frames: FrameSource, wall_time: Callable[[], float]) -> None:
        self.videos_dir = videos_dir
        self.frames = frames
        self.wall_time = wall_time
        self.frames_written = 0
        self._lock = threading.Lock()
        self._file: BinaryIO | None = None
        self._path: Path | None = None
        self._last_key: object = None

    @property
    def recording(self) -> bool:
        with self._lock:
            return self._file is not None

    @property
    def path(self) -> Path | None:
        """The file being written (or the last one written)."""
        with self._lock:
            return self._path

    def start(self) -> None:
        """Scheduler start: nothing to open until the operator records."""

    def begin(self) -> Path:
        """Open a new video file; `HardwareError` if already recording or the file cannot be created."""
        with self._lock:
            if self._file is not None:
                raise HardwareError(f"already recording {self._path.name if self._path else 'a video'}",
                                    component="camera")
            stamp = datetime.fromtimestamp(self.wall_time(), UTC).strftime("%Y%m%d-%H%M%S-%f")
            path = self.videos_dir / f"video-{stamp}.mjpeg"
            try:
                self.videos_dir.mkdir(parents=True, exist_ok=True)
                self._file = path.open("xb")
            except OSError as exc:
                raise HardwareError(f"cannot create {path.name}: {exc.strerror}", component="camera") from None
            self._path, self._last_key = path, None
            self.frames_written = 0
        log.info("recording %s", path)
        return path

    def end(self) -> Path:
        """Close the video file; `HardwareError` if nothing is being recorded."""
        with self._lock:
            file, path = self._file, self._path
            if file is None or path is None:
                raise HardwareError("no video is being recorded", component="camera")
            self._file = None
            file.close()
        log.info("recorded %s (%d frames)", path, self.frames_written)
        return path

    def tick(self, now: float) -> None:
        with self._lock:
            if self._file is None:
                return
            frame = self.frames()
            if frame is None or frame[0] is self._last_key:
                return
            self._last_key = frame[0]
            try:
                self._file.write(frame[1])
            except OSError as exc:
                log.error("video recording stopped: %s", exc)
                self._file.close()
                self._file = None
                return
            self.frames_written += 1

    def shutdown(self) -> None:
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None
