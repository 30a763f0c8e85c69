"""3-D obstacles on the whole simulated robot (issue 24), through ``atemr mission run --headless``.

Each world puts something the lidar's plane (0.2 m) does not show between the start and the goal: a table on
legs whose top is at 0.72 m, a wall cabinet hanging into a corridor from 0.9 m, a shoe 0.1 m tall. With the
depth layer off (``nav.depth_layer: false``) the robot drives as if they were not there and the simulator
reports the collision, naming the object and the part of the robot that hit it: that is what proves each test
can fail. With the layer on, the D415 sees them, the robot goes round and reaches the goal untouched. Judged
from the simulator's ground truth (collisions, the true final pose), never from the robot's own estimate.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from atemr.cli.main import main

pytestmark = pytest.mark.slow

#: The navigator's goal tolerance.
TOLERANCE_M = 0.25

TABLE = """
  - {name: table, box: [3.5, 1.7, 4.4, 3.3], clearance_m: 0.72, height_m: 0.76}
  - {name: table leg, box: [3.5, 1.7, 3.56, 1.76], height_m: 0.72}
  - {name: table leg, box: [4.34, 1.7, 4.4, 1.76], height_m: 0.72}
  - {name: table leg, box: [3.5, 3.24, 3.56, 3.3], height_m: 0.72}
  - {name: table leg, box: [4.34, 3.24, 4.4, 3.3], height_m: 0.72}
"""
#: A wall cabinet over the corridor's north side: 0.75 m deep, from 0.9 m to 1.1 m (the tablet's height).
CABINET = "\n  - {name: wall cabinet, box: [2.5, 1.05, 3.5, 1.8], clearance_m: 0.9, height_m: 1.1}\n"
SHOE = "\n  - {name: shoe, box: [3.85, 2.35, 4.15, 2.65], height_m: 0.1}\n"


def walled_map(directory: Path, name: str, width_m: float, height_m: float) -> str:
    """A walled empty room (10 cm walls, 5 cm cells, origin at its corner) in the map_server format."""
    res = 0.05
    pixels = np.full((round(height_m / res), round(width_m / res)), 254, dtype=np.uint8)
    pixels[:2, :] = pixels[-2:, :] = pixels[:, :2] = pixels[:, -2:] = 0
    Image.fromarray(pixels).save(directory / f"{name}.pgm", format="PPM")
    (directory / f"{name}.yaml").write_text(f"image: {name}.pgm\nresolution: {res}\norigin: [0.0, 0.0, 0.0]\n"
                                            "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return f"{name}.yaml"


def scenario(tmp_path: Path, kind: str) -> tuple[Path, tuple[float, float, float], tuple[float, float, float]]:
    """(world file, start, goal): the 8 m x 5 m hall with the table or the shoe, or the 1.7 m corridor."""
    if kind == "cabinet":
        room, start, goal, items = walled_map(tmp_path, "corridor", 6.4, 1.9), (0.7, 0.95, 0.0), (5.7, 0.95, 0.0), \
            CABINET
    else:
        room, start, goal, items = walled_map(tmp_path, "hall", 8.0, 5.0), (1.0, 2.5, 0.0), (7.0, 2.5, 0.0), \
            TABLE if kind == "table" else SHOE
    world = tmp_path / f"{kind}.yaml"
    world.write_text(f"name: {kind}\nmap: {room}\nstart: [{start[0]}, {start[1]}, {start[2]}]\nfurniture:{items}")
    return world, start, goal


def run(tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, kind: str,
        depth_layer: bool, timeout_s: float = 90.0) -> tuple[dict, tuple[float, float, float]]:
    world, _, goal = scenario(tmp_path, kind)
    monkeypatch.setenv("ATEMR_SIM__CAMERA_HZ", "0")  # the colour camera plays no part
    monkeypatch.setenv("ATEMR_NAV__DEPTH_LAYER", "true" if depth_layer else "false")
    main(["--log-level", "ERROR", "mission", "run", "--headless", "--json", "--data-dir", str(tmp_path / "data"),
          "--world", str(world), "--seed", "1", "--goal", ",".join(map(str, goal)), "--timeout", str(timeout_s)])
    result: dict = json.loads(capsys.readouterr().out)
    return result, goal


def at_goal(result: dict, goal: tuple[float, float, float]) -> bool:
    truth = result["true_pose"]
    return math.hypot(truth["x_m"] - goal[0], truth["y_m"] - goal[1]) <= TOLERANCE_M


@pytest.mark.parametrize(("kind", "what", "part"), [
    ("table", "table", "mast"),  # the base passes between the legs and under the top; the mast does not
    ("cabinet", "wall cabinet", "tablet"),  # the corridor's middle passes under the cabinet's edge
    ("shoe", "shoe", "base"),  # under the lidar's plane, in the way
])
def test_without_the_depth_layer_the_robot_hits_what_the_lidar_cannot_see(tmp_path, capsys, monkeypatch, kind,
                                                                         what, part):
    # 30 s of robot time: the obstacle stands 3 m or less ahead, hit within about 10 s; the robot then presses on
    # against it to the timeout, which proves nothing more
    result, goal = run(tmp_path, capsys, monkeypatch, kind, depth_layer=False, timeout_s=30.0)
    assert result["collisions"] >= 1
    assert {(c["what"], c["part"]) for c in result["collision_list"]} == {(what, part)}
    assert not at_goal(result, goal)


@pytest.mark.parametrize("kind", ["table", "cabinet", "shoe"])
def test_with_the_depth_layer_the_robot_goes_round_and_reaches_the_goal(tmp_path, capsys, monkeypatch, kind):
    result, goal = run(tmp_path, capsys, monkeypatch, kind, depth_layer=True)
    assert result["collisions"] == 0, result["collision_list"]
    assert result["outcome"] == "reached"
    assert at_goal(result, goal), result["true_pose"]
