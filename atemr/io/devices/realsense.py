"""The real RealSense D415 through pyrealsense2 (driver ``realsense``): its depth stream, and its colour stream
as the robot's front camera, from one pipeline.

KAY carries a D415 on its mast (thesis table 3.3): its depth feeds the obstacle layer and its colour stream can
be the camera the carer sees. A RealSense device is opened by one pipeline at a time (a second
``pipeline.start`` on the same camera fails, "Device or resource busy"), so both streams come from one reader,
`D415`: a thread of its own, like every real sensor (`atemr.io.devices.base.ThreadedDevice`), that opens the
pipeline with the streams asked of it, waits for framesets, stamps each with the robot's clock and hands each
kept frame over. The robot sees two devices, `D415Stream` views of it: ``depth`` gives `DepthImage` exactly as the
simulated D415 publishes it (`atemr.io.sim.depth`), so the depth obstacle layer cannot tell them apart, and
``camera`` gives RGB frames exactly as the other cameras do (`atemr.io.devices.camera`). When the camera is
unplugged or stops sending, the pipeline is stopped, both devices' health says why, and it is opened again
every `REOPEN_S` until the camera is back. The drivers share the reader through `DeviceContext.shared`
(`atemr.io.devices.drivers`); ``devices.depth.serial`` picks the camera for both.

The conversions from the SDK's frames are pure functions: `depth_image` (raw 16-bit units times the depth scale
the device reports, 1 mm on the D415, in metres; 0 kept as no data; readings beyond ``range_max_m`` dropped,
since the D415's error grows with the square of the distance; the stream's own intrinsics, whose ``ppx``/``ppy``
are the principal point) and `colour_frame` (the rgb8 stream copied into a new C-contiguous array, since the SDK
reuses its buffers).

pyrealsense2 is optional (the ``realsense`` extra): this module imports without it, and building either driver
without it is a `ConfigError` that names the extra.
"""

from __future__ import annotations

import importlib
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from atemr.domain.status import ComponentHealth
from atemr.errors import ConfigError
from atemr.io.devices.base import DeviceInfo, Publishes, Subscribers, ThreadedDevice, fresh
from atemr.io.devices.camera import RateCap
from atemr.io.devices.config import CameraDeviceConfig, DepthDeviceConfig
from atemr.msgs import CameraMount, DepthImage

log = logging.getLogger(__name__)

R = TypeVar("R")
Frame = NDArray[np.uint8]

#: What to install when pyrealsense2 is missing.
INSTALL_HINT = "the realsense driver needs pyrealsense2: pip install 'atemr[realsense]'"
#: How long a read waits for the next frameset before the camera counts as lost, in milliseconds.
FRAME_TIMEOUT_MS = 1000
#: Frames of each stream waiting for the scheduler at most (a 424 x 240 float depth frame is 400 kB, a
#: 640 x 480 colour frame 900 kB).
QUEUE_FRAMES = 4
#: The D415's minimum depth at 424 x 240 (its stereo search range), metres.
D415_RANGE_MIN_M = 0.3
#: The frame rates the D415's colour sensor streams at; the stream runs at the lowest that covers
#: ``devices.camera.fps`` (frames beyond it are dropped before conversion).
COLOUR_STREAM_FPS = (6, 15, 30, 60)


def require_realsense(path: str = "devices.depth.driver") -> Any:
    """The pyrealsense2 module, or a `ConfigError` at ``path`` naming the extra to install (typed ``Any``: the
    code type-checks with or without it)."""
    try:
        return importlib.import_module("pyrealsense2")
    except ImportError:
        raise ConfigError(INSTALL_HINT, path=path) from None


@dataclass(frozen=True)
class Intrinsics:
    """The depth stream's pinhole model, pixels (the SDK's ``rs.intrinsics``: fx, fy, ppx, ppy)."""

    fx: float
    fy: float
    ppx: float
    ppy: float

    @classmethod
    def of(cls, sdk: Any) -> Intrinsics:
        """From the SDK's intrinsics object."""
        return cls(float(sdk.fx), float(sdk.fy), float(sdk.ppx), float(sdk.ppy))


def depth_image(raw: NDArray[np.uint16], scale_m: float, intrinsics: Intrinsics, mount: CameraMount, t: float, *,
                range_min_m: float = D415_RANGE_MIN_M, range_max_m: float = 3.0) -> DepthImage:
    """A `DepthImage` from the SDK's z16 frame: ``raw`` units times ``scale_m``, 0 (no data) and readings outside
    ``range_min_m``..``range_max_m`` as 0, a new float32 array."""
    array = np.asarray(raw)
    if array.ndim != 2 or array.dtype != np.uint16:
        raise OSError(f"the depth camera gives {array.dtype} frames of shape {array.shape}, not 16-bit depth")
    if not scale_m > 0:
        raise OSError(f"the depth camera reports a depth scale of {scale_m}, not a positive number of metres")
    depth = array.astype(np.float32) * np.float32(scale_m)
    depth[(depth < range_min_m) | (depth > range_max_m)] = 0.0
    return DepthImage(t, depth, intrinsics.fx, intrinsics.fy, intrinsics.ppx, intrinsics.ppy, range_min_m,
                      range_max_m, mount)


def colour_frame(raw: Any, width: int, height: int) -> Frame:
    """The SDK's rgb8 colour frame as the robot's cameras give frames: a new C-contiguous ``uint8`` array of
    shape (height, width, 3), RGB. Another shape or type is a read error (the reader reopens the camera)."""
    array = np.asarray(raw)
    if array.shape != (height, width, 3) or array.dtype != np.uint8:
        raise OSError(f"the colour stream gives {array.dtype} frames of shape {array.shape}, not the "
                      f"{width} x {height} RGB asked for")
    return np.array(array, dtype=np.uint8, order="C", copy=True)


def colour_stream_fps(keep_hz: float) -> int:
    """The colour sensor's frame rate for a camera that keeps ``keep_hz`` frames a second."""
    return next((fps for fps in COLOUR_STREAM_FPS if fps >= keep_hz), COLOUR_STREAM_FPS[-1])


@dataclass(frozen=True)
class _DepthRequest:
    cfg: DepthDeviceConfig
    mount: CameraMount


class D415(ThreadedDevice[tuple[str, float, Any]]):
    """The camera itself: one pipeline, the streams its `D415Stream` devices asked for, one reader thread (see
    the module docstring). Readings are ``(stream, t, frame)``; the streams take theirs."""

    def __init__(self, *, now: Callable[[], float], serial: str = "", config_path: str = "devices.depth.driver",
                 ) -> None:
        self._rs = require_realsense(config_path)
        super().__init__("D415", now=now, max_age_s=1.0, port=f"RealSense {serial or '(first)'}",
                         queue_size=2 * QUEUE_FRAMES)
        self.serial = serial
        self._depth: _DepthRequest | None = None
        self._colour: CameraDeviceConfig | None = None
        self._caps: dict[str, RateCap] = {}
        self._pipeline: Any = None
        self._scale_m = 0.001
        self._intrinsics: Intrinsics | None = None
        self._info = DeviceInfo(kind="depth", driver="realsense")
        self._users = 0
        self._users_lock = threading.Lock()

    # -- the streams ----------------------------------------------------------------------------------------
    def depth_stream(self, cfg: DepthDeviceConfig, mount: CameraMount) -> D415Stream[DepthImage]:
        """The depth stream as the robot's ``depth`` device (``devices.depth``), mounted at ``mount``."""
        self._before_start("depth")
        self._depth = _DepthRequest(cfg, mount)
        self._caps["depth"] = RateCap(cfg.keep_hz)
        return D415Stream(self, "depth", "depth", "depth frame", max_age_s=max(1.0, 3.0 / cfg.keep_hz))

    def colour_stream(self, cfg: CameraDeviceConfig) -> D415Stream[Frame]:
        """The colour stream as the robot's ``camera`` device (``devices.camera``: width, height, fps)."""
        self._before_start("colour")
        self._colour = cfg
        self._caps["colour"] = RateCap(cfg.fps)
        return D415Stream(self, "colour", "camera", "camera frame", max_age_s=max(1.0, 3.0 / cfg.fps))

    def _before_start(self, stream: str) -> None:
        if self._users:
            raise RuntimeError(f"the D415's {stream} stream was asked for after its pipeline started")
        if stream in self._caps:
            raise RuntimeError(f"the D415's {stream} stream is already taken")

    def acquire(self) -> None:
        """A stream's device starts: the first one starts the reader."""
        with self._users_lock:
            self._users += 1
            if self._users == 1:
                self.start()

    def release(self) -> None:
        """A stream's device shuts down: the last one stops the reader and closes the camera."""
        with self._users_lock:
            self._users -= 1
            if self._users == 0:
                self.shutdown()

    def stream_info(self, kind: str) -> DeviceInfo:
        """What the camera says about itself, for the stream ``kind`` (``depth`` or ``camera``)."""
        info = self._info
        return DeviceInfo(kind=kind, driver="realsense", port=info.port, model=info.model, firmware=info.firmware,
                          serial_number=info.serial_number)

    # -- the reader -----------------------------------------------------------------------------------------
    def missing_hint(self, error: BaseException) -> str:
        return (f"{self.name}: {error} (is the D415 plugged in, on a USB 3 port? `rs-enumerate-devices` lists the "
                "cameras the SDK sees)")

    def _present(self) -> None:
        """Raise `OSError` at once when the camera is not connected: librealsense's ``pipeline.start`` waits about
        15 s for one to appear, during which the reader could neither report it nor stop."""
        rs = self._rs
        serials = [str(d.get_info(rs.camera_info.serial_number)) for d in rs.context().query_devices()]
        if not serials:
            raise OSError("no RealSense camera connected")
        if self.serial and self.serial not in serials:
            raise OSError(f"no RealSense camera with serial {self.serial} (connected: {', '.join(serials)})")

    def _open(self) -> None:
        rs = self._rs
        self._present()
        pipeline = rs.pipeline()
        config = rs.config()
        if self.serial:
            config.enable_device(self.serial)
        depth, colour = self._depth, self._colour
        if depth is not None:
            config.enable_stream(rs.stream.depth, depth.cfg.width, depth.cfg.height, rs.format.z16, depth.cfg.fps)
        if colour is not None:
            config.enable_stream(rs.stream.color, colour.width, colour.height, rs.format.rgb8,
                                 colour_stream_fps(colour.fps))
        try:
            profile = pipeline.start(config)
        except RuntimeError as exc:  # the SDK's "No device connected", "Couldn't resolve requests", ...
            raise OSError(str(exc)) from None
        self._pipeline = pipeline
        device = profile.get_device()
        if depth is not None:
            self._scale_m = float(device.first_depth_sensor().get_depth_scale())
            stream = profile.get_stream(rs.stream.depth).as_video_stream_profile()
            self._intrinsics = Intrinsics.of(stream.get_intrinsics())
        info = rs.camera_info
        self._info = DeviceInfo(kind="depth", driver="realsense", port=self.port,
                                model=device.get_info(info.name), firmware=device.get_info(info.firmware_version),
                                serial_number=device.get_info(info.serial_number))

    def _read(self) -> list[tuple[str, float, Any]]:
        pipeline = self._pipeline
        if pipeline is None:
            raise OSError("the D415 is not open")
        try:
            frames = pipeline.wait_for_frames(FRAME_TIMEOUT_MS)
        except RuntimeError as exc:  # "Frame didn't arrive within 1000": unplugged or stalled
            raise OSError(f"no frame within {FRAME_TIMEOUT_MS} ms ({exc})") from None
        t = self.stamp()
        out: list[tuple[str, float, Any]] = []
        depth, colour = self._depth, self._colour
        if depth is not None and self._intrinsics is not None:
            frame = frames.get_depth_frame()  # a frameset may lack a stream running at another rate
            if frame and self._caps["depth"].admit(t):
                raw = np.asanyarray(frame.get_data())
                out.append(("depth", t, depth_image(raw, self._scale_m, self._intrinsics, depth.mount, t,
                                                    range_max_m=depth.cfg.range_max_m)))
        if colour is not None:
            frame = frames.get_color_frame()
            if frame and self._caps["colour"].admit(t):
                out.append(("colour", t, colour_frame(np.asanyarray(frame.get_data()), colour.width, colour.height)))
        return out

    def _close(self) -> None:
        pipeline, self._pipeline = self._pipeline, None
        if pipeline is None:
            return
        try:
            pipeline.stop()
        except Exception:  # stopping a pipeline whose device is gone raises: it is closed either way
            log.debug("%s: stopping the pipeline failed", self.name, exc_info=True)


class D415Stream(Publishes[R]):
    """One of the D415's streams as a robot device (``depth`` or ``camera``): its frames, its health (the
    camera's when it is lost, else its own stream's freshness), and a share of the camera's reader."""

    rate_hz: float | None = ThreadedDevice.rate_hz

    def __init__(self, camera: D415, stream: str, name: str, what: str, *, max_age_s: float) -> None:
        self.name, self.max_age_s = name, max_age_s
        self._camera, self._what = camera, what
        self._stream = stream  # the tag of its readings: "depth" or "colour"
        self._out: Subscribers[R] = Subscribers(name)
        self._last_t: float | None = None
        self._started = False
        camera.subscribe(self._take)

    @property
    def camera(self) -> D415:
        """The reader this stream shares with the camera's other stream."""
        return self._camera

    def start(self) -> None:
        if not self._started:
            self._started = True
            self._camera.acquire()

    def shutdown(self) -> None:
        if self._started:
            self._started = False
            self._camera.release()

    def tick(self, now: float) -> None:
        self._camera.tick(now)  # hands every stream its frames (the other stream's tick then finds none)

    def health(self, now: float) -> ComponentHealth:
        if not self._camera.connected:
            return self._camera.health(now)
        return fresh(self._last_t, now, self.max_age_s, f"{self._what} from {self._camera.port}")

    def info(self) -> DeviceInfo:
        return self._camera.stream_info(self.name)

    def _take(self, reading: tuple[str, float, Any]) -> None:
        stream, t, frame = reading
        if stream == self._stream:
            self._last_t = t
            self._out.publish(frame)


__all__ = [
    "COLOUR_STREAM_FPS",
    "D415",
    "INSTALL_HINT",
    "D415Stream",
    "Intrinsics",
    "colour_frame",
    "colour_stream_fps",
    "depth_image",
    "require_realsense",
]
