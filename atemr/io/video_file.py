"""Video files: the camera written as MP4/H.264 (or WebM/VP8), and the first frame read back for a preview.

Through PyAV (the ``av`` wheel, which carries FFmpeg's libraries, x264 and libvpx among them), so nothing
has to be installed on the robot besides the Python package.

Why MP4/H.264: it is what browsers (Chromium, Debian's build included: it uses the system FFmpeg and
answers ``canPlayType('video/mp4; codecs="avc1.42E01E"')`` with "probably"; Firefox; Safari), phones and
desktop players (VLC, the system players of Windows and macOS) all open. The ``moov`` index is moved to the
front when the file is closed (``+faststart``), so a browser starts playing before the whole file has come.
A PyAV build without an H.264 encoder falls back to WebM/VP8, which every browser plays and VLC opens
(`video_format` picks the first that the build has; `FORMATS` is the order).

Why the encoder's ``ultrafast`` preset and one encoder thread: the robot's CPU goes to the control loop first.
At 640×480 it costs about 8 ms a frame of noise (the worst case) on one core of a development machine
(``veryfast``: about 13 ms, for files about half as large).

Timing: each frame carries the time it was taken (the robot's clock), kept to the millisecond, so a camera
that skips a frame or a robot thread that runs late gives a video that still plays at the real speed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import av
import numpy as np
from av.container import OutputContainer
from av.video.stream import VideoStream
from numpy.typing import NDArray
from PIL import Image

from atemr.errors import AtemrError

#: Frame times are kept to the millisecond.
TIME_BASE = Fraction(1, 1000)
#: Largest frame a preview decodes (a video of a larger size is not previewed): 8K UHD.
MAX_PREVIEW_PIXELS = 7680 * 4320


class VideoFileError(AtemrError):
    """A video cannot be written (no encoder) or read (not a video, damaged, no picture, too large)."""


@dataclass(frozen=True)
class VideoFormat:
    """One way to write a video: the FFmpeg encoder and container, and what the file is called and served as."""

    codec: str
    container: str
    suffix: str
    mimetype: str
    options: dict[str, str] = field(default_factory=dict)
    container_options: dict[str, str] = field(default_factory=dict)
    #: Target bits per second, for encoders without a constant-quality mode by default (VP8); None: the encoder's.
    bit_rate: int | None = None


MP4_H264 = VideoFormat("libx264", "mp4", ".mp4", "video/mp4", {"preset": "ultrafast", "crf": "23"},
                       {"movflags": "+faststart"})
WEBM_VP8 = VideoFormat("libvpx", "webm", ".webm", "video/webm", {"deadline": "realtime", "cpu-used": "8"},
                       bit_rate=2_000_000)
#: Preferred first.
FORMATS: tuple[VideoFormat, ...] = (MP4_H264, WEBM_VP8)


def has_encoder(codec: str) -> bool:
    """Whether this PyAV build can encode with ``codec``."""
    try:
        av.codec.Codec(codec, "w")
    except ValueError:  # UnknownCodecError
        return False
    return True


@functools.cache
def video_format() -> VideoFormat:
    """The first of `FORMATS` this PyAV build can encode; `VideoFileError` when it has none of them."""
    for fmt in FORMATS:
        if has_encoder(fmt.codec):
            return fmt
    raise VideoFileError(f"this PyAV build (av {av.__version__}) has none of the video encoders "
                         f"{', '.join(f.codec for f in FORMATS)}; install the PyPI wheel of av")


class VideoWriter:
    """One video file being written, frame by frame; `close` finishes it (the file is unplayable before).

    The size is fixed by the first frame (rounded down to even numbers, as 4:2:0 video needs); a later
    frame of another size is scaled to it. Not thread-safe: one thread writes.
    """

    def __init__(self, path: Path, fmt: VideoFormat, rate_hz: float) -> None:
        self.path = path
        self.format = fmt
        self.rate_hz = rate_hz
        self.frames = 0
        self._container: OutputContainer | None = None
        self._stream: VideoStream | None = None
        self._t0: float | None = None
        self._last_pts = -1

    def _open(self, width: int, height: int) -> None:
        fmt = self.format
        container = av.open(str(self.path), "w", format=fmt.container, options=fmt.container_options)
        try:
            stream = container.add_stream(fmt.codec, rate=Fraction(round(self.rate_hz * 1000), 1000),
                                          options=fmt.options)
            if not isinstance(stream, VideoStream):
                raise VideoFileError(f"{fmt.codec} is not a video encoder")
            stream.width, stream.height, stream.pix_fmt = width - width % 2, height - height % 2, "yuv420p"
            stream.codec_context.time_base = TIME_BASE
            stream.codec_context.thread_count = 1  # one core at most: the robot's control loop needs the others
            stream.time_base = TIME_BASE
            if fmt.bit_rate is not None:
                stream.bit_rate = fmt.bit_rate
        except BaseException:
            container.close()
            raise
        self._container, self._stream = container, stream

    def write(self, frame: NDArray[np.uint8], t_s: float) -> bool:
        """Encode one RGB frame (height, width, 3) taken at ``t_s`` seconds; False when it is skipped (not
        later than the previous frame by a millisecond)."""
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.shape[0] < 2 or frame.shape[1] < 2:
            raise ValueError(f"a video frame is RGB (height, width, 3), at least 2×2, got shape {frame.shape}")
        if self._t0 is None:
            self._open(frame.shape[1], frame.shape[0])
            self._t0 = t_s
        container, stream = self._container, self._stream
        if container is None or stream is None:
            raise VideoFileError(f"{self.path.name} is closed")
        pts = round((t_s - self._t0) / TIME_BASE)
        if pts <= self._last_pts:
            return False
        video_frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")
        video_frame.pts, video_frame.time_base = pts, TIME_BASE
        for packet in stream.encode(video_frame):
            container.mux(packet)
        self._last_pts = pts
        self.frames += 1
        return True

    def close(self) -> None:
        """Flush the encoder and finish the file (nothing is written when no frame came)."""
        container, stream, self._container = self._container, self._stream, None
        if container is None or stream is None:
            return
        try:
            for packet in stream.encode():
                container.mux(packet)
        finally:
            container.close()


def first_frame(path: Path) -> Image.Image:
    """The first picture of the video at ``path``; `VideoFileError` saying why when there is none (not a
    video, damaged, no video stream, too large)."""
    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise VideoFileError(f"{path.name} has no video stream")
            stream = container.streams.video[0]
            pixels = stream.codec_context.width * stream.codec_context.height
            if pixels > MAX_PREVIEW_PIXELS:
                raise VideoFileError(f"{path.name} is {stream.codec_context.width}×{stream.codec_context.height}, "
                                     "too large to preview")
            for frame in container.decode(stream):
                return frame.to_image()
    except (av.FFmpegError, OSError, ValueError) as exc:
        raise VideoFileError(f"cannot read {path.name}: {exc}") from None
    raise VideoFileError(f"{path.name} has no picture")


__all__ = ["FORMATS", "MP4_H264", "WEBM_VP8", "VideoFileError", "VideoFormat", "VideoWriter", "first_frame",
           "has_encoder", "video_format"]
