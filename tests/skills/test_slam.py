"""Occupancy-grid SLAM: the inverse sensor model on a hand-made room, and mapping the studio from a seeded drive."""

from __future__ import annotations

import importlib.util
import itertools
import math
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from atemr.domain.maps import OccupancyMap
from atemr.errors import ConfigError
from atemr.io.sim.lidar import LidarParams
from atemr.io.sim.maps import load_map, save_map
from atemr.io.sim.scene import Scene
from atemr.io.sim.world import load_world
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.localization.geometry import as_array, as_pose, compose, relative
from atemr.skills.slam import OccupancyGridSlam, SlamParams, map_agreement

ROOT = Path(__file__).resolve().parents[2]


def simdrive() -> ModuleType:
    """The drive-and-record helper shared with the localization tests (importlib mode: load it by path)."""
    name = "atemr_test_simdrive"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, Path(__file__).parent / "localization" / "simdrive.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def box_room_scan(pose_xy: tuple[float, float] = (0.0, 0.0), half_m: float = 2.025, beams: int = 360) -> LaserScan:
    """A noise-free scan from inside a square room of side 2·half_m centred on the origin."""
    ang = -math.pi + 2 * math.pi * np.arange(beams) / beams
    c, s = np.cos(ang), np.sin(ang)
    x0, y0 = pose_xy
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (half_m - x0) / c, np.where(c < 0, (-half_m - x0) / c, np.inf))
        ty = np.where(s > 0, (half_m - y0) / s, np.where(s < 0, (-half_m - y0) / s, np.inf))
    ranges = np.minimum(tx, ty)
    ranges[::50] = np.nan  # invalid returns are ignored
    return LaserScan(0.0, ranges, -math.pi, 2 * math.pi / beams, 0.15, 8.0)


def test_inverse_sensor_model_on_a_square_room() -> None:
    slam = OccupancyGridSlam(SlamParams(size_m=6.0))
    for k in range(5):  # one look is not enough to call a cell free (p 0.4 per look, free below 0.196)
        assert slam.update(Pose2D(0.15 * k, 0.0, 0.0), box_room_scan((0.15 * k, 0.0)))
    assert slam.current_pose.distance_to(Pose2D(0.6, 0.0, 0.0)) < 0.02
    m = slam.to_map("room")
    assert m.value_at(0.0, 0.0) == 0 and m.value_at(1.0, -1.2) == 0  # inside: free
    assert m.value_at(2.02, 0.3) == 100 and m.value_at(-0.5, -2.02) == 100  # walls: occupied
    assert m.value_at(2.6, 0.0) == -1  # behind the wall: unknown
    assert m.width <= 2 * (40 + 5) + 2  # cropped to the known part


def test_bad_input_is_refused() -> None:
    slam = OccupancyGridSlam(SlamParams(size_m=6.0))
    assert not slam.update(Pose2D(float("nan"), 0.0, 0.0), box_room_scan())
    assert slam.refused == 1
    empty = LaserScan(0.0, np.full(360, np.inf), -math.pi, 2 * math.pi / 360, 0.15, 8.0)
    assert slam.update(Pose2D(), empty)
    assert not slam.to_map().occupied.any()
    with pytest.raises(ConfigError):
        SlamParams(p_occ=0.4)
    with pytest.raises(ConfigError):
        OccupancyGridSlam(start=Pose2D(math.inf, 0.0, 0.0))


def lidar_truth() -> OccupancyMap:
    """The studio's map as a lidar can draw it: its occupied cells where something crosses the lidar's plane
    (the dining table's legs, not the footprint of its top). The shipped map is drawn so already
    (`atemr.worlds.make_studio`); taken from the scene, the truth stays the lidar's whatever the map says."""
    world = load_world("studio")
    blocked = Scene(world).blocked_at(LidarParams().height_m)
    data = world.map.data.copy()
    data[world.map.occupied & ~blocked] = 0
    return OccupancyMap(data, world.map.resolution_m, world.map.origin, name="studio at the lidar's plane")


@pytest.fixture(scope="module")
def living_room_drive() -> object:
    """Two laps of the living room: scans from the simulator, noisy odometry with wheel slip, the true poses."""
    return simdrive().drive(seed=3, laps=2, max_s=90.0)


def test_mapping_the_studio_matches_the_ground_truth_map(tmp_path: Path, living_room_drive: object) -> None:
    """Two laps of the living room, mapped and saved: ≥ 90 % of the saved map's occupied cells lie within one
    cell of an occupied cell of the world's map (the rest are people), and most surfaces seen are mapped."""
    rec: Any = living_room_drive
    slam = OccupancyGridSlam(start=rec.truth[0])  # the map frame is the start pose, placed where the world has it
    errors = [slam.current_pose.distance_to(rec.truth[i]) for i, scan in enumerate(rec.scans)
              if slam.update(rec.odom[i], scan)]
    assert slam.updates > 150 and slam.rematched > 0
    assert float(np.sqrt(np.mean(np.square(errors)))) < 0.05  # the map's own pose stays on the truth
    path = save_map(slam.to_map("studio_slam"), tmp_path / "studio_slam.yaml")
    saved = load_map(path)
    truth = lidar_truth()
    precision, recall = map_agreement(saved, truth)
    assert saved.occupied.sum() > 500
    assert precision >= 0.90, precision
    assert recall >= 0.80, recall
    odometry_only = OccupancyGridSlam(SlamParams(match_scans=False), start=rec.truth[0])
    for i, scan in enumerate(rec.scans):
        odometry_only.update(rec.odom[i], scan)
    assert map_agreement(odometry_only.to_map(), truth)[0] < precision  # scan matching is what makes it good


def test_a_map_started_while_localized_keeps_the_active_maps_frame(living_room_drive: object) -> None:
    """The start pose is a localized estimate, off by 2 cm and a third of a degree (a good AMCL estimate). On its
    own that heading tilts the whole axis-aligned grid (on the whole flat the far walls move by centimetres
    and staircase: tests/fsm/test_mission_cli.py). Registered to the active map (the anchor), the new map
    shares its frame."""
    rec: Any = living_room_drive
    truth = load_map(ROOT / "atemr" / "worlds" / "studio" / "studio.yaml")
    t0 = rec.truth[0]
    estimate = Pose2D(t0.x_m + 0.02, t0.y_m - 0.01, t0.yaw_rad + 0.006)

    def build(anchor: object) -> OccupancyGridSlam:
        slam = OccupancyGridSlam(start=estimate, anchor=anchor)  # type: ignore[arg-type]
        for i, scan in enumerate(rec.scans):
            slam.update(rec.odom[i], scan)
        return slam

    anchored, tilted = build(truth), build(None)
    assert anchored.anchored and not tilted.anchored
    first = anchored.trajectory[0]
    assert abs(math.remainder(first.yaw_rad - t0.yaw_rad, math.tau)) < 0.002, first
    assert first.distance_to(t0) < 0.04, first  # within a cell (the map's own cells are where its walls are)
    assert tilted.trajectory[0].distance_to(estimate) < 1e-9  # no anchor: the frame is the estimate as given
    precision = map_agreement(anchored.to_map(), truth)[0]
    assert precision >= 0.90, precision


def test_an_anchor_the_scan_does_not_fit_is_not_used() -> None:
    """A first scan that does not fit the anchor (the robot is not where the estimate says, or the flat changed
    beyond recognition) leaves the start pose as given, rather than snapping the new map onto the wrong walls."""
    corridor = np.zeros((40, 200), dtype=np.int8)  # a 2 m × 10 m corridor: nothing like the square room
    corridor[[0, -1], :] = 100
    anchor = OccupancyMap(corridor, 0.05, Pose2D(-5.0, -1.0, 0.0), name="corridor")
    start = Pose2D(0.0, 0.0, 0.0)
    slam = OccupancyGridSlam(SlamParams(size_m=6.0), start=start, anchor=anchor)
    assert slam.update(Pose2D(), box_room_scan())
    assert not slam.anchored and slam.trajectory[0] == start
    with pytest.raises(ConfigError, match="anchor_min_agreement"):
        SlamParams(anchor_min_agreement=1.5)


def drifted(odometry: list[Pose2D], yaw_per_scan: float) -> list[Pose2D]:
    """The odometry re-integrated with every increment turned ``yaw_per_scan`` further (a gyro bias): its heading
    drifts, and so does every position after it."""
    out = [odometry[0]]
    for before, after in itertools.pairwise(odometry):
        step = relative(as_array(before), as_array(after))
        step[2] += yaw_per_scan
        out.append(as_pose(compose(as_array(out[-1]), step)))
    return out


def test_matching_against_the_grid_closes_the_loop_on_drifting_odometry(living_room_drive: object) -> None:
    """Odometry with a heading bias (0.6 rad, 34°, by the end of two laps): each scan is matched against the
    whole grid mapped so far, so coming back into view of walls mapped on the first lap pulls the pose back onto
    them; the pose error stays small and the map stays good. Odometry alone ends far off."""
    rec: Any = living_room_drive
    truth = load_map(ROOT / "atemr" / "worlds" / "studio" / "studio.yaml")
    odometry = drifted(rec.odom, 0.6 / len(rec.scans))

    def build(params: SlamParams) -> tuple[OccupancyGridSlam, float]:
        slam = OccupancyGridSlam(params, start=rec.truth[0])
        worst = 0.0
        for i, scan in enumerate(rec.scans):
            if slam.update(odometry[i], scan):
                worst = max(worst, slam.current_pose.distance_to(rec.truth[i]))
        return slam, worst

    matched, worst = build(SlamParams())
    assert worst < 0.08, worst
    assert map_agreement(matched.to_map(), truth)[0] >= 0.90
    _, worst_odometry = build(SlamParams(match_scans=False))
    assert worst_odometry > 0.5, worst_odometry


def test_a_scan_icp_refuses_is_placed_by_the_correlative_rematch(living_room_drive: object,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """When ICP refuses a scan (no convergence, too few inliers), the prediction is not simply kept: the scan is
    matched over a window against the grid's likelihood field, which undoes a slip of 0.2 m and 0.1 rad in one
    step. Without that rematch the slip stays in the pose and in the map."""
    import atemr.skills.slam as slam_module
    from atemr.skills.localization.icp import IcpResult
    from atemr.skills.localization.scan_to_map import MapMatch

    rec: Any = living_room_drive
    slip_at = len(rec.scans) // 3
    slip = Pose2D(0.2, -0.05, 0.1)
    real_icp = slam_module.icp
    state = {"refuse": False}

    def icp_refusing(*args: Any, **kwargs: Any) -> IcpResult:
        result = real_icp(*args, **kwargs)
        if state["refuse"]:
            state["refuse"] = False
            return IcpResult(result.pose, result.rmse_m, 0.0, result.iterations, False, result.covariance)
        return result

    monkeypatch.setattr(slam_module, "icp", icp_refusing)

    def error_after_slip() -> float:
        slam = OccupancyGridSlam(start=rec.truth[0])
        for i, scan in enumerate(rec.scans):
            odom = rec.odom[i]
            if i >= slip_at:  # the wheels slipped once: every later odometry pose carries it
                odom = Pose2D(*compose(as_array(odom), as_array(slip)))
            state["refuse"] = i == slip_at
            if slam.update(odom, scan) and i >= slip_at:
                return slam.current_pose.distance_to(rec.truth[i])
        raise AssertionError("no update after the slip")

    assert error_after_slip() < 0.06
    monkeypatch.setattr(slam_module.ScanToMapMatcher, "match",
                        lambda self, points, guess, **kw: MapMatch(guess, 0.0, -math.inf, False))
    assert error_after_slip() > 0.15
