"""The helpers a gateway uses to build the dashboard's snapshot and map image."""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from PIL import Image

from atemr.errors import ConfigError
from atemr.msgs import LaserScan, Pose2D
from atemr.ui.snapshot import (
    FREE_GREY,
    OCCUPIED_GREY,
    UNKNOWN_GREY,
    points_json,
    pose_json,
    render_map,
    scan_points,
    status_levels,
    system_json,
)


def test_pose_json():
    assert pose_json(Pose2D(1.23456, -2.0, 0.5)) == {"x_m": 1.2346, "y_m": -2.0, "yaw_rad": 0.5}
    assert pose_json(None) is None
    assert pose_json(Pose2D(math.nan, 0.0, 0.0)) is None


def test_points_json_drops_non_finite_and_decimates():
    pts = np.array([[0.0, 0.0], [np.nan, 1.0], [1.0, np.inf], [2.00049, 3.0]])
    assert points_json(pts) == [[0.0, 0.0], [2.0, 3.0]]
    many = np.column_stack((np.arange(5000.0), np.zeros(5000)))
    out = points_json(many, max_points=100)
    assert len(out) == 100 and out[0] == [0.0, 0.0] and out[-1] == [4999.0, 0.0]
    assert points_json(None) == [] and points_json([]) == []
    with pytest.raises(ConfigError, match=r"\(N, 2\)"):
        points_json(np.zeros((3, 3)))


ORIGIN = Pose2D()


def scan(ranges, sensor=ORIGIN):
    return LaserScan(0.0, np.asarray(ranges, dtype=np.float64), 0.0, math.pi / 2, 0.15, 8.0, sensor)


def test_scan_points_drop_invalid_returns_and_transform_to_the_map():
    s = scan([1.0, np.nan, 0.0, -np.inf, 9.0, 0.1, np.inf, 2.0])  # beams at 0, 90, 180, 270, 0, ...
    pts = scan_points(s, Pose2D(10.0, 5.0, math.pi / 2))
    # beam 0 (1 m ahead) and beam 7 (2 m at 270° = right of the robot); robot faces +y
    np.testing.assert_allclose(pts, [[10.0, 6.0], [12.0, 5.0]], atol=1e-12)


def test_scan_points_use_the_sensor_pose():
    pts = scan_points(scan([1.0], Pose2D(0.2, 0.0, math.pi)), Pose2D())
    np.testing.assert_allclose(pts, [[-0.8, 0.0]], atol=1e-12)


@given(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True)), min_size=0, max_size=50))
def test_scan_points_never_emit_invalid_points(ranges):
    pts = scan_points(scan(ranges), Pose2D(1.0, 2.0, 0.3))
    assert pts.shape[1] == 2 and np.isfinite(pts).all()
    assert (np.hypot(pts[:, 0] - 1.0, pts[:, 1] - 2.0) <= 8.0 + 1e-9).all()


def test_status_levels():
    from atemr.domain.status import AgentBits, HardwareBits, StateCode
    from atemr.io.can.protocol import PrimaryStatus

    status = PrimaryStatus(AgentBits.HEARTBEAT | AgentBits.AUTO, HardwareBits.LIDAR, StateCode.IDLE)
    level1, level2 = status_levels(status)
    assert level1 == {"heartbeat": True, "hardware": False, "auto": True, "connectivity": False,
                      "localization": False}
    assert level2["lidar"] is True and level2["left_motor"] is False and len(level2) == 8


def test_system_json():
    from atemr.io.system_monitor import SystemSample

    assert system_json(SystemSample(3.0, 12.345, 50.0, 70.0)) == {
        "t": 3.0, "cpu_percent": 12.35, "memory_percent": 50.0, "disk_percent": 70.0}
    assert system_json(None) is None


@dataclass
class Grid:
    data: np.ndarray
    resolution_m: float = 0.05
    origin: Pose2D = field(default_factory=lambda: Pose2D(-1.0, -2.0, 0.0))


def test_render_map_flips_rows_and_maps_values_to_grey():
    data = np.array([[0, 100, -1], [50, 0, 0]], dtype=np.int8)  # row 0 = bottom (ROS)
    image = render_map(Grid(data), version=3)
    assert (image.width_px, image.height_px, image.version) == (3, 2, 3)
    assert image.origin == Pose2D(-1.0, -2.0, 0.0) and image.resolution_m == 0.05
    pixels = np.asarray(Image.open(io.BytesIO(image.png)))
    assert pixels.tolist() == [[127, FREE_GREY, FREE_GREY], [FREE_GREY, OCCUPIED_GREY, UNKNOWN_GREY]]


def test_render_map_refuses_empty_grids():
    with pytest.raises(ConfigError, match="non-empty 2-D"):
        render_map(Grid(np.zeros((0, 4), dtype=np.int8)), 1)
