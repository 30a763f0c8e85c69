"""The Navigator on small hand-made grids with a kinematic robot (the pose follows the command exactly)."""

import itertools
import math

import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.io.sim.base import integrate_arc
from atemr.msgs import Pose2D
from atemr.skills.nav.navigator import Navigator, NavParams, Phase
from atemr.skills.nav.recovery import DEFAULT_SEQUENCE

RES = 0.05
DT = 0.1


def two_rooms(make_map, blocked=False):
    """Two 2 m rooms joined by a 1 m doorway at x = 2.5 m; ``blocked`` walls the doorway up."""
    data = np.zeros((60, 100), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[:, 48:52] = 100
    data[20:40, 48:52] = 100 if blocked else 0
    return make_map(data, RES)


def run(nav, pose, seconds, *, localized=lambda t: True, t0=0.0):
    statuses = []
    t = t0
    for _ in range(round(seconds / DT)):
        status = nav.update(t, pose, None, localized(t))
        statuses.append(status)
        if status.state != "RUNNING":
            break
        pose = integrate_arc(pose, status.twist.linear_mps, status.twist.angular_radps, DT)
        t += DT
    return pose, statuses


def test_reaches_the_goal_in_the_other_room_within_tolerance(make_map):
    nav = Navigator(two_rooms(make_map))
    goal = Pose2D(4.0, 1.5, math.pi / 2)
    nav.start(goal, 0.0)
    pose, statuses = run(nav, Pose2D(0.8, 0.8, 0.0), 60.0)
    final = statuses[-1]
    assert final.state == "SUCCEEDED", final
    assert pose.distance_to(goal) <= 0.25
    assert abs(math.remainder(pose.yaw_rad - goal.yaw_rad, 2 * math.pi)) <= 0.13
    running = [s for s in statuses if s.state == "RUNNING"]
    assert running[0].global_path.shape[1] == 2 and len(running[0].global_path) > 10
    left = [s.distance_left_m for s in running if s.phase == "following the path"]
    assert left[0] > 3.0 and left[-1] < 0.5
    assert all(np.isfinite(s.eta_s) for s in running if s.phase == "following the path")
    assert max(abs(s.twist.linear_mps) for s in statuses) <= nav.params.local.max_linear_mps + 1e-9
    kinds = [e.kind for e in nav.events]
    assert kinds[:2] == ["goal", "plan"] and kinds[-1] == "succeeded"
    assert "recovery" not in kinds


def test_no_path_runs_every_recovery_in_order_then_fails(make_map):
    nav = Navigator(two_rooms(make_map, blocked=True))
    nav.start(Pose2D(4.0, 1.5, 0.0), 0.0)  # a valid goal (free space) that no path reaches
    _, statuses = run(nav, Pose2D(0.8, 1.5, 0.0), 120.0)
    final = statuses[-1]
    assert final.state == "FAILED" and final.reason == "no path"
    assert "no path to the goal after recoveries" in final.message
    recoveries = [e.detail.split(" (")[0] for e in nav.events if e.kind == "recovery"]
    assert recoveries == list(DEFAULT_SEQUENCE)
    assert final.twist.is_zero
    # Finished: further updates keep answering FAILED with a zero twist.
    again = nav.update(200.0, Pose2D(0.8, 1.5, 0.0))
    assert again.state == "FAILED" and again.twist.is_zero


def test_a_robot_that_does_not_move_is_stuck_runs_every_recovery_then_fails(make_map):
    """The wheels turn but the robot stays put (caught on a rug): the progress watchdog calls it stuck, the
    recoveries are tried in order (none moves it either), then the goal fails with the reason "stuck"."""
    nav = Navigator(two_rooms(make_map))
    nav.start(Pose2D(4.0, 1.5, 0.0), 0.0)
    stay = Pose2D(0.8, 0.8, 0.0)
    statuses = []
    for k in range(3000):
        statuses.append(nav.update(k * DT, stay))
        if statuses[-1].state != "RUNNING":
            break
    final = statuses[-1]
    assert final.state == "FAILED" and final.reason == "stuck", final
    assert "stuck" in final.message and final.twist.is_zero
    assert any(not s.twist.is_zero for s in statuses), "it did try to drive"
    recoveries = [e.detail.split(" (")[0] for e in nav.events if e.kind == "recovery"]
    assert recoveries == list(DEFAULT_SEQUENCE)
    first = next(e for e in nav.events if e.kind == "recovery")
    assert first.t >= nav.params.stuck_timeout_s


def test_a_short_loss_of_localization_pauses_a_long_one_fails(make_map):
    nav = Navigator(two_rooms(make_map), NavParams(localization_timeout_s=3.0))
    nav.start(Pose2D(4.0, 1.5, 0.0), 0.0)
    # Lost between 1 s and 2.5 s: stops, then goes on and arrives.
    _, statuses = run(nav, Pose2D(0.8, 0.8, 0.0), 60.0, localized=lambda t: not 1.0 <= t < 2.5)
    waiting = [s for s in statuses if s.phase == "waiting for localization"]
    assert waiting and all(s.twist.is_zero for s in waiting)
    assert statuses[-1].state == "SUCCEEDED"
    # Lost for good.
    nav.start(Pose2D(4.0, 1.5, 0.0), 100.0)
    _, statuses = run(nav, Pose2D(0.8, 0.8, 0.0), 20.0, localized=lambda t: t < 101.0, t0=100.0)
    assert statuses[-1].state == "FAILED" and statuses[-1].reason == "localization lost"


def test_timeout_and_cancel(make_map):
    nav = Navigator(two_rooms(make_map), NavParams(timeout_s=2.0))
    nav.start(Pose2D(4.0, 1.5, 0.0), 0.0)
    _, statuses = run(nav, Pose2D(0.8, 0.8, 0.0), 10.0)
    assert statuses[-1].state == "FAILED" and statuses[-1].reason == "timeout"
    nav = Navigator(two_rooms(make_map))
    nav.start(Pose2D(4.0, 1.5, 0.0), 0.0)
    run(nav, Pose2D(0.8, 0.8, 0.0), 1.0)
    assert nav.cancel(1.0).state == "CANCELED"
    status = nav.update(1.1, Pose2D(0.9, 0.8, 0.0))
    assert status.state == "CANCELED" and status.twist.is_zero


def test_non_finite_pose_counts_as_not_localized(make_map):
    nav = Navigator(two_rooms(make_map))
    nav.start(Pose2D(4.0, 1.5, 0.0), 0.0)
    status = nav.update(0.0, Pose2D(float("nan"), 0.8, 0.0))
    assert status.state == "RUNNING" and status.twist.is_zero and status.phase == "waiting for localization"


def phases_of(nav, pose, seconds, *, localized=lambda k: True, push=None):
    """The phases the navigator goes through (each once per spell) and its last status; ``push(k, pose)`` may
    move the robot before tick ``k``."""
    phases, status = [], None
    for k in range(round(seconds / DT)):
        if push is not None:
            pose = push(k, pose)
        status = nav.update(k * DT, pose, None, localized(k))
        phases.append(nav.phase)
        if status.state != "RUNNING":
            break
        pose = integrate_arc(pose, status.twist.linear_mps, status.twist.angular_radps, DT)
    return [phase for phase, _ in itertools.groupby(phases)], status


def test_phases_of_a_goal_no_path_reaches(make_map):
    nav = Navigator(two_rooms(make_map, blocked=True))
    nav.start(Pose2D(4.0, 1.5, 0.0), 0.0)
    phases, status = phases_of(nav, Pose2D(0.8, 1.5, 0.0), 120.0)
    assert phases == [Phase.NO_PATH, Phase.RECOVERING] * len(DEFAULT_SEQUENCE) + [Phase.NO_PATH]
    assert status.state == "FAILED"


def test_lost_while_turning_turns_on_when_localized_again(make_map):
    nav = Navigator(two_rooms(make_map))
    nav.start(Pose2D(1.0, 1.5, math.pi / 2), 0.0)
    phases, status = phases_of(nav, Pose2D(1.0, 1.5, 0.0), 10.0, localized=lambda k: not 3 <= k < 6)
    assert phases == [Phase.TURNING, Phase.LOST, Phase.TURNING]
    assert status.state == "SUCCEEDED"


def test_pushed_off_the_goal_while_turning_drives_back(make_map):
    nav = Navigator(two_rooms(make_map))
    goal = Pose2D(1.0, 1.5, math.pi / 2)
    nav.start(goal, 0.0)
    phases, status = phases_of(nav, Pose2D(1.0, 1.5, 0.0), 30.0,
                               push=lambda k, pose: Pose2D(1.6, 1.5, pose.yaw_rad) if k == 3 else pose)
    assert phases[:3] == [Phase.TURNING, Phase.FOLLOWING, Phase.TURNING]
    assert [e.kind for e in nav.events].count("position lost") == 1
    assert status.state == "SUCCEEDED"


def test_params_are_checked():
    with pytest.raises(NavigationError, match="xy_tolerance_m"):
        NavParams(xy_tolerance_m=-1.0)
    with pytest.raises(NavigationError, match="arrive_m"):
        NavParams(arrive_m=0.5)
