"""`VideoRecorder`: the camera recorded as MP4/H.264 (or WebM, see `atemr.io.video_file`) while RECORD is on.

A scheduler component ticked at the camera's rate. Its tick, on the robot's thread, only hands each new
frame (with the robot's time) to a bounded queue; a worker thread, one per recording, encodes and writes
them, so an encoder that is slow or a disk that stalls never delays the control loop. When the queue is
full the frame is dropped and counted (the video then skips, at the right times, instead of the robot
waiting). `begin` and `end` come from the web server's threads.

The file is written as ``video-<time>.mp4.part`` and renamed to ``.mp4`` once it is finished, so the media
page lists only videos that play (an MP4 has no index until it is closed). `end` waits for the worker to
finish (at most `FINISH_WAIT_S`; a slower finish still completes and renames the file). A ``.part`` left by
a robot that died while recording cannot be played; `start` names such files in a warning and leaves them.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from atemr.errors import HardwareError
from atemr.io.video_file import VideoFileError, VideoFormat, VideoWriter, video_format

log = logging.getLogger(__name__)

#: The newest camera frame, a new array per frame (None before the first).
FrameSource = Callable[[], "NDArray[np.uint8] | None"]
#: Frames waiting for the encoder at most (about 14 MB at 640×480); more are dropped.
QUEUE_FRAMES = 16
#: Longest `end` waits for the encoder to finish the file.
FINISH_WAIT_S = 10.0
#: What the file is called while it is written.
PART = ".part"


class _Recording:
    """One video being recorded: its queue, its worker thread and its file."""

    def __init__(self, path: Path, fmt: VideoFormat, rate_hz: float, queue_frames: int) -> None:
        self.path = path
        self.part = path.with_name(path.name + PART)
        self.writer = VideoWriter(self.part, fmt, rate_hz)
        self.queue: queue.Queue[tuple[NDArray[np.uint8], float] | None] = queue.Queue(queue_frames)
        self.dropped = 0
        self.error: str | None = None
        self.thread = threading.Thread(target=self._run, name=f"video-{path.stem}", daemon=True)

    def offer(self, frame: NDArray[np.uint8], t_s: float) -> None:
        """Robot's thread: queue a frame, or drop it when the encoder is behind."""
        try:
            self.queue.put_nowait((frame, t_s))
        except queue.Full:
            self.dropped += 1

    def _run(self) -> None:
        try:
            while self.error is None and (item := self.queue.get()) is not None:
                self._write(*item)
        finally:
            self._finish()

    def _write(self, frame: NDArray[np.uint8], t_s: float) -> None:
        try:
            self.writer.write(frame, t_s)
        except Exception as exc:  # disk full, encoder failure: keep what was written, stop writing
            self.error = f"{type(exc).__name__}: {exc}"
            log.error("video %s: recording stopped: %s", self.path.name, self.error)

    def _finish(self) -> None:
        """Close the file and give it its name; a video with no frame is removed."""
        try:
            self.writer.close()
        except Exception as exc:
            self.error = self.error or f"cannot finish the file: {type(exc).__name__}: {exc}"
            log.error("video %s: %s", self.path.name, self.error)
        try:
            if self.writer.frames == 0:
                self.part.unlink(missing_ok=True)
            else:
                self.part.replace(self.path)
        except OSError as exc:
            self.error = self.error or f"cannot finish the file: {exc.strerror}"
            log.error("video %s: %s", self.path.name, self.error)

    def stop(self, wait_s: float) -> bool:
        """Ask the worker to finish (after the frames queued); True when it has, within ``wait_s``."""
        deadline = time.monotonic() + wait_s
        with contextlib.suppress(queue.Full):  # full: the worker stopped on an error and takes no more
            self.queue.put(None, timeout=wait_s)
        self.thread.join(max(0.0, deadline - time.monotonic()))
        return not self.thread.is_alive()


class VideoRecorder:
    """Records the camera into ``videos_dir`` while on (see the module docstring).

    ``frames`` gives the newest camera frame; ``rate_hz`` is the camera's rate (a hint for the encoder:
    frames are timed by the robot's clock); ``fmt`` is `atemr.io.video_file.video_format` by default.
    """

    name = "video_recorder"

    def __init__(self, videos_dir: Path, frames: FrameSource, wall_time: Callable[[], float], *,
                 rate_hz: float = 10.0, fmt: VideoFormat | None = None, queue_frames: int = QUEUE_FRAMES,
                 on_failure: Callable[[str], None] | None = None) -> None:
        self.videos_dir = videos_dir
        self.frames = frames
        self.wall_time = wall_time
        self.rate_hz = rate_hz
        self.format = fmt
        self.queue_frames = queue_frames
        #: Told (from the robot's thread) why a recording stopped by itself: the disk filled, the encoder failed.
        self.on_failure = on_failure
        self._lock = threading.Lock()
        self._recording: _Recording | None = None
        self._last: _Recording | None = None
        self._last_frame: object = None

    @property
    def recording(self) -> bool:
        with self._lock:
            return self._recording is not None

    @property
    def path(self) -> Path | None:
        """The file being written (or the last one written)."""
        with self._lock:
            current = self._recording or self._last
            return None if current is None else current.path

    @property
    def frames_written(self) -> int:
        """Frames the current (or last) video holds so far."""
        with self._lock:
            current = self._recording or self._last
            return 0 if current is None else current.writer.frames

    @property
    def frames_dropped(self) -> int:
        """Frames of the current (or last) video dropped because the encoder was behind."""
        with self._lock:
            current = self._recording or self._last
            return 0 if current is None else current.dropped

    def start(self) -> None:
        """Scheduler start: nothing to open until the operator records; say which unfinished files a robot
        that died while recording left behind."""
        left = sorted(p.name for p in self.videos_dir.glob(f"*{PART}")) if self.videos_dir.is_dir() else []
        if left:
            log.warning("unfinished videos from an earlier run (unplayable, left as they are): %s", ", ".join(left))

    def begin(self) -> Path:
        """Start a new video; `HardwareError` if already recording, or if no encoder or file can be had."""
        with self._lock:
            if self._recording is not None:
                raise HardwareError(f"already recording {self._recording.path.name}", component="camera")
            try:
                fmt = self.format or video_format()
            except VideoFileError as exc:
                raise HardwareError(str(exc), component="camera") from None
            stamp = datetime.fromtimestamp(self.wall_time(), UTC).strftime("%Y%m%d-%H%M%S-%f")
            path = self.videos_dir / f"video-{stamp}{fmt.suffix}"
            recording = _Recording(path, fmt, self.rate_hz, self.queue_frames)
            try:
                self.videos_dir.mkdir(parents=True, exist_ok=True)
                recording.part.open("xb").close()  # the name is ours; the encoder writes it on the first frame
            except OSError as exc:
                raise HardwareError(f"cannot create {path.name}: {exc.strerror}", component="camera") from None
            recording.thread.start()
            self._recording, self._last_frame = recording, None
        log.info("recording %s", path)
        return path

    def end(self) -> Path:
        """Finish the video and return its path; `HardwareError` if nothing is being recorded, or saying why
        the video is missing or cut short (no camera frame came, the disk is full, ...)."""
        with self._lock:
            recording, self._recording = self._recording, None
            if recording is None:
                raise HardwareError("no video is being recorded", component="camera")
            self._last = recording
        finished = recording.stop(FINISH_WAIT_S)
        frames, dropped = recording.writer.frames, recording.dropped
        log.info("recorded %s (%d frames, %d dropped%s)", recording.path, frames, dropped,
                 "" if finished else f"; still being finished after {FINISH_WAIT_S:g} s")
        if finished and frames == 0:
            raise HardwareError(f"{recording.path.name}: no camera frame came while recording; nothing saved",
                                component="camera")
        if recording.error is not None:
            raise HardwareError(f"{recording.path.name} stopped after {frames} frames: {recording.error}",
                                component="camera")
        return recording.path

    def tick(self, now: float) -> None:
        """Hand a new camera frame to the encoder (the robot's thread: no encoding here); a recording whose
        worker failed is ended and reported."""
        with self._lock:
            recording = self._recording
            if recording is None:
                return
            if recording.error is not None:
                self._recording, self._last = None, recording
            else:
                frame = self.frames()
                if frame is not None and frame is not self._last_frame:
                    self._last_frame = frame
                    recording.offer(frame, now)
                return
        if self.on_failure is not None:
            self.on_failure(f"recording {recording.path.name} stopped after {recording.writer.frames} frames: "
                            f"{recording.error}")

    def shutdown(self) -> None:
        """Finish a video still being recorded, so stopping the robot keeps it."""
        if self.recording:
            try:
                self.end()
            except HardwareError as exc:
                log.warning("%s", exc)
