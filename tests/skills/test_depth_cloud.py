"""Depth image → base-frame points (issue 24), on synthetic arrays: the frame conversion the real D415 driver's
images and the simulator's go through."""

import math

import numpy as np
import pytest

from atemr.msgs import CameraMount, DepthImage
from atemr.skills.depth_cloud import DepthProjector, depth_to_points, mount_rotation

W, H = 8, 6
FX = FY = 4.0
CX, CY = 3.5, 2.5


def image(depth: np.ndarray, mount: CameraMount) -> DepthImage:
    return DepthImage(0.0, depth.astype(np.float32), FX, FY, CX, CY, 0.3, 3.0, mount)


def test_the_optical_axis_is_the_base_x_axis_for_a_level_camera():
    r = mount_rotation(CameraMount())
    assert r @ [0, 0, 1] == pytest.approx([1, 0, 0])  # optical z (forward) → base x
    assert r @ [1, 0, 0] == pytest.approx([0, -1, 0])  # optical x (right) → base -y
    assert r @ [0, 1, 0] == pytest.approx([0, 0, -1])  # optical y (down) → base -z


def test_pitch_down_and_yaw_left():
    down = mount_rotation(CameraMount(pitch_rad=math.radians(30)))
    assert down @ [0, 0, 1] == pytest.approx([math.cos(math.radians(30)), 0, -math.sin(math.radians(30))])
    left = mount_rotation(CameraMount(yaw_rad=math.pi / 2))
    assert left @ [0, 0, 1] == pytest.approx([0, 1, 0], abs=1e-12)


def test_a_flat_wall_ahead_becomes_points_at_its_distance():
    mount = CameraMount(x_m=0.1, y_m=0.0, z_m=0.9)
    points = depth_to_points(image(np.full((H, W), 2.0), mount))
    assert points.shape == (W * H, 3)
    assert points[:, 0] == pytest.approx(np.full(W * H, 2.1))  # depth along the axis + the mount's x
    # the principal point's neighbours: right of it is to the robot's right (y < 0), below is lower (z < 0.9)
    grid = points.reshape(H, W, 3)
    assert grid[2, 7, 1] < 0 < grid[2, 0, 1]
    assert grid[5, 3, 2] < 0.9 < grid[0, 3, 2]
    assert grid[5, 3, 2] == pytest.approx(0.9 - (5 - CY) / FY * 2.0)


def test_a_tilted_camera_sees_the_floor_at_height_zero():
    pitch = math.radians(25)
    mount = CameraMount(z_m=1.0, pitch_rad=pitch)
    # the depth a level floor gives each pixel: z-depth = h / (sin(p) + cos(p) * (v - cy) / fy)
    v = np.arange(H, dtype=np.float64)[:, None] * np.ones((1, W))
    depth = 1.0 / (math.sin(pitch) + math.cos(pitch) * (v - CY) / FY)
    points = depth_to_points(image(depth, mount))
    assert len(points) == int(((depth >= 0.3) & (depth <= 3.0)).sum()) > W  # rows above the horizon see no floor
    assert points[:, 2] == pytest.approx(np.zeros(len(points)), abs=1e-5)


def test_no_data_and_out_of_range_pixels_are_dropped():
    depth = np.full((H, W), 1.5)
    depth[0, :] = 0.0
    depth[1, 0] = np.nan
    depth[2, 0] = 0.1  # under the minimum range
    depth[3, 0] = 9.0  # beyond the maximum
    points = depth_to_points(image(depth, CameraMount()))
    assert len(points) == W * H - W - 3


def test_the_projector_keeps_its_rays_between_frames_and_subsamples():
    projector = DepthProjector(stride=2)
    first = projector.points(image(np.full((H, W), 1.0), CameraMount(z_m=0.5)))
    assert len(first) == (W // 2) * (H // 2)
    second = projector.points(image(np.full((H, W), 2.0), CameraMount(z_m=0.5)))
    assert second[:, 0] == pytest.approx(np.full(len(second), 2.0))
    moved = projector.points(image(np.full((H, W), 2.0), CameraMount(x_m=1.0, z_m=0.5)))  # a new mount: new rays
    assert moved[:, 0] == pytest.approx(np.full(len(moved), 3.0))
    with pytest.raises(ValueError):
        DepthProjector(stride=0)
