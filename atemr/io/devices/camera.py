"""The real front camera through OpenCV (driver ``opencv``): a V4L2 camera, a video file or a network stream.

Frames leave the driver exactly as the simulator's camera publishes them (`atemr.io.sim.camera`): numpy
``uint8`` arrays of shape (height, width, 3), RGB, C-contiguous, a new array per frame. Consumers (the
dashboard's JPEG stream, the video recorder, the behaviour trees' ``CaptureImage``) therefore cannot tell a
real camera from the simulated one. OpenCV decodes to BGR, so every kept frame is converted, and resized to
the configured size when the device gives another one (a camera that ignores the requested resolution).

The source (``devices.camera.source``) says what is opened, and how:

* ``"0"``: a V4L2 index, ``/dev/video0`` or any ``/dev/...`` path (udev's ``/dev/v4l/by-id/...``): a local
  camera, opened with the V4L2 backend on Linux and asked for the configured size and frame rate;
* ``rtsp://...``, ``http://...`` (any ``scheme://``): a network stream, opened by OpenCV's default backend
  (FFmpeg) with open and read timeouts, so a camera that vanishes from the network cannot block the reader
  thread for FFmpeg's default 30 s;
* anything else: a video file, played at its own frame rate and **looped** when it ends. A file is a stand-in
  for a camera on the bench and in tests; its end is not a fault, so it is reopened from the start instead of
  being reported unplugged (which would make the device unhealthy every time the clip ends).

A live source that stops giving frames (unplugged, the stream closed, a read timeout) raises `OSError` from
`_read`: `ThreadedDevice` closes it, reports why in ``health`` and reopens it until it is back.

How soon a lost camera shows: ``health`` turns unhealthy as soon as the reader gives the source up, and in
any case once the newest frame is older than ``max_age_s`` (by default, as the simulated camera's, three frame
periods and at least 1 s). Freshness is judged on the scheduler's side, so that bound holds even while the
reader thread is stuck inside OpenCV. A closed stream or an unplugged device fails the read at once; a source
that hangs is given up after the read timeout (2 s by default: ``CAP_PROP_READ_TIMEOUT_MSEC`` for FFmpeg,
``OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT`` for V4L2), then reopened every `REOPEN_S` until it answers.

At most ``fps`` frames per second are kept, timed by the robot's clock: the rest are grabbed (so a V4L2
queue never fills with stale frames) but not decoded nor converted, which is where the CPU goes.

OpenCV is optional (the ``camera`` extra): this module imports without it, and building the driver without it
is a `ConfigError` that says what to install.
"""

from __future__ import annotations

import errno
import importlib
import logging
import math
import os
import re
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal
from urllib.parse import urlsplit, urlunsplit

import numpy as np
from numpy.typing import NDArray

from atemr.errors import ConfigError
from atemr.io.devices.base import DeviceInfo, ThreadedDevice
from atemr.io.devices.config import CameraDeviceConfig

log = logging.getLogger(__name__)

Frame = NDArray[np.uint8]
SourceKind = Literal["index", "device", "url", "file"]

#: What to install when OpenCV is missing.
INSTALL_HINT = "the opencv driver needs OpenCV: pip install 'atemr[camera]'"
#: How long a network stream may take to open (connect, handshake, probe), in seconds.
OPEN_TIMEOUT_S = 5.0
#: How long a network stream may send nothing before it counts as lost and is reopened, in seconds.
READ_TIMEOUT_S = 2.0
#: The environment variable OpenCV's V4L2 backend reads its frame timeout from, in whole seconds.
V4L2_TIMEOUT_ENV = "OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT"
#: Frames waiting for the scheduler at most: when it stalls the oldest are dropped (64 queued 640x480 frames,
#: the base's default, would hold about 59 MB).
QUEUE_FRAMES = 4
#: The longest `_read` sleeps while pacing a video file (the reader thread must notice ``shutdown``).
MAX_PACE_SLEEP_S = 0.1
#: A frame may arrive this fraction of a period early and still be kept: arrival times jitter (USB, the
#: scheduler, the network), and a camera running at exactly the capped rate must not lose frames to it.
EARLY_FRACTION = 0.5

_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")


def require_opencv() -> Any:
    """The cv2 module, or a `ConfigError` saying how to install it.

    Imported here, when a driver is built, not with this module: a robot without a camera (or with the
    simulated one) never needs OpenCV installed. Typed ``Any`` so the code type-checks with or without it.
    """
    try:
        return importlib.import_module("cv2")
    except ImportError:
        raise ConfigError(INSTALL_HINT, path="devices.camera.driver") from None


def limit_v4l2_wait(seconds: float) -> None:
    """Bound how long OpenCV's V4L2 backend waits for a frame from a camera that stopped sending.

    V4L2 ignores ``CAP_PROP_READ_TIMEOUT_MSEC``; it waits ``OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT`` seconds (10 by
    default, read once, at the first V4L2 frame of the process) before a read fails, and for that long the
    reader thread can neither reopen the camera nor stop. Set only when unset, so an operator's value wins.
    """
    os.environ.setdefault(V4L2_TIMEOUT_ENV, str(max(1, math.ceil(seconds))))


# -- the source -----------------------------------------------------------------------------------------------
def redact(source: str) -> str:
    """``source`` with a URL's password hidden: the source is shown in health, logs and the dashboard."""
    if not _URL.match(source):
        return source
    parts = urlsplit(source)
    if parts.password is None:
        return source
    host = parts.hostname or ""
    if parts.port is not None:
        host = f"{host}:{parts.port}"
    return urlunsplit(parts._replace(netloc=f"{parts.username}:***@{host}"))


@dataclass(frozen=True)
class CameraSource:
    """What ``devices.camera.source`` names: a V4L2 index or device path, a stream URL, or a video file."""

    text: str
    kind: SourceKind
    index: int | None = None

    @classmethod
    def parse(cls, text: str) -> CameraSource:
        """Classify ``text``; an empty source is a `ConfigError` (OpenCV would try some default device)."""
        text = text.strip()
        if not text:
            raise ConfigError("the camera source is empty", path="devices.camera.source")
        if text.isdigit():
            return cls(text, "index", int(text))
        if _URL.match(text):
            return cls(text, "url")
        if text.startswith("/dev/"):
            return cls(text, "device")
        return cls(text, "file")

    @property
    def local(self) -> bool:
        """A camera on this computer (V4L2), as opposed to a stream or a file."""
        return self.kind in ("index", "device")

    @property
    def shown(self) -> str:
        """The source as messages show it (no password)."""
        return redact(self.text)

    def device_path(self) -> str | None:
        """The device node to check before opening a local camera (an index is ``/dev/videoN`` on Linux)."""
        if self.kind == "device":
            return self.text
        if self.kind == "index" and sys.platform.startswith("linux"):
            return f"/dev/video{self.index}"
        return None


# -- frames ---------------------------------------------------------------------------------------------------
def to_rgb(image: Any, width: int, height: int) -> Frame:
    """An OpenCV image (BGR, BGRA or grey) as the robot's frame: RGB uint8 (height, width, 3), C-contiguous."""
    cv = require_opencv()
    array = np.asarray(image)
    if array.dtype != np.uint8:
        raise OSError(f"the camera gives {array.dtype} pixels; only 8-bit images are supported")
    if array.ndim == 2 or (array.ndim == 3 and array.shape[2] == 1):
        code = cv.COLOR_GRAY2RGB
    elif array.ndim == 3 and array.shape[2] == 4:
        code = cv.COLOR_BGRA2RGB
    elif array.ndim == 3 and array.shape[2] == 3:
        code = cv.COLOR_BGR2RGB
    else:
        raise OSError(f"the camera gives images of shape {array.shape}, not an 8-bit colour or grey image")
    rgb = cv.cvtColor(array, code)
    if rgb.shape[:2] != (height, width):
        shrink = rgb.shape[0] * rgb.shape[1] > width * height
        rgb = cv.resize(rgb, (width, height), interpolation=cv.INTER_AREA if shrink else cv.INTER_LINEAR)
    return np.ascontiguousarray(rgb, dtype=np.uint8)


class RateCap:
    """Admits at most ``rate_hz`` events per second of a clock and drops the rest.

    Admissions follow a fixed schedule (each one moves the next due time on by one period) rather than "one
    period after the last admitted", so a source slightly faster than the cap is not halved by jitter, and a
    frame may come up to `EARLY_FRACTION` of a period early. After a gap longer than a period (a slow source,
    a stall) the schedule restarts, so no burst catches up. Over any window of ``w`` seconds at most
    ``rate_hz * w + 1 + EARLY_FRACTION`` events are admitted.
    """

    def __init__(self, rate_hz: float) -> None:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"the frame rate must be positive, got {rate_hz}")
        self.period = 1.0 / rate_hz
        self._due: float | None = None

    def admit(self, t: float) -> bool:
        """Whether an event at time ``t`` is kept."""
        if self._due is not None and t < self._due - EARLY_FRACTION * self.period:
            return False
        if self._due is None or t - self._due >= self.period:
            self._due = t + self.period
        else:
            self._due += self.period
        return True


# -- the driver -----------------------------------------------------------------------------------------------
class OpenCvCamera(ThreadedDevice[Frame]):
    """The front camera read with OpenCV by a thread of its own (see the module docstring)."""

    def __init__(self, source: str, *, now: Callable[[], float], width: int = 640, height: int = 480,
                 fps: float = 10.0, name: str = "camera", max_age_s: float | None = None,
                 open_timeout_s: float = OPEN_TIMEOUT_S, read_timeout_s: float = READ_TIMEOUT_S) -> None:
        require_opencv()
        self.source = CameraSource.parse(source)
        if max_age_s is None:  # as the simulated camera's: a few frame periods, at least a second
            max_age_s = max(1.0, 3.0 / fps)
        super().__init__(name, now=now, max_age_s=max_age_s, port=self.source.shown, queue_size=QUEUE_FRAMES)
        self.width, self.height, self.fps = width, height, fps
        self.open_timeout_s, self.read_timeout_s = open_timeout_s, read_timeout_s
        self._cap_rate = RateCap(fps)
        self._capture: Any = None
        self._grabbed = False  # the first frame of a fresh capture is grabbed by `_open` and not yet used
        self._backend: str | None = None
        self._file_period: float | None = None
        self._next_wall: float | None = None
        #: Frames grabbed from the source, frames dropped by the ``fps`` cap, and times a video file looped.
        self.frames_read = 0
        self.frames_skipped = 0
        self.loops = 0

    @classmethod
    def from_config(cls, cfg: CameraDeviceConfig, *, now: Callable[[], float], name: str = "camera") -> OpenCvCamera:
        """The camera that ``devices.camera`` describes; a `ConfigError` when OpenCV is not installed."""
        return cls(cfg.source, now=now, width=cfg.width, height=cfg.height, fps=cfg.fps, name=name)

    def info(self) -> DeviceInfo:
        """Driver ``opencv``, the source (password hidden) and the OpenCV backend that opened it."""
        return DeviceInfo(kind="camera", driver="opencv", port=self.source.shown, model=self._backend)

    def missing_hint(self, error: BaseException) -> str:
        """Why the camera could not be opened, and what to do about it."""
        message = f"{self.name}: {error}"
        if isinstance(error, PermissionError):
            return message + " (add the user to the `video` group: sudo usermod -aG video $USER, then log in again)"
        if self.source.local:
            return message + " (is the camera plugged in? `v4l2-ctl --list-devices` lists the cameras)"
        if self.source.kind == "url":
            return message + " (is the camera on the network, and are the URL and its credentials right?)"
        return message + " (check devices.camera.source)"

    # -- opening ----------------------------------------------------------------------------------------------
    def _open(self) -> None:
        capture = self._open_capture()
        if not capture.grab():
            capture.release()
            raise OSError(f"{self.source.shown} opened but gave no frame")
        self._capture, self._grabbed = capture, True

    def _open_capture(self) -> Any:
        """A `cv2.VideoCapture` that is open on the source; `OSError` saying why not."""
        cv = require_opencv()
        if self.source.local:
            self._check_device()
            limit_v4l2_wait(self.read_timeout_s)
            backend = cv.CAP_V4L2 if sys.platform.startswith("linux") else cv.CAP_ANY
            target: int | str = self.source.index if self.source.index is not None else self.source.text
            capture = cv.VideoCapture(target, backend)
        elif self.source.kind == "url":
            capture = cv.VideoCapture(self.source.text, cv.CAP_ANY, self._timeouts())
        else:
            if "%" not in self.source.text and not os.path.isfile(self.source.text):  # %: an image sequence
                raise FileNotFoundError(errno.ENOENT, f"no video file {self.source.text}")
            capture = cv.VideoCapture(self.source.text, cv.CAP_ANY)
        if not capture.isOpened():
            capture.release()
            raise OSError(self._not_opened())
        self._backend = self._backend_name(capture)
        if self.source.local:
            self._ask_format(capture)
        self._file_period = self._file_frame_period(capture) if self.source.kind == "file" else None
        return capture

    def _check_device(self) -> None:
        """A missing or forbidden device node, said plainly (OpenCV only says it could not open it)."""
        path = self.source.device_path()
        if path is None:
            return
        if not os.path.exists(path):
            raise FileNotFoundError(errno.ENOENT, f"no camera device {path}")
        if not os.access(path, os.R_OK | os.W_OK):
            raise PermissionError(errno.EACCES, f"no permission to open {path}")

    def _not_opened(self) -> str:
        shown = self.source.shown
        if self.source.local:
            return (f"OpenCV could not open {shown} with V4L2 (in use by another program, no permission, or not a "
                    "capture device)")
        if self.source.kind == "url":
            return (f"OpenCV could not open the stream {shown} (refused, unreachable, or no answer within "
                    f"{self.open_timeout_s:g} s)")
        return f"OpenCV could not open the video file {shown} (not a video it can decode)"

    def _timeouts(self) -> list[int]:
        """Open and read timeouts for a network stream, where this OpenCV has them (FFmpeg honours both; without
        them a dead stream blocks a read for FFmpeg's default 30 s)."""
        cv = require_opencv()
        if not (hasattr(cv, "CAP_PROP_OPEN_TIMEOUT_MSEC") and hasattr(cv, "CAP_PROP_READ_TIMEOUT_MSEC")):
            return []
        return [cv.CAP_PROP_OPEN_TIMEOUT_MSEC, round(self.open_timeout_s * 1000),
                cv.CAP_PROP_READ_TIMEOUT_MSEC, round(self.read_timeout_s * 1000)]

    def _ask_format(self, capture: Any) -> None:
        """Ask a local camera for the configured size and rate; one that refuses is resized in `to_rgb`."""
        cv = require_opencv()
        for prop, value in ((cv.CAP_PROP_FRAME_WIDTH, self.width), (cv.CAP_PROP_FRAME_HEIGHT, self.height),
                            (cv.CAP_PROP_FPS, self.fps)):
            if not capture.set(prop, float(value)):
                log.debug("%s: %s did not accept property %d = %s", self.name, self.source.shown, prop, value)

    def _file_frame_period(self, capture: Any) -> float:
        """Seconds between a video file's frames (its own rate; the configured one when it does not say)."""
        rate = float(capture.get(require_opencv().CAP_PROP_FPS))
        if not (math.isfinite(rate) and 0.1 <= rate <= 1000.0):
            rate = self.fps
        return 1.0 / rate

    @staticmethod
    def _backend_name(capture: Any) -> str | None:
        try:
            return str(capture.getBackendName())
        except Exception:  # older builds raise when the backend has no name
            return None

    # -- reading ----------------------------------------------------------------------------------------------
    def _read(self) -> list[Frame]:
        capture = self._capture
        if capture is None:
            raise OSError(f"{self.source.shown} is not open")
        if not self._paced():
            return []
        if self._grabbed:
            self._grabbed = False
        elif not capture.grab():
            return self._ended()
        self.frames_read += 1
        if not self._cap_rate.admit(self.stamp()):
            self.frames_skipped += 1
            return []
        ok, image = capture.retrieve()
        if not ok or image is None:
            raise OSError(f"a frame from {self.source.shown} could not be decoded")
        return [to_rgb(image, self.width, self.height)]

    def _paced(self) -> bool:
        """For a video file, wait until its next frame is due (wall time: a file plays at its own speed);
        False when that is further away than `MAX_PACE_SLEEP_S`. Live sources are paced by the device."""
        if self._file_period is None:
            return True
        now = time.monotonic()
        if self._next_wall is None or now - self._next_wall > 1.0:  # first frame, or far behind: restart
            self._next_wall = now
        delay = self._next_wall - now
        if delay > MAX_PACE_SLEEP_S:
            time.sleep(MAX_PACE_SLEEP_S)
            return False
        if delay > 0:
            time.sleep(delay)
        self._next_wall += self._file_period
        return True

    def _ended(self) -> list[Frame]:
        """No next frame: a video file starts again; a live source is lost (the base reopens it)."""
        if self.source.kind != "file":
            raise OSError(f"no frame from {self.source.shown} (unplugged, or the stream ended or timed out)")
        self._close()
        self._open()
        self.loops += 1
        if self._next_wall is not None and self._file_period is not None:
            self._next_wall -= self._file_period  # this call gave no frame: keep the cadence across the loop
        return []

    def _close(self) -> None:
        capture, self._capture, self._grabbed = self._capture, None, False
        if capture is None:
            return
        try:
            capture.release()
        except Exception:
            log.exception("%s: releasing %s failed", self.name, self.source.shown)
