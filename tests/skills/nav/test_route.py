"""A goal with a route (Nav2's FollowPath): the Navigator drives along the given points, not the shortest way."""

import itertools
import math

import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.io.sim.base import integrate_arc
from atemr.msgs import Pose2D
from atemr.skills.nav.local_planner import LocalPlannerParams
from atemr.skills.nav.navigator import Navigator, NavParams
from atemr.skills.nav.route import Route

RES = 0.05
DT = 0.1
START = Pose2D(0.6, 0.6, 0.0)
GOAL = Pose2D(4.4, 0.6, 0.0)
#: Up the left side, along the top, down the right side: three times the straight way along the bottom.
DETOUR = [[0.6, 3.2], [4.4, 3.2]]


def hall(make_map):
    """An empty 5 m x 4 m room."""
    data = np.zeros((80, 100), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    return make_map(data, RES)


def drive(nav, pose, seconds, t0=0.0):
    poses, statuses, t = [pose], [], t0
    for _ in range(round(seconds / DT)):
        status = nav.update(t, pose, None, True)
        statuses.append(status)
        if status.state != "RUNNING":
            break
        pose = integrate_arc(pose, status.twist.linear_mps, status.twist.angular_radps, DT)
        poses.append(pose)
        t += DT
    return np.array([[p.x_m, p.y_m] for p in poses]), statuses


def distance_to_polyline(xy, corners):
    """Distance of each point of ``xy`` to the polyline through ``corners``."""
    best = np.full(len(xy), np.inf)
    for a, b in itertools.pairwise(corners):
        ab = b - a
        t = np.clip(((xy - a) @ ab) / (ab @ ab), 0.0, 1.0)
        best = np.minimum(best, np.hypot(*(xy - (a + t[:, None] * ab)).T))
    return best


def test_the_route_is_followed_not_the_shortest_way(make_map):
    shortest = Navigator(hall(make_map))
    shortest.start(GOAL, 0.0)
    xy, statuses = drive(shortest, START, 60.0)
    assert statuses[-1].state == "SUCCEEDED" and xy[:, 1].max() < 1.2, "without a route: straight along the bottom"

    nav = Navigator(hall(make_map))
    nav.start(GOAL, 0.0, route=DETOUR)
    xy, statuses = drive(nav, START, 120.0)
    assert statuses[-1].state == "SUCCEEDED", statuses[-1]
    assert math.dist(xy[-1], (GOAL.x_m, GOAL.y_m)) <= 0.25
    corners = np.array([[START.x_m, START.y_m], *DETOUR, [GOAL.x_m, GOAL.y_m]])
    assert distance_to_polyline(xy, corners).max() < 0.35, "stays on the route"
    assert xy[:, 1].max() > 3.0, "went along the top"
    # In order: up the left side before the right side.
    near_left, near_right = (np.hypot(*(xy - corner).T) < 0.5 for corner in DETOUR)
    assert near_left.any() and near_right.any(), "rounded both corners of the route"
    assert int(np.argmax(near_left)) < int(np.argmax(near_right))
    assert "along a" in nav.events[0].detail
    following = [s for s in statuses if s.phase == "following the path"]
    assert following[0].distance_left_m == pytest.approx(9.0, abs=0.1), "left along the route: 2.6 to it + 6.4"


def test_a_robot_off_the_route_first_drives_to_it(make_map):
    nav = Navigator(hall(make_map))
    nav.start(GOAL, 0.0, route=DETOUR)
    xy, statuses = drive(nav, Pose2D(2.5, 0.6, 0.0), 120.0)  # starts in the middle of the bottom
    assert statuses[-1].state == "SUCCEEDED"
    assert [e.kind for e in nav.events][:2] == ["goal", "plan"]
    # Drove to the route's start (joined within its first metre: nothing skipped), then followed it round.
    up = int(np.argmax(xy[:, 1] > 3.0))
    assert up > 0 and xy[up, 0] < 1.6 + 0.35, f"reached the top at x = {xy[up, 0]:.2f}"
    assert np.hypot(*(xy - DETOUR[1]).T).min() < 0.5


@pytest.mark.parametrize(("route", "why"), [
    ([[2.5, 3.2], [2.5, 4.5]], "route leaves the map near"),
    ([[2.5, 3.2], [2.5, 3.95]], "route passes through or too close to an obstacle near"),
    ([[2.5, float("nan")]], r"route point 0 must be two finite numbers"),
    ([[2.5, 1.0, 0.0]], r"route point 0 must be two finite numbers"),
])
def test_a_route_the_map_rules_out_is_refused(make_map, route, why):
    nav = Navigator(hall(make_map))
    with pytest.raises(NavigationError, match=why):
        nav.start(GOAL, 0.0, route=route)
    assert nav.state == "IDLE" and nav.route is None
    assert nav.events[-1].kind == "refused"


def test_a_blocked_route_is_waited_for_not_bypassed(make_map):
    nav = Navigator(hall(make_map))
    nav.start(GOAL, 0.0, route=DETOUR)
    xy, _ = drive(nav, START, 6.0)  # on the way up the left side
    # Someone stands across the top stretch, right ahead (the predicted layer stands in for the scan).
    wall = np.array([[x, y] for x in np.arange(0.05, 1.6, 0.05) for y in np.arange(3.0, 3.95, 0.05)])
    nav.costmap.set_predicted(wall)
    nav._run.t_plan = -math.inf  # the next tick replans, as after a new scan
    pose = Pose2D(0.6, 2.6, math.pi / 2)
    xy, statuses = drive(nav, pose, 2.0, t0=10.0)
    assert statuses[-1].phase == "no path: waiting", statuses[-1]
    assert statuses[-1].global_path.shape[0] == 0, "no other way offered"
    assert xy[:, 1].min() > 2.4, "did not turn back to the short way along the bottom"


def test_route_points_are_dense_and_end_at_the_goal():
    route = Route.through([[0.0, 0.0], [1.0, 0.0]], Pose2D(1.0, 1.0, 0.0), 0.05)
    assert np.allclose(route.points[0], [0.0, 0.0]) and np.allclose(route.points[-1], [1.0, 1.0])
    assert np.hypot(*np.diff(route.points, axis=0).T).max() <= 0.05 + 1e-12
    assert route.length_m == pytest.approx(2.0)
    # A hairpin: out along y = 0, back along y = 0.2 (legs closer than the join distance).
    hairpin = Route.through([[0.0, 0.0], [2.0, 0.0], [2.0, 0.2]], Pose2D(0.0, 0.2, math.pi), 0.05)
    assert hairpin.advance(1.0, 0.02) > 0.35 and hairpin.index == 0, "1 m on in one call: not yet"
    for x in (0.3, 0.6, 0.9, 1.0):  # the robot drives along the first leg
        hairpin.advance(x, 0.02)
    assert hairpin.index == 20, "the first pass, not the return leg 0.18 m away"
    assert hairpin.advance(1.5, 1.0) > 0.35 and hairpin.index == 20, "off the route: the progress stays"
    window = hairpin.window()
    assert math.dist(window[-1], (2.0, 0.2)) <= 0.15 and window[:, 0].min() >= 1.0 - 1e-9, \
        "up to the turn, and not back along the return leg"
    assert hairpin.remaining_m == pytest.approx(1.0 + 0.2 + 2.0)
    for x in (1.4, 1.8, 2.0):
        hairpin.advance(x, 0.01)
    assert hairpin.advance(2.0, 0.2) == pytest.approx(0.0) and hairpin.index == 44
    assert hairpin.window()[-1, 0] < 0.1, "at the apex: the return leg is next"
    with pytest.raises(ValueError, match="route point 1 must be two finite numbers"):
        Route.through([[0.0, 0.0], 5.0], Pose2D(0.0, 0.2, 0.0), 0.05)  # type: ignore[list-item]
    with pytest.raises(ValueError, match="route point 0 must be two finite numbers"):
        Route.through([[1.0, None]], Pose2D(0.0, 0.2, 0.0), 0.05)  # type: ignore[list-item]


@pytest.mark.parametrize("gap_m", [0.4, 0.2])
def test_a_hairpin_route_is_driven_to_its_turn_and_back(make_map, gap_m):
    # Out 3.4 m along y = 0.6, back along y = 0.6 + gap: the return leg is close by all the way out (taken for
    # "the way on", it made the robot turn back early, or shuttle for ever when the legs were 0.2 m apart).
    nav = Navigator(hall(make_map))
    back = 0.6 + gap_m
    nav.start(Pose2D(0.6, back, math.pi), 0.0, route=[[4.0, 0.6], [4.0, back]])
    xy, statuses = drive(nav, START, 120.0)
    assert statuses[-1].state == "SUCCEEDED", statuses[-1]
    assert xy[:, 0].max() > 3.6, "drove out to the turn (rounding its corner, as the local planner does)"
    assert math.dist(xy[-1], (0.6, back)) <= 0.25


def test_a_fast_robot_keeps_its_progress_and_never_turns_back(make_map):
    params = NavParams(local=LocalPlannerParams(max_linear_mps=1.0))
    nav = Navigator(hall(make_map), params)
    nav.start(GOAL, 0.0, route=DETOUR)
    xy, statuses = drive(nav, START, 120.0)
    assert statuses[-1].state == "SUCCEEDED"
    left = [s.distance_left_m for s in statuses if s.phase == "following the path"]
    assert max(b - a for a, b in itertools.pairwise(left)) < 0.15, "the distance left never jumps back up"
    assert xy[:, 1].max() > 3.0


def test_a_route_back_to_its_start_is_driven_before_the_goal_counts(make_map):
    nav = Navigator(hall(make_map))
    nav.start(Pose2D(START.x_m, START.y_m, 0.0), 0.0, route=[[2.5, 0.6], [2.5, 2.0], [0.6, 2.0]])
    xy, statuses = drive(nav, START, 120.0)
    assert statuses[-1].state == "SUCCEEDED" and len(statuses) > 50, "not reached at once: it is a round"
    assert np.hypot(*(xy - (2.5, 2.0)).T).min() < 0.5


def test_someone_by_the_goal_does_not_block_a_route(make_map):
    nav = Navigator(hall(make_map))
    nav.start(GOAL, 0.0, route=[[2.5, 0.6]])
    person = np.array([[GOAL.x_m + dx, GOAL.y_m + 0.35 + dy] for dx in (-0.05, 0.0, 0.05) for dy in (-0.05, 0.0, 0.05)])
    nav.costmap.set_predicted(person)
    xy, statuses = drive(nav, START, 60.0)
    assert statuses[-1].state == "SUCCEEDED", statuses[-1]
    assert math.dist(xy[-1], (GOAL.x_m, GOAL.y_m)) <= 0.25


def test_a_new_map_that_rules_the_route_out_fails_the_goal(make_map):
    nav = Navigator(hall(make_map))
    nav.start(GOAL, 0.0, route=DETOUR)
    drive(nav, START, 2.0)
    walled = np.zeros((80, 100), dtype=np.int8)
    walled[0, :] = walled[-1, :] = walled[:, 0] = walled[:, -1] = 100
    walled[50:, 50:52] = 100  # a wall across the top stretch of the route
    nav.set_map(make_map(walled, RES))
    status = nav.update(2.1, Pose2D(0.6, 1.0, math.pi / 2))
    assert status.state == "FAILED" and status.reason == "no path"
    assert "the route does not fit the new map: route passes through" in status.message


