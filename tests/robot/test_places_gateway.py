"""The dashboard's place commands on the whole simulated robot (issue 27): every change is checked (name,
pose on the map, duplicates, a map being built) before it is stored with the map, a refused one changes
nothing, and "Go to" drives the robot to the place."""

from __future__ import annotations

import math

from atemr.io.map_store import MapStore
from atemr.msgs import Pose2D
from atemr.ui.state import state_problems

from .test_gateway import agent_state, booted, run  # noqa: F401  (booted is a fixture)

ROOMS = ["home", "living room", "kitchen", "bedroom", "bathroom", "balcony door"]


def test_places_are_added_moved_renamed_and_deleted_and_stored_with_the_map(booted):  # noqa: F811
    robot, gateway = booted
    store = MapStore(robot.config.data_dir)
    state = gateway.state()
    assert not state_problems(state)
    assert [p["name"] for p in state["places"]] == ROOMS and state["places"][0]["kind"] == "dock"

    assert gateway.save_place("front door", Pose2D(0.5, 6.5, 1.0)).ok
    assert store.places("studio")["front door"].pose == Pose2D(0.5, 6.5, 1.0)  # stored at once
    refusals = {
        "duplicate": gateway.save_place("Front  Door", Pose2D(1.0, 1.0, 0.0)),
        "outside": gateway.save_place("garden", Pose2D(40.0, 1.0, 0.0)),
        "wall": gateway.save_place("in the wall", Pose2D(5.55, 3.0, 0.0)),
        "name": gateway.save_place("<b>", Pose2D(1.0, 1.0, 0.0)),
        "kind": gateway.save_place("sofa", Pose2D(1.0, 1.0, 0.0), "bed"),
        "unknown": gateway.save_place("hall", Pose2D(1.0, 1.0, 0.0), previous="hal"),
        "delete": gateway.delete_place("garage"),
    }
    assert not any(r.ok for r in refusals.values())
    assert "exists already" in refusals["duplicate"].reason
    assert "outside the map studio" in refusals["outside"].reason
    assert "in an obstacle" in refusals["wall"].reason
    assert "invalid place name" in refusals["name"].reason
    assert "kind is one of place, dock" in refusals["kind"].reason
    assert "no place named 'hal'" in refusals["unknown"].reason
    assert "no place named 'garage'" in refusals["delete"].reason
    assert list(store.places("studio")) == [*ROOMS, "front door"]  # nothing changed by a refusal

    assert gateway.save_place("hall door", Pose2D(0.6, 6.4, 0.0), previous="front door").ok  # moved and renamed
    assert gateway.delete_place("BEDROOM").ok
    run(robot, 0.2)
    names = [p["name"] for p in gateway.state()["places"]]
    assert names == ["home", "living room", "kitchen", "bathroom", "balcony door", "hall door"]
    assert list(MapStore(robot.config.data_dir).places("studio")) == names  # what a restart reads


def test_go_to_a_place_drives_the_robot_there(booted):  # noqa: F811
    robot, gateway = booted
    assert gateway.go_to_place("kitchen").reason == "switch to AUTO first"
    assert "closest: kitchen" in gateway.go_to_place("kichen").reason
    assert gateway.set_mode("AUTO").ok
    for _ in range(50):
        run(robot, 0.1)
        if agent_state(robot) == "IDLE.AUTO":
            break
    assert gateway.go_to_place("balcony door").ok
    run(robot, 0.3)
    assert agent_state(robot) == "EXEC"
    goal = robot.parts.navigation.goal
    for _ in range(600):
        run(robot, 0.1)
        if agent_state(robot) == "IDLE.AUTO":
            break
    assert goal == Pose2D(4.25, 1.9, -1.571)
    truth = robot.parts.sim.pose
    assert math.hypot(truth.x_m - 4.25, truth.y_m - 1.9) < 0.3, truth
    assert any(e["text"] == "going to balcony door" for e in gateway.state()["events"])
