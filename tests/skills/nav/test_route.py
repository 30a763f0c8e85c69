"""A goal with a route (Nav2's FollowPath): the Navigator drives along the given points, not the shortest way."""

import itertools
import math

import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.io.sim.base import integrate_arc
from atemr.msgs import Pose2D
from atemr.skills.nav.navigator import Navigator
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
    assert following[0].distance_left_m > 9.0, "distance left is along the route"


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
    nav._t_plan = -math.inf  # the next tick replans, as after a new scan
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
    # Progress only moves forward, and only within the window ahead: a loop back is no shortcut.
    loop = Route.through([[2.0, 0.0], [2.0, 0.2]], Pose2D(0.0, 0.2, 0.0), 0.05)
    assert loop.advance(0.0, 0.19) > 1.0 and loop.index == 0, "off the route: progress stays"
    assert loop.advance(2.0, 0.1) == pytest.approx(0.0) and loop.index == 2
    assert loop.advance(0.0, 0.19) > 1.0 and loop.index == 2
    assert loop.advance(1.5, 0.2) == pytest.approx(0.0) and loop.index == 14

