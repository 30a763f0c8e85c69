"""Mission files: the shipped examples, the compiled trees, and each validation error with its position."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from atemr.domain.places import Place, Places
from atemr.errors import ConfigError
from atemr.io.map_store import MapStore
from atemr.io.sim.world import load_world
from atemr.msgs import Pose2D
from atemr.trees.behaviours import behaviours
from atemr.trees.missions import Mission, load_mission, parse_mission
from atemr.yamlsafe import load_yaml

MISSIONS = sorted((Path(__file__).resolve().parents[2] / "trees" / "missions").glob("*.yaml"))
IN_A_WORLD = [p for p in MISSIONS if load_mission(p).world is not None]


def parse(text: str) -> Mission:
    return parse_mission(load_yaml("m.yaml", text=text), "m.yaml")


def test_at_least_three_missions_ship_for_the_default_world() -> None:
    worlds = [load_mission(p).world for p in MISSIONS]
    assert worlds.count("studio") >= 3


@pytest.mark.parametrize("path", IN_A_WORLD, ids=[p.stem for p in IN_A_WORLD])
def test_shipped_mission_poses_are_in_free_space_with_clearance(path: Path, tmp_path: Path) -> None:
    mission = load_mission(path)
    assert mission.world is not None
    world = load_world(mission.world)
    grid = world.map
    rows, cols = np.mgrid[0:grid.data.shape[0], 0:grid.data.shape[1]]
    x_m, y_m = grid.cell_to_world(rows, cols)
    occupied = grid.occupied.copy()
    for thing in world.furniture:  # the unmapped ones too (laundry basket, plant): navigation pads those
        occupied |= thing.contains(x_m, y_m)
    clearance_m = ndimage.distance_transform_edt(~occupied) * grid.resolution_m
    places = MapStore(tmp_path).places(mission.world)
    mission.check_places(places, mission.world)
    poses = [n.options for n in mission.spec.walk() if n.type == "GoToPose"]
    poses += [places[n.options.place].pose for n in mission.spec.walk() if n.type == "GoToPlace"]
    assert poses
    for pose in poses:
        row, col = grid.world_to_cell(pose.x_m, pose.y_m)
        assert grid.free[row, col], (pose, "not free")
        assert clearance_m[row, col] >= 0.5, (pose, "too close to an obstacle for the robot")


def test_every_shipped_mission_has_its_behaviours_and_a_missing_one_is_reported(
        monkeypatch: pytest.MonkeyPatch) -> None:
    assert all(load_mission(p).report()["runnable"] for p in MISSIONS)
    monkeypatch.delitem(behaviours._items, "GoToPose")
    kitchen = load_mission(MISSIONS[0].parent / "kitchen-check.yaml").report()
    assert kitchen["name"] == "kitchen-check"
    assert kitchen["runnable"] is False and kitchen["missing_behaviours"] == ["GoToPose"]
    assert [s["runnable"] for s in kitchen["steps"]] == [False, True, True, True, True, False]


def test_compiled_tree_wraps_steps_in_timeout_and_retry() -> None:
    mission = parse("""
mission:
  name: t
  home: {x_m: 0, y_m: 0}
  defaults: {timeout_s: 30}
  steps:
    - go_to: {x_m: 1, y_m: 2, yaw_rad: 0.5}
      retries: 2
    - patrol: {waypoints: [{x_m: 1, y_m: 1}, {x_m: 2, y_m: 2}], loops: 0}
    - wait: {duration_s: 1}
      timeout_s: 5
    - return_home: {}
    - relocalize: {timeout_s: 10}
""")
    first, patrol, wait, home, relocalize = mission.spec.children
    assert relocalize.children[0].type == "Relocalize" and relocalize.children[0].options.timeout_s == 10.0
    assert (first.type, first.options.num_failures) == ("Retry", 3)
    assert (first.children[0].type, first.children[0].options.duration_s) == ("Timeout", 30.0)
    assert first.children[0].children[0].options.pose().y_m == 2.0
    repeat = patrol.children[0]
    assert (repeat.type, repeat.options.num_success) == ("Repeat", -1)
    assert [c.options.x_m for c in repeat.children[0].children] == [1.0, 2.0]
    assert wait.options.duration_s == 5.0 and wait.children[0].options.duration_s == 1.0
    assert home.children[0].options.x_m == 0.0
    assert [s.line for s in mission.steps] == [7, 9, 10, 12, 13]


BAD = [
    ("unknown kind", "    - goto: {x_m: 1, y_m: 2}\n", "goto", ["unknown step kind 'goto'", "'go_to'"]),
    ("two kinds", "    - {wait: {duration_s: 1}, rotate: {angle_rad: 1}}\n", "{wait", ["exactly one kind"]),
    ("missing parameter", "    - go_to: {x_m: 1}\n", "{x_m", ["missing required parameter: y_m"]),
    ("bad parameter", "    - wait: {duration_s: -2}\n", "-2", ["must be at least 0"]),
    ("unknown parameter", "    - wait: {duration_s: 2, speed: 1}\n", "speed", ["unknown key 'speed'"]),
    ("return home without home", "    - return_home: {}\n", "return_home", ["needs the mission's 'home'"]),
    ("bad loops", "    - patrol: {waypoints: [{x_m: 1, y_m: 1}], loops: -1}\n", "-1", ["'loops' must be"]),
    ("bad waypoint", "    - visit: {waypoints: [{x_m: 1, y_m: 1}, 7]}\n", "7", ["a pose is a mapping"]),
    ("bad timeout", "    - wait: {duration_s: 1}\n      timeout_s: 0\n", "0\n", ["must be at least 0.1"]),
    ("bad label", "    - capture_image: {label: ../../etc}\n", "{label", ["label must be"]),
    ("place and pose", "    - go_to: {place: kitchen, x_m: 1}\n", "x_m", ["unknown key 'x_m'"]),
    ("bad place name", "    - go_to: {place: '<kitchen>'}\n", "{place", ["invalid place name"]),
    ("bad place waypoint", "    - visit: {waypoints: [kitchen, 7]}\n", "7", ["or a place {place: name}"]),
]


@pytest.mark.parametrize(("kind", "step", "at", "words"), BAD, ids=[b[0] for b in BAD])
def test_mission_errors_point_at_the_step(kind: str, step: str, at: str, words: list[str]) -> None:
    text = "mission:\n  name: bad\n  steps:\n    - wait: {duration_s: 1}\n" + step
    with pytest.raises(ConfigError) as info:
        parse(text)
    index = text.index(at, text.index(step))
    line = text.count("\n", 0, index) + 1
    column = index - (text.rfind("\n", 0, index) + 1) + 1
    assert (info.value.file, info.value.line, info.value.column) == ("m.yaml", line, column), str(info.value)
    assert info.value.path and info.value.path.startswith("mission.steps[1]")
    for word in words:
        assert word in info.value.reason


@pytest.mark.parametrize(("text", "words"), [
    ("steps: []\n", ["one top-level key, 'mission'"]),
    ("mission:\n  name: x\n  step: []\n", ["unknown key 'step'", "'steps'"]),
    ("mission:\n  name: x\n  steps: []\n", ["'steps' must be a non-empty list"]),
    ("mission:\n  steps: [{wait: {duration_s: 1}}]\n", ["needs a non-empty 'name'"]),
])
def test_mission_document_errors(text: str, words: list[str]) -> None:
    with pytest.raises(ConfigError) as info:
        parse(text)
    for word in words:
        assert word in str(info.value)


PLACES_MISSION = """mission:
  name: by-name
  home: {place: Home}
  steps:
    - wait: {duration_s: 1}
    - go_to: {place: kitchen}
    - patrol: {waypoints: [bedroom, {place: bathroom}, {x_m: 1, y_m: 2}], loops: 2}
    - return_home: {}
"""


def test_missions_name_places_and_a_missing_one_is_refused_with_the_closest_names() -> None:
    mission = parse(PLACES_MISSION)
    assert mission.place_names() == ["kitchen", "bedroom", "bathroom", "Home"]
    assert [s.behaviours for s in mission.steps] == [("Wait",), ("GoToPlace",), ("GoToPlace", "GoToPose"),
                                                     ("GoToPlace",)]
    assert mission.report()["places"] == ["kitchen", "bedroom", "bathroom", "Home"]
    patrol = [n for n in mission.steps[2].spec.walk() if n.type in ("GoToPlace", "GoToPose")]
    assert [n.name for n in patrol] == ["step 2: patrol: loop: bedroom", "step 2: patrol: loop: bathroom",
                                        "step 2: patrol: loop: waypoint 2"]
    here = Places([Place(n, Pose2D(1, 1, 0)) for n in ("home", "kitchen", "bedroom", "bathroom")])
    mission.check_places(here)  # names are matched whatever their case
    with pytest.raises(ConfigError) as info:
        mission.check_places(here.without("bedroom").with_place(Place("bedroom 2", Pose2D(0, 0, 0))), "map flat")
    assert info.value.reason == ("mission 'by-name' step 2: no place named 'bedroom' on map flat "
                                 "(closest: bedroom 2, bathroom)")
    assert (info.value.file, info.value.line) == ("m.yaml", 7)


def test_missing_behaviours_are_reported_not_hidden(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(behaviours._items, "GoToPose")
    mission = parse("mission:\n  name: x\n  steps:\n    - go_to: {x_m: 1, y_m: 1}\n    - wait: {duration_s: 1}\n")
    assert mission.missing_behaviours() == ["GoToPose"]
    assert np.array_equal([s["runnable"] for s in mission.report()["steps"]], [False, True])


def test_progress_reports_distance_left_and_errors() -> None:
    import py_trees

    from atemr.msgs import Pose2D
    from atemr.trees.progress import TaskProgress

    mission = parse("mission:\n  name: p\n  steps:\n    - go_to: {x_m: 3, y_m: 4, yaw_rad: 1.0}\n"
                    "    - wait: {duration_s: 1}\n")
    first, second = py_trees.behaviours.Running("go"), py_trees.behaviours.Success("wait")
    root = py_trees.composites.Sequence("p", True, [first, second])
    progress = TaskProgress(mission, root, 0.0)
    root.tick_once()
    progress.update(0.1, Pose2D(0, 0, 0))
    step = progress.steps[0]
    assert (step.status, step.started_s, step.distance_left_m) == ("running", 0.1, 5.0)
    progress.finish("cancelled", 0.5, Pose2D(3, 3.9, 1.2))
    report = progress.report()
    assert report["outcome"] == "cancelled" and report["duration_s"] == 0.5
    assert report["steps"][0]["status"] == "interrupted"
    assert report["steps"][0]["position_error_m"] == pytest.approx(0.1)
    assert report["steps"][0]["heading_error_rad"] == pytest.approx(0.2)
    assert report["steps"][1]["status"] == "not run"
