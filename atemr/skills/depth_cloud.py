"""Depth image → point cloud in the base frame: the pinhole model backwards and the camera's mounting pose.

A depth camera reports, per pixel (u, v), the distance ``z`` along its optical axis. With the intrinsics
(focal lengths ``fx``, ``fy`` and principal point ``cx``, ``cy``, in pixels) the point in the optical frame
(x right, y down, z forward, as the RealSense SDK and ROS's ``*_optical_frame`` have it) is::

    x = (u - cx) / fx * z,   y = (v - cy) / fy * z,   z

and the mount turns it into the base frame (x forward, y left, z up from the floor, REP 103): first the
fixed axis swap of an optical frame, then the camera's tilt (pitch, positive looking down) and turn (yaw),
then its position. All of it is one 3x3 rotation and a translation, applied to every pixel at once.

The same rotation gives the simulator the direction of every pixel's ray (`pixel_rays`), so what the
simulated camera renders and what the skill reads back are one model.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from atemr.msgs import CameraMount, DepthImage

F32 = NDArray[np.float32]

#: From an optical frame (x right, y down, z forward) to an untilted base-aligned frame (x forward, y left, z up).
OPTICAL_TO_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def mount_rotation(mount: CameraMount) -> NDArray[np.float64]:
    """The rotation taking optical-frame vectors to base-frame vectors: yaw · pitch · optical axis swap."""
    cp, sp = math.cos(mount.pitch_rad), math.sin(mount.pitch_rad)
    cy, sy = math.cos(mount.yaw_rad), math.sin(mount.yaw_rad)
    pitch = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])  # +pitch: the optical axis tilts down
    yaw = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    rotation: NDArray[np.float64] = yaw @ pitch @ OPTICAL_TO_BODY
    return rotation


def pixel_rays(size: tuple[int, int], intrinsics: tuple[float, float, float, float], *, stride: int = 1) -> F32:
    """Optical-frame direction of every ``stride``-th pixel's ray of an image of ``size`` (width, height) with
    ``intrinsics`` (fx, fy, cx, cy), scaled so that z = 1 (row-major, (N, 3)): a ray times a pixel's depth is
    its 3-D point."""
    width, height = size
    fx, fy, cx, cy = intrinsics
    u = np.arange(0, width, stride, dtype=np.float32)
    v = np.arange(0, height, stride, dtype=np.float32)
    uu, vv = np.meshgrid((u - np.float32(cx)) / np.float32(fx), (v - np.float32(cy)) / np.float32(fy))
    rays = np.empty((uu.size, 3), dtype=np.float32)
    rays[:, 0] = uu.ravel()
    rays[:, 1] = vv.ravel()
    rays[:, 2] = 1.0
    return rays


class DepthProjector:
    """Turns depth images of one camera into base-frame points; the per-pixel rays are computed once per
    camera geometry (intrinsics, size, mount and ``stride``) and reused for every frame."""

    def __init__(self, stride: int = 1) -> None:
        if stride < 1:
            raise ValueError(f"stride must be at least 1, got {stride}")
        self.stride = stride
        self._key: tuple[object, ...] | None = None
        self._rays_base: F32 = np.zeros((0, 3), dtype=np.float32)
        self._origin: F32 = np.zeros(3, dtype=np.float32)

    def _prepare(self, image: DepthImage) -> None:
        key = (image.width, image.height, image.fx, image.fy, image.cx, image.cy, image.mount)
        if key == self._key:
            return
        rays = pixel_rays((image.width, image.height), (image.fx, image.fy, image.cx, image.cy), stride=self.stride)
        self._rays_base = (rays @ mount_rotation(image.mount).T.astype(np.float32)).astype(np.float32)
        m = image.mount
        self._origin = np.array([m.x_m, m.y_m, m.z_m], dtype=np.float32)
        self._key = key

    @property
    def origin(self) -> F32:
        """The camera's optical centre in the base frame (of the last image)."""
        return self._origin

    def rays(self, image: DepthImage) -> F32:
        """Each (strided) pixel's ray in the base frame, row-major: a point is its ray times its depth, plus
        `origin`."""
        self._prepare(image)
        return self._rays_base

    def strided(self, image: DepthImage) -> F32:
        """The depths of the pixels `rays` describes, row-major."""
        out: F32 = image.depth_m[::self.stride, ::self.stride].ravel()
        return out

    def points(self, image: DepthImage) -> F32:
        """Base-frame points (N, 3) of the valid pixels (depth within the image's range; 0 and NaN dropped)."""
        self._prepare(image)
        depth = self.strided(image)
        valid = (depth >= image.range_min_m) & (depth <= image.range_max_m)  # NaN compares False
        if not valid.all():
            depth = depth[valid]
            rays = self._rays_base[valid]
        else:
            rays = self._rays_base
        points: F32 = rays * depth[:, None]
        points += self._origin
        return points


def depth_to_points(image: DepthImage, *, stride: int = 1) -> F32:
    """Base-frame points of one depth image (see `DepthProjector` for many images of one camera)."""
    return DepthProjector(stride).points(image)


__all__ = ["DepthProjector", "depth_to_points", "mount_rotation", "pixel_rays"]
