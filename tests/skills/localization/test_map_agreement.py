"""The honest agreement of a scan with the map: beams that end on the map, beams through walls, beams in free
space; the walk along each beam done two ways that agree."""

from __future__ import annotations

import math
from types import ModuleType

import numpy as np
import pytest

import atemr.skills.localization.likelihood_field as likelihood_field
from atemr.errors import ConfigError
from atemr.io.sim.lidar import Lidar, LidarParams
from atemr.io.sim.maps import OccupancyMap
from atemr.io.sim.scene import Scene
from atemr.io.sim.world import load_world
from atemr.msgs import Pose2D
from atemr.skills.localization.global_search import GlobalSearchParams
from atemr.skills.localization.likelihood_field import LikelihoodField
from atemr.skills.localization.map_agreement import HIT, THROUGH, UNEXPLAINED, AgreementParams, MapAgreement
from atemr.skills.localization.scan import scan_points, sensor_origin


def two_rooms() -> OccupancyMap:
    """4 m x 2 m at 0.1 m, a wall along x = 2 (cells 20-21) splitting it into two rooms, walls all round."""
    data = np.zeros((20, 40), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[:, 20:22] = 100
    return OccupancyMap(data, 0.1, Pose2D(0.0, 0.0, 0.0))


def test_each_beam_is_on_the_map_through_a_wall_or_unexplained() -> None:
    agreement = MapAgreement(LikelihoodField(two_rooms()))
    pose = np.array([[1.0, 1.0, 0.0]])  # the west room, facing east
    points = np.array([
        [0.95, 0.0],   # ends on the dividing wall (x 2.0..2.2): on the map
        [2.6, 0.0],    # ends on the east room's far wall: right distance to *a* wall, but through the divider
        [0.5, 0.0],    # ends in the middle of the room: something the map does not know
        [0.0, 0.85],   # the north wall, straight up
    ])
    kinds = agreement.classify(pose, points)
    assert kinds.tolist() == [[HIT, THROUGH, UNEXPLAINED, HIT]]
    counts = agreement.measure(pose, points)
    assert counts.agreement[0] == 0.5 and counts.structure_agreement[0] == pytest.approx(2 / 3)
    assert counts.reach[0] == 0.75 and counts.at(0).beams.tolist() == [4]
    # seen from the sensor 0.7 m ahead, the first point is 0.25 m short of the divider: unexplained
    assert agreement.classify(pose, points[:1], (0.7, 0.0)).tolist() == [[HIT]]
    assert agreement.classify(np.array([[0.3, 1.0, 0.0]]), points[:1], (0.0, 0.0)).tolist() == [[UNEXPLAINED]]


def test_a_wrong_room_no_longer_scores_as_the_right_one() -> None:
    """Issue 21: at a pose in another room, most end points of a scan still land near *some* wall (the old
    measure said "95 % on the map"); beam by beam, they cross walls to get there."""
    world = load_world("studio")
    scene = Scene(world)
    lidar = Lidar(LidarParams(noise_std_m=0.0, dropout_prob=0.0), np.random.default_rng(0))
    truth = Pose2D(5.23, 4.58, -2.6)  # where the robot stood in the issue
    scan = lidar.scan(0.0, truth, scene, np.zeros((0, 2)), np.zeros(0))
    points, sensor = scan_points(scan), sensor_origin(scan)
    field = LikelihoodField(world.map)
    agreement = MapAgreement(field, AgreementParams(max_beams=360))
    # the pose the old measure likes best anywhere the robot could stand, at least 1 m from the truth
    xs, ys, yaws = np.meshgrid(np.arange(0.2, 9.0, 0.15), np.arange(0.2, 7.0, 0.15), np.arange(-math.pi, math.pi, 0.1))
    poses = np.column_stack([xs.ravel(), ys.ravel(), yaws.ravel()])
    poses = poses[(field.distance(poses[:, 0], poses[:, 1]) >= 0.25)
                  & (np.hypot(poses[:, 0] - truth.x_m, poses[:, 1] - truth.y_m) > 1.0)]
    old = field.agreement(poses, points[::6])
    wrong = poses[int(np.argmax(old))]
    honest = agreement.measure(np.vstack([[truth.x_m, truth.y_m, truth.yaw_rad], wrong]), points, sensor)
    limit = GlobalSearchParams().min_agreement
    # the old measure found most of the scan "on the map" in another room, well over the localization limit
    # (0.78 since the dining table stands on legs: its top no longer answers the lidar)
    assert old.max() >= limit + 0.05
    assert honest.agreement[0] > 0.9 and honest.agreement[1] < limit
    assert honest.through[1] > 0.3 * honest.beams[1]


def test_walking_and_sampling_the_beams_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    world = load_world("studio")
    field = LikelihoodField(world.map)
    rng = np.random.default_rng(1)
    poses = np.column_stack([rng.uniform(0, 9, 20), rng.uniform(0, 7, 20), rng.uniform(-3, 3, 20)])
    angles = np.linspace(-math.pi, math.pi, 90, endpoint=False)
    ranges = rng.uniform(0.2, 8.0, angles.size)
    points = np.column_stack([ranges * np.cos(angles), ranges * np.sin(angles)])
    monkeypatch.setattr(likelihood_field, "DENSE_LOOKUPS", 10**12)
    sampled = field.crossings(poses, (0.1, 0.0), points, 0.2)
    monkeypatch.setattr(likelihood_field, "DENSE_LOOKUPS", 0)
    traced = field.crossings(poses, (0.1, 0.0), points, 0.2)
    assert sampled.shape == traced.shape == (20, 90) and 0.2 < sampled.mean() < 0.9
    assert np.mean(sampled != traced) < 0.01  # a corner clipped between two samples, at most


@pytest.mark.parametrize("walk", ["sampled", "traced"])
def test_the_compiled_walks_answer_as_the_numpy_ones_did(walk: str, monkeypatch: pytest.MonkeyPatch,
                                                         numpy_baselines: ModuleType) -> None:
    """The same booleans as `benchmarks/numpy_baselines.py`'s numpy `crossings`, which keeps every seeded run (its
    map agreement, global search and lost checks) what it was, on poses on and off the map, NaN and absurd."""
    world = load_world("studio")
    ours, before = LikelihoodField(world.map), numpy_baselines.NumpyLikelihoodField(world.map)
    lookups = 10**12 if walk == "sampled" else 0
    monkeypatch.setattr(likelihood_field, "DENSE_LOOKUPS", lookups)
    monkeypatch.setattr(numpy_baselines, "DENSE_LOOKUPS", lookups)
    rng = np.random.default_rng(7)
    for n, m in ((1, 90), (7, 360), (40, 30), (3, 1)):
        poses = np.column_stack([rng.uniform(-2, 11, n), rng.uniform(-4, 10, n), rng.uniform(-4, 4, n)])
        poses[0] = (1e12, math.nan, 0.5) if m == 30 else poses[0]
        points = rng.uniform(-9, 9, (m, 2))
        for start, stop in (((0.1, 0.0), 0.2), ((0.0, 0.0), 0.0)):
            got = ours.crossings(poses, start, points, stop)
            np.testing.assert_array_equal(got, before.crossings(poses, start, points, stop))
            assert 0.0 < got.mean() < 1.0  # both kinds of segment, or the comparison proves little


def test_an_empty_scan_and_bad_parameters() -> None:
    agreement = MapAgreement(LikelihoodField(two_rooms()))
    counts = agreement.measure(np.zeros((2, 3)), np.zeros((0, 2)))
    assert counts.agreement.tolist() == [0.0, 0.0] and counts.structure_agreement.tolist() == [0.0, 0.0]
    with pytest.raises(ConfigError, match="hit_tolerance_m"):
        AgreementParams(hit_tolerance_m=0.0)
    with pytest.raises(ConfigError, match="agreement_beams"):
        AgreementParams(max_beams=0)


def test_an_open_beam_is_clear_unless_the_pose_puts_a_wall_across_it() -> None:
    agreement = MapAgreement(LikelihoodField(two_rooms()))
    poses = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, math.pi / 2]])  # the west room: facing east, facing north
    ends = np.array([[0.8, 0.0], [2.6, 0.0]])  # open to 0.8 m ahead (clear), and to 2.6 m (across the divider)
    assert agreement.open_clear(poses, ends).tolist() == [[True, False], [True, False]]
    assert agreement.open_clear(poses, np.zeros((0, 2))).shape == (2, 0)


def test_beams_grazing_a_corner_answer_as_every_sample_would(numpy_baselines: ModuleType,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """The sampled walk skips the samples a free cell vouches for (`_sampled`); beams aimed a fraction of a
    millimetre past the corners of lone occupied cells are where a skip that reached too far would miss the cell.
    (With half the margin the skips take, dozens of these answers change.)"""
    data = np.zeros((200, 200), dtype=np.int8)
    rng = np.random.default_rng(0)
    cells = rng.integers(20, 180, (12, 2))
    data[cells[:, 0], cells[:, 1]] = 100
    grid = OccupancyMap(data, 0.05, Pose2D())
    ours, before = LikelihoodField(grid), numpy_baselines.NumpyLikelihoodField(grid)
    monkeypatch.setattr(likelihood_field, "DENSE_LOOKUPS", 10**12)
    monkeypatch.setattr(numpy_baselines, "DENSE_LOOKUPS", 10**12)
    crossed = 0
    for row, col in cells:
        for corner in ((col, row), (col + 1, row), (col, row + 1), (col + 1, row + 1)):
            aim = np.array(corner) * 0.05
            away = rng.uniform(1.0, 3.0)
            heading = rng.uniform(-math.pi, math.pi)
            start = aim - away * np.array([math.cos(heading), math.sin(heading)])
            bearings = heading + rng.uniform(-2e-4, 2e-4, 60) / away
            reach = away + rng.uniform(0.05, 1.0, 60)
            points = np.column_stack([reach * np.cos(bearings), reach * np.sin(bearings)])
            pose = np.array([[start[0], start[1], 0.0]])
            for stop in (0.0, 0.02):
                got = ours.crossings(pose, (0.0, 0.0), points, stop)
                np.testing.assert_array_equal(got, before.crossings(pose, (0.0, 0.0), points, stop))
                crossed += int(got.sum())
    assert 0 < crossed < 12 * 4 * 60 * 2  # beams on both sides of the corners
