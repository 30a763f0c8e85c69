"""A D415 behind the pyrealsense2 API: the SDK calls the ``realsense`` drivers make (pipeline, config, streams,
the device's depth scale and camera info, framesets) answered with a wall ``wall_mm`` millimetres ahead in the
depth stream and a test picture in the colour stream, so the real driver (`atemr.io.devices.realsense`) runs end
to end without the camera, unplugging included. As the real camera, it is opened by one pipeline at a time: a
second ``start`` while one runs fails ("Device or resource busy"). RealSense cameras speak USB through
librealsense, not bytes a pseudo-terminal can carry (as the RPLidar and WT901 emulators do): the SDK's Python
surface is where an emulator can stand in. Framesets come at the pace of the fastest stream asked for, as the
camera's do. Install it with ``sys.modules["pyrealsense2"] = FakeD415().module()``
before the driver is built."""

from __future__ import annotations

import time
import types
from typing import Any

import numpy as np

#: The colour stream's picture: the left half this red, the right half this blue (RGB).
LEFT_RGB = (200, 30, 30)
RIGHT_RGB = (20, 40, 220)


class _Intrinsics:
    fx, fy, ppx, ppy = 305.0, 305.0, 211.5, 119.5


class _Frame:
    def __init__(self, raw: np.ndarray | None) -> None:
        self._raw = raw

    def get_data(self) -> np.ndarray:
        assert self._raw is not None
        return self._raw

    def __bool__(self) -> bool:  # the SDK's empty frame (a stream missing from the frameset) is falsy
        return self._raw is not None


class _Frames:
    def __init__(self, depth: np.ndarray | None, colour: np.ndarray | None) -> None:
        self._depth, self._colour = _Frame(depth), _Frame(colour)

    def get_depth_frame(self) -> _Frame:
        return self._depth

    def get_color_frame(self) -> _Frame:
        return self._colour


def colour_picture(width: int, height: int) -> np.ndarray:
    """The colour stream's frame: `LEFT_RGB` on the left half, `RIGHT_RGB` on the right."""
    picture = np.empty((height, width, 3), dtype=np.uint8)
    picture[:, : width // 2] = LEFT_RGB
    picture[:, width // 2:] = RIGHT_RGB
    return picture


class FakeD415:
    """The emulated camera's state: what was asked of it, and whether the camera is plugged in."""

    def __init__(self, wall_mm: int = 1500) -> None:
        self.wall_mm = wall_mm
        self.plugged = True
        self.streams: list[tuple[Any, ...]] = []
        self.started = 0
        self.stopped = 0
        self.running = 0

    def module(self) -> types.ModuleType:
        """A stand-in for ``import pyrealsense2``."""
        fake = self
        rs = types.ModuleType("pyrealsense2")
        rs.stream = types.SimpleNamespace(depth="depth", color="color")  # type: ignore[attr-defined]
        rs.format = types.SimpleNamespace(z16="z16", rgb8="rgb8")  # type: ignore[attr-defined]
        rs.camera_info = types.SimpleNamespace(name="name", firmware_version="fw",  # type: ignore[attr-defined]
                                               serial_number="serial")

        class Config:
            def __init__(self) -> None:
                self.enabled: dict[str, tuple[Any, ...]] = {}

            def enable_device(self, serial: str) -> None:
                fake.streams.append(("device", serial))

            def enable_stream(self, *args: Any) -> None:
                fake.streams.append(args)
                self.enabled[args[0]] = args

        class Device:
            def first_depth_sensor(self) -> Any:
                return types.SimpleNamespace(get_depth_scale=lambda: 0.001)

            def get_info(self, what: str) -> str:
                return {"name": "Intel RealSense D415", "fw": "5.16.0.1", "serial": "822512060000"}[what]

        class Profile:
            def __init__(self, enabled: dict[str, tuple[Any, ...]]) -> None:
                self._enabled = enabled

            def get_device(self) -> Device:
                return Device()

            def get_stream(self, kind: str) -> Any:
                if kind not in self._enabled:
                    raise RuntimeError(f"the profile has no {kind} stream")
                return types.SimpleNamespace(as_video_stream_profile=lambda: types.SimpleNamespace(
                    get_intrinsics=_Intrinsics))

        class Pipeline:
            def __init__(self) -> None:
                self._enabled: dict[str, tuple[Any, ...]] | None = None

            def start(self, config: Config) -> Profile:
                if not fake.plugged:
                    raise RuntimeError("No device connected")
                if fake.running:
                    raise RuntimeError("xioctl(VIDIOC_S_FMT) failed, errno=16 Last Error: Device or resource busy")
                fake.running += 1
                fake.started += 1
                self._enabled = dict(config.enabled)
                return Profile(self._enabled)

            def wait_for_frames(self, timeout_ms: int) -> _Frames:
                if not fake.plugged or self._enabled is None:
                    raise RuntimeError(f"Frame didn't arrive within {timeout_ms}")
                time.sleep(1.0 / max(stream[-1] for stream in self._enabled.values()))  # the fastest stream's pace
                depth = colour = None
                if "depth" in self._enabled:
                    _, width, height = self._enabled["depth"][:3]
                    depth = np.full((height, width), fake.wall_mm, dtype=np.uint16)
                    depth[:, : width // 8] = 0  # the left edge: no data, as the D415's stereo shadow gives
                if "color" in self._enabled:
                    _, width, height = self._enabled["color"][:3]
                    colour = colour_picture(width, height)
                return _Frames(depth, colour)

            def stop(self) -> None:
                if self._enabled is not None:
                    self._enabled = None
                    fake.running -= 1
                fake.stopped += 1

        class Context:
            def query_devices(self) -> list[Device]:
                return [Device()] if fake.plugged else []

        rs.context = Context  # type: ignore[attr-defined]
        rs.config = Config  # type: ignore[attr-defined]
        rs.pipeline = Pipeline  # type: ignore[attr-defined]
        return rs
