import math

import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.io.sim.simulation import build_simulation
from atemr.msgs import Pose2D, Twist
from atemr.skills.nav.costmap import Costmap
from atemr.skills.nav.local_planner import (
    LocalPlanner,
    LocalPlannerParams,
    ramped_rollout,
    stop_cone_clearance,
    zone_speed_cap,
)

RES = 0.05


@pytest.fixture
def open_room(make_map, make_room):
    return Costmap(make_map(make_room(80, 120), RES))  # 6 m x 4 m


def straight_path(x0, x1, y):
    xs = np.arange(x0, x1 + 1e-9, 0.05)
    return np.column_stack([xs, np.full_like(xs, y)])


def test_ramped_rollout_holds_the_arc_and_ramps_within_the_limits():
    # Already at the target: the exact arc (quarter circle of radius v / w after pi / 2 / w seconds).
    v, w = 0.5, math.pi / 2
    x, y, th = ramped_rollout(Pose2D(1.0, 2.0, 0.0), Twist(v, w), np.array([v]), np.array([w]), step_s=0.01,
                              steps=100, linear_accel=1.0, angular_accel=1.0)
    radius = v / w
    assert x[0, -1] == pytest.approx(1.0 + radius, abs=1e-4) and y[0, -1] == pytest.approx(2.0 + radius, abs=1e-4)
    assert th[0, -1] == pytest.approx(math.pi / 2)
    # From rest towards 0.5 m/s at 1 m/s^2: 0.5 t^2 for the first 0.5 s, then 0.5 m/s.
    x, y, _ = ramped_rollout(Pose2D(), Twist(), np.array([0.5]), np.array([0.0]), step_s=0.1, steps=10,
                             linear_accel=1.0, angular_accel=1.0)
    assert x[0, 4] == pytest.approx(0.125, abs=1e-9) and x[0, 9] == pytest.approx(0.125 + 0.25, abs=1e-9)
    assert np.allclose(y, 0.0)


def test_follows_a_straight_path_within_the_limits(open_room):
    params = LocalPlannerParams()
    lp = LocalPlanner(open_room, params)
    path = straight_path(1.0, 5.0, 2.0)
    v0 = Twist(0.3, 0.0)
    plan = lp.compute(Pose2D(1.0, 2.0, 0.0), v0, path, (5.0, 2.0), 0.1)
    assert plan.ok and plan.valid > 0
    # Speed is scored (by progress over the rollout): on a clear path the fastest target wins, so the command
    # is a full acceleration step towards it.
    assert plan.twist.linear_mps == pytest.approx(0.3 + params.linear_accel_mps2 * 0.1)
    assert abs(plan.twist.angular_radps) < 0.1
    # From rest it can only speed up by a * dt.
    plan = lp.compute(Pose2D(1.0, 2.0, 0.0), Twist(), path, (5.0, 2.0), 0.1)
    assert 0 < plan.twist.linear_mps <= params.linear_accel_mps2 * 0.1 + 1e-12
    # At top speed it stays at or below the limit.
    plan = lp.compute(Pose2D(1.0, 2.0, 0.0), Twist(params.max_linear_mps, 0.0), path, (5.0, 2.0), 0.1)
    assert plan.twist.linear_mps <= params.max_linear_mps + 1e-12


def test_steers_back_onto_the_path(open_room):
    lp = LocalPlanner(open_room)
    path = straight_path(1.0, 5.0, 2.0)
    plan = lp.compute(Pose2D(1.5, 1.7, 0.0), Twist(0.3, 0.0), path, (5.0, 2.0), 0.1)
    assert plan.twist.angular_radps > 0.05  # the path is to the left


def test_turns_on_the_spot_when_the_path_is_behind(open_room):
    lp = LocalPlanner(open_room)
    path = straight_path(1.0, 5.0, 2.0)[::-1]  # towards -x
    plan = lp.compute(Pose2D(4.0, 2.0, 0.0), Twist(), path, (1.0, 2.0), 0.1)
    assert plan.twist.linear_mps == 0.0 and plan.twist.angular_radps != 0.0


def test_slows_for_the_goal_and_stops_there(open_room):
    from atemr.io.sim.base import integrate_arc

    params = LocalPlannerParams()
    lp = LocalPlanner(open_room, params)
    path = straight_path(1.0, 3.0, 2.0)
    pose, v = Pose2D(1.0, 2.0, 0.0), Twist(params.max_linear_mps, 0.0)
    for _ in range(60):
        plan = lp.compute(pose, v, path, (3.0, 2.0), 0.1)
        assert abs(plan.twist.linear_mps - v.linear_mps) <= params.linear_accel_mps2 * 0.1 + 1e-9
        v = plan.twist
        pose = integrate_arc(pose, v.linear_mps, v.angular_radps, 0.1)
    assert abs(pose.x_m - 3.0) < 0.1 and abs(pose.y_m - 2.0) < 0.05
    assert v.linear_mps < 0.1


def test_never_drives_into_a_wall_ahead(make_map, make_room):
    data = make_room(80, 120)
    data[:, 50] = 100  # a wall across the room at x = 2.5 m
    cm = Costmap(make_map(data, RES))
    lp = LocalPlanner(cm)
    path = straight_path(1.5, 5.0, 2.0)  # a (stale) path straight through the wall
    pose = Pose2D(2.1, 2.0, 0.0)
    plan = lp.compute(pose, Twist(0.4, 0.0), path, (5.0, 2.0), 0.1)
    if plan.ok:
        clear = cm.distance_at(plan.trajectory[:, 0], plan.trajectory[:, 1])
        assert (clear >= cm.params.inscribed_radius_m - 1e-6).all()
    # Pressed against it (inside the inscribed zone), only moves that get farther away are allowed.
    pose = Pose2D(2.3, 2.0, 0.0)
    plan = lp.compute(pose, Twist(), path, (5.0, 2.0), 0.1)
    ends = plan.trajectory[-1]
    assert cm.distance_at(ends[0], ends[1]) >= cm.distance_at(pose.x_m, pose.y_m)


def test_the_stop_cone_flags_obstacles_ahead_within_60_degrees_not_beside(make_map, make_room):
    data = make_room(80, 120)
    data[40, 60] = 100  # one obstacle cell at (3.025, 2.025)
    cm = Costmap(make_map(data, RES))
    ox, oy = 3.025, 2.025
    r = 0.40

    def cone(bearing_deg, dist, yaw=0.0, direction=1.0):
        # the base placed so that the obstacle is at ``dist`` and ``bearing_deg`` from its heading ``yaw``
        a = yaw + math.radians(bearing_deg)
        x, y = ox - dist * math.cos(a), oy - dist * math.sin(a)
        return float(stop_cone_clearance(cm, np.array([x]), np.array([y]), np.array([yaw]),
                                         direction=np.array([direction]), radius_m=r)[0])

    for bearing in (0.0, 30.0, -45.0, 58.0):
        assert cone(bearing, 0.33) < 1.0, bearing  # inside the ramp's stop cone (less the margins): flagged
    assert cone(90.0, 0.32) >= 1.0 and cone(-90.0, 0.32) >= 1.0  # beside the base (a door jamb passed): not
    assert cone(0.0, 0.60) >= 1.0  # ahead but far enough
    assert cone(180.0, 0.33) >= 1.0  # behind a base that drives forward
    assert cone(180.0, 0.33, direction=-1.0) < 1.0  # ... is ahead of one that reverses
    assert cone(0.0, 0.33, direction=0.0) == math.inf  # turning on the spot is never stopped by the ramp


def test_does_not_cut_round_a_door_jamb_into_the_stop_cone(make_map, make_room):
    # A wall from the bottom up to y = 2.0 at x = 3.0 (a door jamb); the path turns south round its end. Just
    # past the jamb, heading south-east at 0.35 m/s, the tightest turn towards the path brings the jamb into the
    # ramp's stop cone (an emergency stop in the whole robot); the planner must keep it out.
    data = make_room(80, 120)
    data[:40, 60] = 100
    cm = Costmap(make_map(data, RES))
    path = np.vstack([straight_path(1.5, 2.95, 2.45), np.column_stack([np.full(20, 3.45), np.linspace(2.4, 1.2, 20)])])
    pose = Pose2D(3.2, 2.35, -0.5)

    def chosen_cone(planner):
        plan = planner.compute(pose, Twist(0.35, 0.0), path, (3.45, 1.2), 0.1)
        assert plan.ok
        traj = plan.trajectory
        yaw = np.arctan2(np.diff(traj[:, 1]), np.diff(traj[:, 0]))
        return float(stop_cone_clearance(cm, traj[1:, 0], traj[1:, 1], yaw, direction=np.ones(len(yaw)),
                                           radius_m=0.40).min())

    assert chosen_cone(LocalPlanner(cm)) >= 1.0
    assert chosen_cone(LocalPlanner(cm, LocalPlannerParams(stop_cone_m=1e-3))) < 0.9  # what it did without


def test_bad_params_are_navigation_errors():
    with pytest.raises(NavigationError, match="max_linear_mps"):
        LocalPlannerParams(max_linear_mps=0.0)
    with pytest.raises(NavigationError, match="samples"):
        LocalPlannerParams(angular_samples=1)


def test_speed_is_capped_by_the_motion_pipelines_stop_zone(make_map, make_room):
    """A plan the pipeline would veto is no plan: towards a return just beyond the stop zone the planner only
    turns; with room it may drive, faster the more room there is."""
    params = LocalPlannerParams()
    edge = params.stop_distance_m + params.stop_margin_m
    assert zone_speed_cap(edge, params) < 1e-9 and zone_speed_cap(edge - 0.1, params) == 0.0
    caps = [zone_speed_cap(edge + d, params) for d in (0.02, 0.1, 0.3)]
    assert 1e-3 < caps[0] < caps[1] < caps[2]
    assert zone_speed_cap(math.inf, params) == math.inf
    cm = Costmap(make_map(make_room(), 0.05))
    planner = LocalPlanner(cm, params)
    pose = Pose2D(1.0, 1.5, 0.0)
    path = np.array([[1.0, 1.5], [2.0, 1.5], [3.0, 1.5]])
    free = planner.compute(pose, Twist(0.0, 0.0), path, (3.0, 1.5), 0.1, zone=(math.inf, math.inf))
    assert free.ok and free.twist.linear_mps > 0
    walled = planner.compute(pose, Twist(0.0, 0.0), path, (3.0, 1.5), 0.1, zone=(edge, math.inf))
    assert walled.twist.linear_mps <= 1e-9
    near = planner.compute(pose, Twist(0.3, 0.0), path, (3.0, 1.5), 0.1, zone=(edge + 0.02, math.inf))
    assert 0.0 <= near.twist.linear_mps <= caps[0] + 1e-9


def test_the_compiled_rollouts_and_checks_answer_as_the_numpy_ones(numpy_baselines):
    """`benchmarks/numpy_baselines.py`'s numpy rollouts and safety check against the compiled loops, to the bit: in the
    studio with people in the obstacle layer and their predictions, and on a rotated map of random walls; from poses
    in the open, near walls and inside the inscribed radius (escaping), at random speeds, along the global plan to a
    random goal. The rollouts, which of them are safe, the chosen plan and the evasive move are the same, so a
    seeded run drives as before."""
    from atemr.domain.maps import OccupancyMap
    from atemr.skills.nav.global_planner import GlobalPlanner

    sim = build_simulation("studio", 3)
    rng = np.random.default_rng(3)
    data = np.zeros((80, 100), dtype=np.int8)
    for _ in range(12):  # random walls
        r, c = (int(v) for v in rng.integers(5, 70, 2))
        data[r:r + int(rng.integers(2, 8)), c:c + int(rng.integers(2, 25))] = 100
    grids = (sim.world.map, OccupancyMap(data, RES, Pose2D(-0.7, 0.4, 0.3), name="rotated"))
    cases = {"escaping": 0, "some invalid": 0, "none valid": 0, "moving": 0}
    for grid in grids:
        cm = Costmap(grid)
        ours, before = LocalPlanner(cm), numpy_baselines.NumpyLocalPlanner(cm)
        free = np.argwhere(cm.cost < 100)
        for k in range(60):
            if k % 10 == 0:  # someone walks about: obstacles and predictions change the clearance
                cm.clear_obstacles()
                for r, c in free[rng.integers(0, len(free), 3)]:
                    cm.obstacles[r - 2:r + 2, c - 2:c + 2] = True
                    cm.predicted[r + 2:r + 5, c - 1:c + 1] = True
                cm.version += 1
            r, c = free[rng.integers(0, len(free))]
            x, y = (float(v) for v in grid.cell_to_world(r, c))
            pose = Pose2D(x + float(rng.uniform(-0.02, 0.02)), y + float(rng.uniform(-0.02, 0.02)),
                          float(rng.uniform(-math.pi, math.pi)))
            velocity = Twist(float(rng.uniform(-0.1, 0.5)), float(rng.uniform(-1.2, 1.2)))
            gr, gc = free[rng.integers(0, len(free))]
            goal = tuple(float(v) for v in grid.cell_to_world(gr, gc))
            path = GlobalPlanner(cm).plan((pose.x_m, pose.y_m), goal)
            points = path.points if path is not None else np.array([[pose.x_m, pose.y_m], goal])
            here = float(cm.distance_at(pose.x_m, pose.y_m))
            vs, ws = ours.targets(velocity, 0.5, reverse=here < cm.params.inscribed_radius_m)
            rolled = ours._rollout(pose, velocity, vs, ws, ours.params.sim_time_s)
            for a, b in zip(rolled, before._rollout(pose, velocity, vs, ws, ours.params.sim_time_s), strict=True):
                assert a.tobytes() == b.tobytes()
            valid = ours._valid(pose, *rolled, vs=vs, clearance_here=here)
            np.testing.assert_array_equal(valid, before._valid(pose, *rolled, vs=vs, clearance_here=here))
            plan, plan_before = ours.compute(pose, velocity, points, goal), before.compute(pose, velocity, points, goal)
            assert plan.twist == plan_before.twist and (plan.ok, plan.candidates, plan.valid) == (
                plan_before.ok, plan_before.candidates, plan_before.valid)
            assert plan.trajectory.tobytes() == plan_before.trajectory.tobytes()
            assert ours.evade(pose, velocity) == before.evade(pose, velocity)
            cases["escaping"] += here < cm.params.inscribed_radius_m
            cases["some invalid"] += 0 < valid.sum() < len(valid)
            cases["none valid"] += not valid.any()
            cases["moving"] += plan.twist.linear_mps != 0.0
    assert min(cases.values()) >= 5, cases  # every branch was met, or the comparison proves little
