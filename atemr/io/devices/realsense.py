"""The real depth camera: an Intel RealSense D415 through pyrealsense2 (driver ``realsense``).

KAY carries a D415 on its mast (thesis table 3.3). This driver reads its depth stream (z16, 424 x 240 by
default) on a thread of its own, like every real sensor (`atemr.io.devices.base.ThreadedDevice`): it opens the
pipeline, waits for frames, stamps each kept one with the robot's clock and hands it over as a `DepthImage`,
exactly what the simulated D415 publishes (`atemr.io.sim.depth`), so the depth obstacle layer cannot tell them
apart. When the camera is unplugged or stops sending, the pipeline is stopped, health says why, and it is
opened again every `REOPEN_S` until the camera is back.

The conversion from the SDK's frame is a pure function (`depth_image`): raw 16-bit units times the depth
scale the device reports (1 mm on the D415) in metres, 0 kept as no data, readings beyond ``range_max_m``
dropped (the D415's error grows with the square of the distance), and the stream's own intrinsics (the
SDK's ``ppx``/``ppy`` are the principal point).

pyrealsense2 is optional (the ``realsense`` extra): this module imports without it, and building the driver
without it is a `ConfigError` that names the extra.
"""

from __future__ import annotations

import importlib
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from atemr.errors import ConfigError
from atemr.io.devices.base import DeviceInfo, ThreadedDevice
from atemr.io.devices.camera import RateCap
from atemr.io.devices.config import DepthDeviceConfig
from atemr.msgs import CameraMount, DepthImage

log = logging.getLogger(__name__)

#: What to install when pyrealsense2 is missing.
INSTALL_HINT = "the realsense driver needs pyrealsense2: pip install 'atemr[realsense]'"
#: How long a read waits for the next frame before the camera counts as lost, in milliseconds.
FRAME_TIMEOUT_MS = 1000
#: Frames waiting for the scheduler at most (a 424 x 240 float frame is 400 kB).
QUEUE_FRAMES = 4
#: The D415's minimum depth at 424 x 240 (its stereo search range), metres.
D415_RANGE_MIN_M = 0.3


def require_realsense() -> Any:
    """The pyrealsense2 module, or a `ConfigError` naming the extra to install (typed ``Any``: the code
    type-checks with or without it)."""
    try:
        return importlib.import_module("pyrealsense2")
    except ImportError:
        raise ConfigError(INSTALL_HINT, path="devices.depth.driver") from None


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


class RealSenseDepth(ThreadedDevice[DepthImage]):
    """The D415's depth stream read by a thread of its own (see the module docstring)."""

    def __init__(self, *, now: Callable[[], float], mount: CameraMount, serial: str = "", width: int = 424,
                 height: int = 240, fps: int = 15, keep_hz: float = 10.0, range_max_m: float = 3.0,
                 name: str = "depth") -> None:
        self._rs = require_realsense()
        super().__init__(name, now=now, max_age_s=max(1.0, 3.0 / keep_hz), port=f"RealSense {serial or '(first)'}",
                         queue_size=QUEUE_FRAMES)
        self.mount, self.serial = mount, serial
        self.width, self.height, self.fps, self.range_max_m = width, height, fps, range_max_m
        self._cap = RateCap(keep_hz)
        self._pipeline: Any = None
        self._scale_m = 0.001
        self._intrinsics: Intrinsics | None = None
        self._info: DeviceInfo = DeviceInfo(kind="depth", driver="realsense")

    @classmethod
    def from_config(cls, cfg: DepthDeviceConfig, *, now: Callable[[], float], mount: CameraMount) -> RealSenseDepth:
        """The camera ``devices.depth`` describes, mounted at ``mount`` (its ``pose``); a `ConfigError` naming the
        extra without pyrealsense2."""
        return cls(now=now, mount=mount, serial=cfg.serial, width=cfg.width,
                   height=cfg.height, fps=cfg.fps, keep_hz=cfg.keep_hz, range_max_m=cfg.range_max_m)

    def info(self) -> DeviceInfo:
        return self._info

    def missing_hint(self, error: BaseException) -> str:
        return (f"{self.name}: {error} (is the D415 plugged in, on a USB 3 port? `rs-enumerate-devices` lists the "
                "cameras the SDK sees)")

    def _open(self) -> None:
        rs = self._rs
        pipeline = rs.pipeline()
        config = rs.config()
        if self.serial:
            config.enable_device(self.serial)
        config.enable_stream(rs.stream.depth, self.width, self.height, rs.format.z16, self.fps)
        try:
            profile = pipeline.start(config)
        except RuntimeError as exc:  # the SDK's "No device connected", "Couldn't resolve requests", ...
            raise OSError(str(exc)) from None
        self._pipeline = pipeline
        device = profile.get_device()
        self._scale_m = float(device.first_depth_sensor().get_depth_scale())
        stream = profile.get_stream(rs.stream.depth).as_video_stream_profile()
        self._intrinsics = Intrinsics.of(stream.get_intrinsics())
        info = rs.camera_info
        self._info = DeviceInfo(kind="depth", driver="realsense", port=self.port,
                                model=device.get_info(info.name), firmware=device.get_info(info.firmware_version),
                                serial_number=device.get_info(info.serial_number))

    def _read(self) -> list[DepthImage]:
        pipeline, intrinsics = self._pipeline, self._intrinsics
        if pipeline is None or intrinsics is None:
            raise OSError("the depth camera is not open")
        try:
            frames = pipeline.wait_for_frames(FRAME_TIMEOUT_MS)
        except RuntimeError as exc:  # "Frame didn't arrive within 1000": unplugged or stalled
            raise OSError(f"no depth frame within {FRAME_TIMEOUT_MS} ms ({exc})") from None
        t = self.stamp()
        if not self._cap.admit(t):
            return []
        frame = frames.get_depth_frame()
        if not frame:
            return []
        raw = np.asanyarray(frame.get_data())
        return [depth_image(raw, self._scale_m, intrinsics, self.mount, t, range_max_m=self.range_max_m)]

    def _close(self) -> None:
        pipeline, self._pipeline = self._pipeline, None
        if pipeline is None:
            return
        try:
            pipeline.stop()
        except Exception:  # stopping a pipeline whose device is gone raises: it is closed either way
            log.debug("%s: stopping the pipeline failed", self.name, exc_info=True)


__all__ = ["INSTALL_HINT", "Intrinsics", "RealSenseDepth", "depth_image", "require_realsense"]
