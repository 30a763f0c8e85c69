"""A D415 behind the pyrealsense2 API: the SDK calls the ``realsense`` driver makes (pipeline, config, streams,
the device's depth scale and camera info, frames) answered with a wall ``wall_mm`` millimetres ahead, so the
real driver (`atemr.io.devices.realsense`) runs end to end without the camera, unplugging included. RealSense
cameras speak USB through librealsense, not bytes a pseudo-terminal can carry (as the RPLidar and WT901
emulators do): the SDK's Python surface is where an emulator can stand in. Install it with
``sys.modules["pyrealsense2"] = FakeD415().module()`` before the driver is built."""

from __future__ import annotations

import types
from typing import Any

import numpy as np


class _Intrinsics:
    fx, fy, ppx, ppy = 305.0, 305.0, 211.5, 119.5


class _Frame:
    def __init__(self, raw: np.ndarray) -> None:
        self._raw = raw

    def get_data(self) -> np.ndarray:
        return self._raw

    def __bool__(self) -> bool:
        return True


class _Frames:
    def __init__(self, raw: np.ndarray) -> None:
        self._depth = _Frame(raw)

    def get_depth_frame(self) -> _Frame:
        return self._depth


class FakeD415:
    """The emulated camera's state: what was asked of it, and whether the camera is plugged in."""

    def __init__(self, wall_mm: int = 1500) -> None:
        self.wall_mm = wall_mm
        self.plugged = True
        self.streams: list[tuple[Any, ...]] = []
        self.stopped = 0

    def module(self) -> types.ModuleType:
        """A stand-in for ``import pyrealsense2``."""
        fake = self
        rs = types.ModuleType("pyrealsense2")
        rs.stream = types.SimpleNamespace(depth="depth")  # type: ignore[attr-defined]
        rs.format = types.SimpleNamespace(z16="z16")  # type: ignore[attr-defined]
        rs.camera_info = types.SimpleNamespace(name="name", firmware_version="fw",  # type: ignore[attr-defined]
                                               serial_number="serial")

        class Config:
            def enable_device(self, serial: str) -> None:
                fake.streams.append(("device", serial))

            def enable_stream(self, *args: Any) -> None:
                fake.streams.append(args)

        class Device:
            def first_depth_sensor(self) -> Any:
                return types.SimpleNamespace(get_depth_scale=lambda: 0.001)

            def get_info(self, what: str) -> str:
                return {"name": "Intel RealSense D415", "fw": "5.16.0.1", "serial": "822512060000"}[what]

        class Profile:
            def get_device(self) -> Device:
                return Device()

            def get_stream(self, _kind: str) -> Any:
                return types.SimpleNamespace(as_video_stream_profile=lambda: types.SimpleNamespace(
                    get_intrinsics=_Intrinsics))

        class Pipeline:
            def start(self, config: Config) -> Profile:
                if not fake.plugged:
                    raise RuntimeError("No device connected")
                return Profile()

            def wait_for_frames(self, timeout_ms: int) -> _Frames:
                if not fake.plugged:
                    raise RuntimeError(f"Frame didn't arrive within {timeout_ms}")
                width, height = fake.streams[-1][1], fake.streams[-1][2]
                raw = np.full((height, width), fake.wall_mm, dtype=np.uint16)
                raw[:, : width // 8] = 0  # the left edge: no data, as the D415's stereo shadow gives
                return _Frames(raw)

            def stop(self) -> None:
                fake.stopped += 1

        rs.config = Config  # type: ignore[attr-defined]
        rs.pipeline = Pipeline  # type: ignore[attr-defined]
        return rs
