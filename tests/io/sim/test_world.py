"""World files: the shipped studio, plain maps as worlds, and clear errors for bad world files."""

import filecmp

import numpy as np
import pytest

from atemr.errors import ConfigError
from atemr.io.sim.world import load_world, shipped_world_names
from atemr.worlds.make_studio import build_studio_map
from atemr.worlds.make_studio import main as make_studio


def test_studio_is_shipped_and_complete():
    assert "studio" in shipped_world_names()
    w = load_world("studio")
    assert w.name == "studio"
    assert w.map.resolution_m == 0.05
    names = {f.name for f in w.furniture}
    assert {"sofa", "dining table", "bed"} <= names
    assert any(not f.mapped for f in w.furniture), "some furniture must be missing from the map"
    assert [z.name for z in w.drop_zones] == ["balcony edge"]
    assert {m.kind for m in w.movers} == {"person", "pet"}
    # the robot starts in the living room (x < 5.5, y < 4.6) on free floor
    assert 0 < w.start.x_m < 5.5 and 0 < w.start.y_m < 4.6
    assert w.map.value_at(w.start.x_m, w.start.y_m) == 0


def test_studio_doorways_are_about_80_cm():
    m = load_world("studio").map
    # along the living room | bedroom wall (x = 5.5..5.65) the gap in y is the doorway
    col = m.world_to_cell(5.57, 0.0)[1]
    column = m.occupied[:, col]
    ys = m.cell_to_world(np.arange(m.height), col)[1]
    inside = (ys > 0.0) & (ys < 4.5)
    gap = np.count_nonzero(~column[inside]) * m.resolution_m
    assert gap == pytest.approx(0.8, abs=0.051)


def test_shipped_studio_map_is_what_the_script_generates(tmp_path):
    assert make_studio(["--out", str(tmp_path)]) == 0
    shipped = load_world("studio").source.parent
    assert filecmp.cmp(tmp_path / "studio.pgm", shipped / "studio.pgm", shallow=False)
    assert filecmp.cmp(tmp_path / "studio.yaml", shipped / "studio.yaml", shallow=False)
    assert build_studio_map().data.shape == (190, 200)


def test_a_plain_map_is_a_world_with_a_free_start(shared_dir):
    path = shared_dir / "worlds" / "external" / "turtlebot3_world.yaml"
    if not path.is_file():
        pytest.skip(f"{path} is not there")
    w = load_world(path)
    assert w.furniture == () and w.movers == ()
    row, col = w.map.world_to_cell(w.start.x_m, w.start.y_m)
    assert w.map.free[row, col]


def test_world_file_with_everything(make_world):
    path = make_world(
        "start: [1.0, 1.0, 0.5]\n"
        "furniture:\n"
        "  - {name: crate, box: [3.0, 1.0, 3.5, 1.5], height_m: 0.4, color: [10, 20, 30]}\n"
        "  - {name: bin, circle: [4.0, 3.0, 0.2]}\n"
        "drop_zones:\n"
        "  - {name: stairs, polygon: [[5.0, 0.2], [5.8, 0.2], [5.8, 1.0]], depth_m: 0.5}\n"
        "moving:\n"
        "  - {name: walker, kind: person, path: [[1, 3], [5, 3]], loop: true}\n"
        "  - {name: dog, kind: pet, area: [1, 1, 2, 2], speed_mps: 0.8}\n"
    )
    w = load_world(path)
    assert w.start.yaw_rad == 0.5
    assert w.furniture[0].color == (10, 20, 30) and w.furniture[1].shape == "circle"
    assert w.drop_zones[0].contains(np.array([5.7, 5.1]), np.array([0.3, 0.9])).tolist() == [True, False]
    assert w.movers[0].loop and w.movers[1].speed_mps == 0.8 and w.movers[1].radius_m == 0.15


@pytest.mark.parametrize(("body", "where", "message"), [
    ("furniture:\n  - {name: x, box: [1, 1, 0.5, 2]}\n", "furniture[0].box", "x1 > x0"),
    ("furniture:\n  - {name: x, bx: [1, 1, 2, 2]}\n", "furniture[0].bx", "did you mean 'box'"),
    ("moving:\n  - {name: p, kind: person}\n", "moving[0]", "needs a 'path'"),
    ("moving:\n  - {name: p, kind: robot, path: [[0, 0], [1, 1]]}\n", "moving[0].kind", "'person' or 'pet'"),
    ("drop_zones:\n  - {name: d, polygon: [[0, 0], [1, 1]]}\n", "drop_zones[0].polygon", "at least 3"),
    ("start: [1, 2]\n", "start", "3 numbers"),
    ("start: [100, 2, 0]\n", "start", "outside the map"),
    ("furniture:\n  - {name: far, circle: [50, 50, 1]}\n", "furniture[0].circle", "'far' lies outside the map"),
    ("furnitur: []\n", "furnitur", "did you mean 'furniture'"),
    ("furniture:\n  - {name: x, circle: [1, 1, 0.2], color: [0, 0, 300]}\n", "furniture[0].color", "0..255"),
])
def test_bad_world_files_point_at_the_place(make_world, body, where, message):
    path = make_world(body)
    with pytest.raises(ConfigError) as err:
        load_world(path)
    assert err.value.file == str(path)
    assert err.value.path == where
    assert err.value.line is not None and err.value.line >= 3
    assert message in str(err.value)


def test_unknown_world_name_suggests_a_shipped_one():
    with pytest.raises(ConfigError, match="did you mean 'studio'"):
        load_world("studi")


def test_world_with_a_missing_map(tmp_path):
    path = tmp_path / "w.yaml"
    path.write_text("name: w\nmap: absent.yaml\n")
    with pytest.raises(ConfigError, match="map file not found") as err:
        load_world(path)
    assert err.value.line == 2


@pytest.mark.parametrize("name", ["nav2_depot", "nav2_tb3_sandbox", "nav2_warehouse", "turtlebot3_world"])
def test_external_maps_are_simulated_worlds(shared_dir, name):
    from atemr.io.sim.simulation import build_simulation

    path = shared_dir / "worlds" / "external" / f"{name}.yaml"
    if not path.is_file():
        pytest.skip(f"{path} is not there")
    sim = build_simulation(path, 0)
    m = sim.world.map
    # the start has room for the robot, on the map, away from its edge
    assert sim.clearance_at(sim.pose.x_m, sim.pose.y_m).clearance_m > 0
    row, col = m.world_to_cell(sim.pose.x_m, sim.pose.y_m)
    assert 5 <= row < m.height - 5 and 5 <= col < m.width - 5
    scan = sim.read_lidar(0.0)
    assert np.isfinite(scan.ranges_m).mean() > 0.1  # it sees walls
    assert sim.render_camera(0.0).shape == (480, 640, 3)


def test_shipped_twin_rooms_map_is_what_the_script_generates_and_symmetric(tmp_path):
    from atemr.worlds.make_twin_rooms import main as make_twin_rooms

    assert make_twin_rooms(["--out", str(tmp_path)]) == 0
    world = load_world("twin_rooms")
    shipped = world.source.parent
    assert filecmp.cmp(tmp_path / "twin_rooms.pgm", shipped / "twin_rooms.pgm", shallow=False)
    assert filecmp.cmp(tmp_path / "twin_rooms.yaml", shipped / "twin_rooms.yaml", shallow=False)
    data = world.map.data
    assert np.array_equal(data, data[::-1, ::-1]), "turned half a turn, the flat is itself"
    assert "twin_rooms" in shipped_world_names() and world.map.free[world.map.world_to_cell(2.0, 1.75)]
