"""Global localization that knows when it does not know (issue 21): localized, ambiguous or failed, never
confidently wrong.

The statistics run `benchmarks/global_localization.py` at the skill level (one simulated scan per true pose,
the shipped search). The issue's 50 seeded poses on the studio and on each external map of ``../shared`` take
about a minute of CPU (a search costs 50-200 ms, 0.7 s in the 50 m warehouse): the default suite runs all 50
on the studio and a seeded subset on each external map, checking what must hold for every single answer (no
confidently wrong one, the true place among an ambiguous answer's candidates); ``ATEMR_TEST_SOAK=1`` runs the 50
everywhere and checks the rates too, as README's table reports them.
"""

from __future__ import annotations

import importlib.util
import math
import os
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from atemr.errors import ConfigError
from atemr.io.sim.lidar import Lidar, LidarParams
from atemr.io.sim.maps import OccupancyMap
from atemr.io.sim.scene import Scene
from atemr.io.sim.world import World, load_world
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.localization.global_search import GlobalSearchParams, mcnemar_z
from atemr.skills.localization.localizer import LOOK_TIMEOUT_S, LOOKED_ROUND_RAD, Localizer
from atemr.skills.localization.scan import OPEN_SHORT_M, SILENT_RUN, _in_runs, open_ray_ends, scan_points, sensor_origin

ROOT = Path(__file__).resolve().parents[3]


def load_quality() -> ModuleType:
    spec = importlib.util.spec_from_file_location("global_localization_under_test",
                                                  ROOT / "benchmarks" / "global_localization.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


quality = load_quality()


def scan_from(world_name: str, pose: Pose2D, seed: int = 0):  # type: ignore[no-untyped-def]
    world = load_world(world_name)
    scan = Lidar(LidarParams(), np.random.default_rng(seed)).scan(0.0, pose, Scene(world), np.zeros((0, 2)),
                                                                   np.zeros(0))
    return world, scan_points(scan), sensor_origin(scan)


#: The issue's bar is 80 % localized on every map. From one scan the warehouse misses it (76 %): its aisles of
#: identical shelves look alike within the lidar's 8 m, so one scan often cannot tell them apart, and the search
#: says so (ambiguous, every look-alike listed) instead of guessing. What it reaches there is held here so it
#: cannot get worse unnoticed; docs/navigation.md's table says the same. Turning in place, as FIND POSITION and
#: the relocalize step do, meets the bar everywhere (`test_turning_in_place_meets_the_bar_on_every_map`).
MIN_LOCALIZED = {"nav2_warehouse": 0.76}
FULL = os.environ.get("ATEMR_TEST_SOAK") == "1"
#: Poses per map in the default suite (all 50 with ATEMR_TEST_SOAK=1).
POSES = {"studio": 50, "nav2_depot": 12, "nav2_tb3_sandbox": 12, "turtlebot3_world": 12, "nav2_warehouse": 6}


@pytest.mark.parametrize("name", ["studio", *quality.EXTERNAL_MAPS])
def test_never_confidently_wrong_and_mostly_localized(name: str, shared_dir: Path) -> None:
    world = name if name == "studio" else str(shared_dir / "worlds" / "external" / f"{name}.yaml")
    if not (name == "studio" or Path(world).is_file()):
        pytest.skip(f"{world} is not there")
    poses = 50 if FULL else POSES[name]
    trials = quality.run_world(world, poses, seed=0)
    row = quality.summarize(name, trials)
    wrong = [(t.truth, t.pose) for t in trials if t.wrong]
    assert row.wrong == 0, f"confidently wrong on {name}: {wrong}"
    unlisted = [t.truth for t in trials if t.outcome == "ambiguous" and not t.truth_listed]
    assert not unlisted, f"ambiguous without the true place on {name}: {unlisted}"
    if name not in MIN_LOCALIZED:  # mostly localized, even in a small sample
        assert row.localized >= 0.5 * row.poses, quality.table([row])
    if poses == 50:
        assert row.localized >= MIN_LOCALIZED.get(name, quality.MIN_LOCALIZED) * row.poses, quality.table([row])
        assert row.met == (name not in MIN_LOCALIZED)


def test_turning_in_place_meets_the_bar_on_every_map(shared_dir: Path) -> None:
    """An ambiguous answer followed by turning in place (`quality.turn_in_place`, as the robot does after FIND
    POSITION or in a relocalize step): with ATEMR_TEST_SOAK=1 every map's 50 poses reach 80 %, never confidently
    wrong; the default suite turns at the warehouse's first six poses, where one scan is ambiguous at three."""
    external = shared_dir / "worlds" / "external"
    if not (external / "nav2_warehouse.yaml").is_file():
        pytest.skip(f"{external / 'nav2_warehouse.yaml'} is not there")
    if not FULL:
        world = str(external / "nav2_warehouse.yaml")
        one_scan = quality.summarize("nav2_warehouse", quality.run_world(world, POSES["nav2_warehouse"], seed=0))
        turned = quality.summarize("nav2_warehouse", quality.run_world(world, POSES["nav2_warehouse"], seed=0,
                                                                       turn=True))
        assert turned.wrong == 0 and (one_scan.localized, turned.localized) == (3, 5), \
            quality.table([one_scan, turned])
        return
    for name in ("studio", *quality.EXTERNAL_MAPS):
        world = name if name == "studio" else str(external / f"{name}.yaml")
        if name != "studio" and not Path(world).is_file():
            continue
        row = quality.summarize(name, quality.run_world(world, 50, seed=0, turn=True))
        assert row.wrong == 0 and row.met, quality.table([row])


def test_twin_rooms_are_ambiguous_with_both_rooms_never_localized_in_either() -> None:
    trials = quality.run_world("twin_rooms", 12, seed=1)
    assert [t.outcome for t in trials] == ["ambiguous"] * 12
    world = load_world("twin_rooms")
    search = quality.search_for(world)
    for truth in (Pose2D(2.0, 1.75, 0.0), Pose2D(7.0, 2.0, 2.5)):  # one in each room
        _, points, sensor = scan_from("twin_rooms", truth)
        result = search.localize(points, sensor)
        assert result.outcome == "ambiguous" and result.pose is None, result.reason
        twin = Pose2D(8.15 - truth.x_m, 3.5 - truth.y_m, truth.yaw_rad + math.pi)  # half a turn about the door
        for place in (truth, twin):
            assert any(h.pose.distance_to(place) < 0.1
                       and abs(math.remainder(h.pose.yaw_rad - place.yaw_rad, 2 * math.pi)) < 0.05
                       for h in result.candidates), (place, result.candidates)
        assert result.confidence < search.params.min_agreement  # shared between the rooms: not localized
        assert "2 places explain the scan about equally" in result.reason


def test_a_scan_from_elsewhere_fails_and_says_why() -> None:
    """A scan the map cannot explain (taken in another flat) is not forced onto the map."""
    _, points, sensor = scan_from("twin_rooms", Pose2D(2.0, 1.75, 0.3))
    result = quality.search_for(load_world("studio")).localize(points, sensor)
    assert result.outcome == "failed" and result.pose is None
    assert result.confidence < 0.7 and "no place on the map explains the scan" in result.reason
    empty = quality.search_for(load_world("studio")).localize(np.zeros((0, 2)))
    assert empty.outcome == "failed" and "too few valid returns" in empty.reason


def test_the_issues_robot_is_found_where_it_stands() -> None:
    """Issue 21: at about (5.23, 4.58) the old search converged in another room, sure of itself. Returns from
    beyond the search's range (a lidar set up for a longer one) do not wrap round into it."""
    truth = Pose2D(5.23, 4.58, -2.6)
    world, points, sensor = scan_from("studio", truth)
    far = np.array([[x, y] for x in (-30.0, 25.0) for y in (-18.0, 40.0)])
    search = quality.search_for(world)
    assert not np.isin(search.thin(np.vstack([points, far])), far).all(axis=1).any()
    result = search.localize(np.vstack([points, far]), sensor)
    assert result.outcome == "localized" and result.pose is not None, result.reason
    assert result.pose.distance_to(truth) < 0.1 and result.confidence > 0.9


def test_mcnemar_counts_only_the_beams_the_places_disagree_on() -> None:
    a = np.array([True] * 90 + [False] * 10)
    assert mcnemar_z(a, a) == 0.0
    b = a.copy()
    b[:20] = False  # B misses 20 beams A hits
    assert mcnemar_z(a, b) == pytest.approx(20 / math.sqrt(20))
    assert mcnemar_z(b, a) == pytest.approx(-mcnemar_z(a, b))


def test_bad_parameters_name_the_key() -> None:
    with pytest.raises(ConfigError, match="step_xy_m"):
        GlobalSearchParams(step_xy_m=0.0)
    with pytest.raises(ConfigError, match="min_agreement"):
        GlobalSearchParams(min_agreement=1.0)
    with pytest.raises(ConfigError, match="beams"):
        GlobalSearchParams(keep=0)


def drive_straight(world_name: str, start: Pose2D, metres: float) -> tuple[Localizer, Pose2D, list[str]]:
    """FIND POSITION at ``start``, then the operator drives straight ahead (a scan every 4 cm, exact odometry)."""
    world = load_world(world_name)
    scene, lidar = Scene(world), Lidar(LidarParams(), np.random.default_rng(0))
    localizer = Localizer(world.map, np.random.default_rng(0))
    localizer.start_global(0.0, "test")
    states, truth = [], start
    for k in range(int(metres / 0.04) + 1):
        d = 0.04 * k
        truth = Pose2D(start.x_m + d * math.cos(start.yaw_rad), start.y_m + d * math.sin(start.yaw_rad), start.yaw_rad)
        states.append(localizer.update(0.1 * k, Pose2D(d, 0.0, 0.0), lidar.scan(0.1 * k, truth, scene,
                                                                               np.zeros((0, 2)), np.zeros(0))))
    return localizer, truth, states


def test_only_the_operators_ambiguous_search_asks_to_look_around() -> None:
    """FIND POSITION (``look_around``) that answers ambiguous asks the robot to turn in place (`wants_a_look`),
    and the event says it turns; a search the robot started by itself does not, nor does one that is answered
    (a pose set)."""
    world = load_world("twin_rooms")
    scene, lidar = Scene(world), Lidar(LidarParams(), np.random.default_rng(0))
    scan = lidar.scan(0.0, Pose2D(6.2, 1.2, 1.0), scene, np.zeros((0, 2)), np.zeros(0))
    for asked in (True, False):
        localizer = Localizer(world.map, np.random.default_rng(0))
        localizer.start_global(0.0, "test", look_around=asked)
        assert not localizer.wants_a_look  # nothing answered yet
        assert localizer.update(0.1, Pose2D(0.0, 0.0, 0.0), scan) == "ambiguous"
        assert localizer.wants_a_look is asked
        said = localizer.events[-1].detail
        assert ("turning in place" in said) is asked and ("move the robot" in said) is not asked
    localizer.start_global(0.2, "again", look_around=True)
    localizer.update(0.3, Pose2D(0.0, 0.0, 0.0), scan)
    assert localizer.wants_a_look
    localizer.set_initial_pose(0.4, Pose2D(6.2, 1.2, 1.0))
    assert not localizer.wants_a_look
    localizer.start_global(0.5, "and again", look_around=True)
    localizer.update(0.6, Pose2D(0.0, 0.0, 0.0), scan)
    assert localizer.wants_a_look
    localizer.stop_looking()  # the operator took over (the joystick, STOP, mapping)
    assert not localizer.wants_a_look and localizer.state == "ambiguous"


def test_the_look_around_ends_after_a_turn_or_a_time_limit() -> None:
    """The localizer owns the end of the operator's look: it stops asking once the robot has turned about once
    round (the views pooled meanwhile), or after `LOOK_TIMEOUT_S` when nothing turned it (a safety stop, blocked
    wheels), and says so; never does it stay asked for, to turn the robot again later."""
    world = load_world("twin_rooms")
    scene, lidar = Scene(world), Lidar(LidarParams(), np.random.default_rng(2))
    truth = Pose2D(6.2, 1.2, 1.0)
    none = (np.zeros((0, 2)), np.zeros(0))
    # held still: asked until the time limit
    held = Localizer(world.map, np.random.default_rng(0))
    held.start_global(0.0, "test", look_around=True)
    t = 0.1
    while t < LOOK_TIMEOUT_S + 1.0 and (t < 1.0 or held.wants_a_look):
        held.update(t, Pose2D(0.0, 0.0, 0.0), lidar.scan(t, truth, scene, *none))
        assert held.state == "ambiguous" and (held.wants_a_look or t >= LOOK_TIMEOUT_S)
        t = round(t + 0.1, 6)
    assert not held.wants_a_look and LOOK_TIMEOUT_S <= t < LOOK_TIMEOUT_S + 0.2
    assert held.events[-1].kind == "ambiguous" and "looked around for 30 s" in held.events[-1].detail
    # turned at 0.4 rad/s: asked until about once round
    turned = Localizer(world.map, np.random.default_rng(0))
    turned.start_global(0.0, "test", look_around=True)
    yaw, k = 0.0, 0
    while k < 200 and (k < 10 or turned.wants_a_look):
        k += 1
        pose = Pose2D(truth.x_m, truth.y_m, truth.yaw_rad + yaw)
        turned.update(0.1 * k, Pose2D(0.0, 0.0, yaw), lidar.scan(0.1 * k, pose, scene, *none))
        yaw += 0.04 if turned.wants_a_look else 0.0
    assert not turned.wants_a_look
    if turned.state == "ambiguous":
        assert LOOKED_ROUND_RAD - 0.05 <= yaw <= LOOKED_ROUND_RAD + 0.05, yaw
        assert "turned once round" in turned.events[-1].detail
    else:  # the rooms differ by a table's place: a turn may tell them apart, in the true room
        assert turned.state == "localized" and turned.estimate is not None
        assert math.hypot(turned.estimate.pose.x_m - truth.x_m, turned.estimate.pose.y_m - truth.y_m) < 0.3


def test_an_ambiguous_robot_decides_once_it_has_moved(shared_dir: Path) -> None:
    """One scan cannot tell this place of the sandbox from its near mirror; a metre of driving can. Every
    candidate is carried along and the new views pooled: localized at the true place, never the twin."""
    world = shared_dir / "worlds" / "external" / "nav2_tb3_sandbox.yaml"
    if not world.is_file():
        pytest.skip(f"{world} is not there")
    localizer, truth, states = drive_straight(str(world), Pose2D(-0.525, -0.075, 1.533), 1.0)
    assert states[0] == "ambiguous" and states[-1] == "localized", states
    assert "localized" not in states[:states.index("localized")] and "lost" not in states
    kinds = [e.kind for e in localizer.events]
    assert kinds == ["global_start", "ambiguous", "localized"] and "views" in localizer.events[-1].detail
    estimate = localizer.estimate
    assert estimate is not None and estimate.pose.distance_to(truth) < 0.05


def test_twin_rooms_stay_ambiguous_while_driving_both_candidates_carried_along() -> None:
    localizer, truth, states = drive_straight("twin_rooms", Pose2D(1.0, 1.75, 0.0), 1.2)
    assert set(states) == {"ambiguous"}, states
    twin = Pose2D(8.15 - truth.x_m, 3.5 - truth.y_m, truth.yaw_rad + math.pi)
    places = localizer.candidates
    assert any(h.pose.distance_to(truth) < 0.1 for h in places) and any(h.pose.distance_to(twin) < 0.1
                                                                        for h in places), places


def alcoves(depth_m: float = 13.0) -> World:
    """Two identical 2 m alcoves open to the north, at 0.05 m: the west one (x 10 m) opens onto a hall that
    reaches more than the lidar's 8 m from anywhere inside it (``depth_m`` deep: at 20 m, beyond the device's
    12 m reach too), the east one (x 35 m) onto a wall 3 m off. From inside, the returns of the two are the same."""
    data = np.zeros((round(depth_m / 0.05), 1000), dtype=np.int8)  # 50 m wide
    data[:2, :] = data[-2:, :] = data[:, :2] = data[:, -2:] = 100
    for x0 in (200, 700):  # the back wall at y 1 m, the sides 2 m deep
        data[20:22, x0:x0 + 42] = 100
        data[20:60, x0:x0 + 2] = data[20:60, x0 + 40:x0 + 42] = 100
    data[118:120, 560:880] = 100  # y 5.9 m, x 28 to 44 m: in front of the east alcove only
    grid = OccupancyMap(data, 0.05, Pose2D(0.0, 0.0, 0.0))
    return World("alcoves", grid, Pose2D(11.0, 2.0, 0.0))


def test_open_beams_tell_apart_places_whose_returns_look_alike() -> None:
    """Beams that return nothing within the lidar's range (+inf) crossed open space: the west alcove, facing
    a hall, is the only place that explains them; the east one puts a wall across them. Without that
    evidence the two are ambiguous; with it, and in the localizer (which passes it), localized at the truth."""
    world = alcoves()
    scene, lidar = Scene(world), Lidar(LidarParams(), np.random.default_rng(3))
    search = quality.search_for(world)
    twin_offset = 25.0
    for truth in (Pose2D(11.3, 2.2, 0.4), Pose2D(10.6, 1.8, 2.0)):
        scan = lidar.scan(0.0, truth, scene, np.zeros((0, 2)), np.zeros(0))
        points, sensor, opens = scan_points(scan), sensor_origin(scan), open_ray_ends(scan)
        assert opens.shape[0] > 20  # the beams out of the alcove's mouth
        blind = search.localize(points, sensor)
        assert blind.outcome == "ambiguous", blind.reason
        twin = Pose2D(truth.x_m + twin_offset, truth.y_m, truth.yaw_rad)
        assert all(any(h.pose.distance_to(p) < 0.1 for h in blind.candidates) for p in (truth, twin))
        seeing = search.localize(points, sensor, opens)
        assert seeing.outcome == "localized" and seeing.pose is not None, seeing.reason
        assert seeing.pose.distance_to(truth) < 0.1
        assert seeing.confidence == pytest.approx(blind.candidates[0].agreement, abs=0.02)  # beams' share only
        localizer = Localizer(world.map, np.random.default_rng(0))
        localizer.start_global(0.0, "test")
        assert localizer.update(0.1, Pose2D(0.0, 0.0, 0.0), scan) == "localized"
        assert localizer.estimate is not None and localizer.estimate.pose.distance_to(truth) < 0.1
    # in the east alcove the wall in front returns: that place is told apart by its returns alone
    east = Pose2D(36.3, 2.2, 0.4)
    scan = lidar.scan(0.0, east, scene, np.zeros((0, 2)), np.zeros(0))
    result = search.localize(scan_points(scan), sensor_origin(scan), open_ray_ends(scan))
    assert result.outcome == "localized" and result.pose is not None and result.pose.distance_to(east) < 0.1


def test_open_ray_ends_are_the_plus_inf_beams_short_of_the_range() -> None:
    """+inf (a return beyond the range) is open space; a lone NaN (no return: a dropout, a dark spot) and -inf
    say nothing."""
    ranges = np.array([np.inf, 2.0, np.nan, -np.inf, np.inf])
    scan = LaserScan(0.0, ranges, 0.0, math.pi / 2, 0.15, 8.0, Pose2D(0.1, 0.0, math.pi))
    ends = open_ray_ends(scan)
    reach = 8.0 - OPEN_SHORT_M
    assert ends == pytest.approx(np.array([[0.1 - reach, 0.0], [0.1 - reach, 0.0]]))  # beams at 0 and 2π, turned
    assert open_ray_ends(LaserScan(0.0, np.array([1.0, np.nan]), 0.0, 0.1, 0.1, 8.0)).shape == (0, 2)


def angles(ends: np.ndarray) -> list[float]:
    """The bearings of base-frame points, whole degrees."""
    return np.round(np.degrees(np.arctan2(ends[:, 1], ends[:, 0]))).tolist()


def test_runs_of_silent_beams_are_open_lone_ones_are_not() -> None:
    """NaN beams in a run of at least `SILENT_RUN` neighbours are open (nothing within the device's reach that
    way); shorter runs are dropouts. On a whole revolution the last beam neighbours the first; on a partial
    scan it does not."""
    nan = np.nan
    ranges = np.array([nan, nan, 2.0, nan, nan, nan, 3.0, nan, 2.0, 2.0, 2.0, nan])
    full = LaserScan(0.0, ranges, -math.pi, 2 * math.pi / ranges.size, 0.15, 8.0, Pose2D(0.0, 0.0, 0.0))
    # beams 3-5 (-90, -60, -30 degrees) and, round the end, 11, 0, 1 (150, -180, -150)
    assert sorted(angles(open_ray_ends(full))) == sorted([-90.0, -60.0, -30.0, 150.0, -180.0, -150.0])
    assert SILENT_RUN == 3
    part = LaserScan(0.0, ranges, -math.pi / 2, math.radians(10), 0.15, 8.0, Pose2D(0.0, 0.0, 0.0))
    assert angles(open_ray_ends(part)) == [-60.0, -50.0, -40.0]  # beams 3-5 only: 11 and 0 are 120 degrees apart
    assert open_ray_ends(full, silent_run=7).shape == (0, 2)


def test_runs_are_what_every_window_of_true_flags_covers() -> None:
    """`_in_runs` finds runs from where the flags switch; it marks exactly the flags some window of ``length``
    consecutive true flags covers (round the end too on a revolution), on 5,000 random rows of every density."""
    rng = np.random.default_rng(4)
    for _ in range(5000):
        n, length, wrap = int(rng.integers(0, 30)), int(rng.integers(0, 10)), bool(rng.integers(0, 2))
        flags = rng.random(n) < rng.uniform(0.0, 1.0)
        expected = np.zeros(n, dtype=bool) if length > 1 else flags.copy()
        if length > 1:
            for start in range(n if wrap else n - length + 1):
                window = [(start + k) % n for k in range(length)] if length <= n else []
                if window and flags[window].all():
                    expected[window] = True
        np.testing.assert_array_equal(_in_runs(flags, length, wrap=wrap), expected, err_msg=f"{flags} {length} {wrap}")


def test_silent_beams_beyond_the_devices_reach_tell_places_apart() -> None:
    """The west alcove's hall 20 m deep: out of its mouth the beams return nothing at all within the A2M8's 12 m
    (NaN, not +inf). Those silent runs are open space as +inf beams are: localized at the truth, where
    without them the two alcoves are ambiguous."""
    world = alcoves(depth_m=20.0)
    scene, lidar = Scene(world), Lidar(LidarParams(), np.random.default_rng(3))
    search = quality.search_for(world)
    truth = Pose2D(11.3, 2.2, 0.4)
    scan = lidar.scan(0.0, truth, scene, np.zeros((0, 2)), np.zeros(0))
    assert np.count_nonzero(np.isnan(scan.ranges_m)) > 20 and not np.isposinf(scan.ranges_m).any()
    points, sensor, opens = scan_points(scan), sensor_origin(scan), open_ray_ends(scan)
    assert opens.shape[0] > 20
    deaf = search.localize(points, sensor, open_ray_ends(scan, silent_run=scan.ranges_m.size + 1))
    assert deaf.outcome == "ambiguous", deaf.reason
    result = search.localize(points, sensor, opens)
    assert result.outcome == "localized" and result.pose is not None, result.reason
    assert result.pose.distance_to(truth) < 0.1
