"""Closed loop: the Navigator drives the simulator's base (RMD wheel models, wheel slip) with the
ground-truth pose and the simulated lidar, on a simulated clock. Seeded, deterministic."""

import math

import pytest

from atemr.io.sim.simulation import build_simulation
from atemr.msgs import Pose2D
from atemr.skills.nav.navigator import Navigator, NavParams

DOORWAY = (5.575, 1.4)  # the living room | bedroom doorway of the studio (x 5.5..5.65, y 1.0..1.8)


def within_tolerance(pose: Pose2D, goal: Pose2D) -> bool:
    return pose.distance_to(goal) <= 0.25 and abs(math.remainder(pose.yaw_rad - goal.yaw_rad, 2 * math.pi)) <= 0.13


def test_studio_living_room_to_bedroom(closed_loop):
    sim = build_simulation("studio", 11)  # starts in the living room, (2.6, 2.6)
    goal = Pose2D(6.3, 0.8, -math.pi / 2)  # the bedroom, beside the bed
    nav = Navigator(sim.world.map)
    run = closed_loop(sim, nav, goal, max_s=60.0)
    assert run.status.state == "SUCCEEDED", (run.status, nav.events)
    assert within_tolerance(sim.pose, goal)
    assert run.collisions == []
    assert run.t_end <= 30.0
    assert not [e for e in nav.events if e.kind == "recovery"]


def test_studio_person_in_the_doorway_then_stepping_aside(closed_loop):
    """A person stands in the only doorway to the bedroom: no path, the robot waits and runs recoveries,
    plans again when the person has gone, and arrives."""
    sim = build_simulation("studio", 12)
    person = sim.drop_obstacle(*DOORWAY, size_m=0.44, shape="circle", name="person", height_m=1.7)

    gone = []

    def step_aside(now, s):
        if now >= 15.0 and not gone:
            s.remove_obstacle(person)
            gone.append(now)

    goal = Pose2D(6.3, 0.8, 0.0)
    nav = Navigator(sim.world.map, NavParams(path_wait_s=4.0))
    run = closed_loop(sim, nav, goal, max_s=60.0, on_tick=step_aside)
    kinds = [e.kind for e in nav.events]
    assert "no path" in kinds
    assert "recovery" in kinds
    assert kinds.index("no path") < kinds.index("replan") < kinds.index("succeeded")
    assert run.status.state == "SUCCEEDED"
    assert within_tolerance(sim.pose, goal)
    assert run.collisions == []


def test_studio_doorway_blocked_for_good_fails_with_no_path(closed_loop):
    sim = build_simulation("studio", 13)
    sim.drop_obstacle(*DOORWAY, size_m=0.44, shape="circle", name="person", height_m=1.7)
    nav = Navigator(sim.world.map, NavParams(path_wait_s=2.0))
    run = closed_loop(sim, nav, Pose2D(6.3, 0.8, 0.0), max_s=90.0)
    assert run.status.state == "FAILED"
    assert run.status.reason == "no path"
    recoveries = [e.detail for e in nav.events if e.kind == "recovery"]
    assert [r.split(" (")[0] for r in recoveries] == ["clear costmap", "rotate in place", "back off", "replan"]
    assert run.collisions == []
    assert run.statuses[-1].twist.is_zero


def test_studio_doorway_blocked_past_the_recoveries_waits_for_the_way_to_clear(closed_loop):
    """The person stays in the doorway through every recovery: the map has a path, so the robot waits (up to
    ``obstacle_wait_s``) instead of failing, and goes on when she leaves."""
    sim = build_simulation("studio", 13)
    person = sim.drop_obstacle(*DOORWAY, size_m=0.44, shape="circle", name="person", height_m=1.7)
    nav = Navigator(sim.world.map, NavParams(path_wait_s=2.0, obstacle_wait_s=60.0))
    left: list[float] = []

    def leave_after_the_recoveries(now, s):
        waiting = [e.t for e in nav.events if e.kind == "waiting" and "not in the map" in e.detail]
        if waiting and now >= waiting[0] + 10.0 and not left:
            s.remove_obstacle(person)
            left.append(now)

    run = closed_loop(sim, nav, Pose2D(6.3, 0.8, 0.0), max_s=150.0, on_tick=leave_after_the_recoveries)
    recoveries = [e.detail.split(" (")[0] for e in nav.events if e.kind == "recovery"]
    assert recoveries == ["clear costmap", "rotate in place", "back off", "replan"]
    assert left, [(e.t, e.kind) for e in nav.events]
    assert run.status.state == "SUCCEEDED", run.status
    assert run.collisions == []


def test_studio_crossing_the_carers_walk(closed_loop):
    """The carer walks to and fro across the living room; the robot crosses her line to the kitchen."""
    sim = build_simulation("studio", 14)
    goal = Pose2D(3.6, 5.6, math.pi)
    nav = Navigator(sim.world.map)
    run = closed_loop(sim, nav, goal, max_s=90.0)
    assert run.status.state == "SUCCEEDED"
    assert within_tolerance(sim.pose, goal)
    # No contact at all: the tracker sees her walking and the robot waits for her to pass instead of standing
    # in her way (the simulator's people stop only when they touch the robot).
    assert run.collisions == []


@pytest.mark.parametrize(("name", "start", "goal"), [
    ("nav2_depot", Pose2D(23.0, 7.8, 0.0), Pose2D(15.5, 9.5, 1.0)),
    ("turtlebot3_world", Pose2D(0.28, -1.47, 0.0), Pose2D(1.73, 1.38, 0.0)),
])
def test_external_maps(closed_loop, shared_dir, name, start, goal):
    path = shared_dir / "worlds" / "external" / f"{name}.yaml"
    if not path.is_file():
        pytest.skip(f"{path} is missing")
    sim = build_simulation(path, 3)
    sim.kidnap(start)
    nav = Navigator(sim.world.map)
    run = closed_loop(sim, nav, goal, max_s=120.0)
    assert run.status.state == "SUCCEEDED", (run.status, nav.events)
    assert within_tolerance(sim.pose, goal)
    assert run.collisions == []
