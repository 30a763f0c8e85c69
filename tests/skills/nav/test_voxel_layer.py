"""The depth camera's obstacle layer (issue 24): frames from the simulated D415 (a real part, not a stand-in)
marked and cleared in a voxel grid over the costmap, projected to its cells and to the safety zones."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.io.sim.base import BaseParams
from atemr.io.sim.simulation import SimParams, Simulation, build_simulation
from atemr.msgs import CameraMount, DepthImage, Pose2D
from atemr.skills.body import KAY
from atemr.skills.nav.costmap import LETHAL, Costmap
from atemr.skills.nav.voxel_layer import VoxelLayer, VoxelLayerParams

PARAMS = SimParams(base=BaseParams(slip_std=0.0, odom_noise_std=0.0), depth_hz=10.0)
TABLE = "  - {name: table, box: [3.0, 1.0, 4.2, 3.0], clearance_m: 0.70, height_m: 0.75}\n"
SHOE = "  - {name: shoe, box: [2.4, 1.9, 2.6, 2.1], height_m: 0.10}\n"
SHELF = "  - {name: high shelf, box: [2.4, 1.5, 2.8, 2.5], clearance_m: 1.5, height_m: 1.6}\n"


def world(tmp_path: Path, *items: str) -> Simulation:
    """A 6 m x 4 m walled room (5 cm cells) with ``items``, the robot at (1.0, 2.0) facing east (+x)."""
    from PIL import Image

    pixels = np.full((80, 120), 254, dtype=np.uint8)
    pixels[:2, :] = pixels[-2:, :] = pixels[:, :2] = pixels[:, -2:] = 0
    Image.fromarray(pixels).save(tmp_path / "room.pgm", format="PPM")
    (tmp_path / "room.yaml").write_text("image: room.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
                                        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    body = "furniture:\n" + "".join(items) if items else ""
    (tmp_path / "w.yaml").write_text(f"name: room\nmap: room.yaml\nstart: [1.0, 2.0, 0.0]\n{body}")
    return build_simulation(tmp_path / "w.yaml", 0, params=PARAMS)


def look(sim: Simulation, layer: VoxelLayer, pose: Pose2D | None = None, frames: int = 1) -> int:
    pose = pose or sim.pose
    if pose != sim.pose:
        sim.kidnap(pose)
    cells = 0
    for i in range(frames):
        cells = layer.update(sim.depth_camera.render(float(i), pose, sim.scene, sim.movers), pose)
    return cells


def marked_xy(layer: VoxelLayer) -> np.ndarray:
    rows, cols = np.nonzero(layer.columns)
    xs, ys = layer.costmap.map.cell_to_world(rows, cols)
    return np.column_stack([xs, ys])


def new_layer(sim: Simulation) -> VoxelLayer:
    return VoxelLayer(Costmap(sim.world.map), VoxelLayerParams.for_body(KAY))


def test_a_table_top_the_lidar_misses_is_marked_where_it_is(tmp_path):
    sim = world(tmp_path, TABLE)
    layer = new_layer(sim)
    assert look(sim, layer, Pose2D(1.6, 2.0, 0.0)) > 20
    xy = marked_xy(layer)
    assert xy[:, 0].min() == pytest.approx(3.0, abs=0.05)  # the top's front edge, seen 1.3 m ahead
    assert (xy[:, 0] <= 4.25).all() and (np.abs(xy[:, 1] - 2.0) < 1.05).all()
    # the costmap: lethal there, and the floor in front is free
    costmap = layer.costmap
    assert costmap.cost_at(3.05, 2.0) == LETHAL
    assert costmap.cost_at(2.2, 2.0) < LETHAL
    front = layer.clearance(Pose2D(1.6, 2.0, 0.0))
    assert front.front_m == pytest.approx(3.0 - 1.6, abs=0.05)
    assert math.isinf(front.rear_m)


def test_a_shoe_under_the_lidar_plane_is_marked_and_a_shelf_above_the_robot_is_not(tmp_path):
    sim = world(tmp_path, SHOE, SHELF.replace("2.4, 1.5, 2.8, 2.5", "3.4, 1.5, 3.8, 2.5"))
    layer = new_layer(sim)
    look(sim, layer)
    xy = marked_xy(layer)
    assert len(xy) > 0
    assert (xy[:, 0] >= 2.35).all() and (xy[:, 0] <= 2.65).all()  # the shoe, and nothing at the shelf (x 3.4..3.8)
    assert layer.clearance(sim.pose).front_m == pytest.approx(2.4 - 1.0, abs=0.05)


def test_an_overhanging_shelf_below_the_robot_height_is_marked(tmp_path):
    sim = world(tmp_path, SHELF.replace("clearance_m: 1.5, height_m: 1.6", "clearance_m: 0.9, height_m: 0.95"))
    layer = new_layer(sim)
    look(sim, layer)
    xy = marked_xy(layer)
    assert len(xy) > 0 and xy[:, 0].min() == pytest.approx(2.4, abs=0.05)


def test_what_leaves_clears_by_the_rays_that_now_pass_through(tmp_path):
    sim = world(tmp_path, SHOE)
    layer = new_layer(sim)
    assert look(sim, layer, frames=3) > 0
    stable = layer.columns.copy()
    shoe = next(i for i, item in sim.scene.objects.items() if item.name == "shoe")
    sim.remove_obstacle(shoe)
    assert look(sim, layer) == 0  # the floor is seen where it was: every voxel of it cleared
    assert stable.any() and not layer.costmap.voxels.any()


def test_what_stays_in_view_stays_marked_frame_after_frame(tmp_path):
    sim = world(tmp_path, SHOE, TABLE)
    layer = new_layer(sim)
    first = look(sim, layer)
    counts = [look(sim, layer) for _ in range(5)]  # new noise each frame
    assert min(counts) >= first * 0.9


def test_what_is_out_of_view_is_remembered(tmp_path):
    sim = world(tmp_path, TABLE)
    layer = new_layer(sim)
    look(sim, layer, Pose2D(1.6, 2.0, 0.0))
    # the mast 0.25 m from the top's edge: the edge is under the camera's 0.3 m, out of its view
    close = Pose2D(2.75, 2.0, 0.0)
    image = sim.depth_camera.render(1.0, close, sim.scene, sim.movers)
    layer.update(image, close)
    assert layer.costmap.voxels[layer.costmap.cells(3.02, 2.0)[:2]]
    assert layer.clearance(close).front_m < 0.28  # inside the stop zone, as a wall there would be


def test_mapped_walls_are_not_marked_a_flying_pixel_is_not_an_obstacle():
    from atemr.domain.maps import OccupancyMap

    data = np.zeros((40, 40), dtype=np.int8)
    data[:, 30] = 100  # a wall 1.5 m ahead
    costmap = Costmap(OccupancyMap(data, 0.05, Pose2D(0.0, 0.0, 0.0), name="t"))
    layer = VoxelLayer(costmap, VoxelLayerParams())
    mount = CameraMount(z_m=0.5)
    depth = np.zeros((40, 40), dtype=np.float32)
    depth[:, :] = 1.49  # the wall's face (from a camera at x 0.0)
    depth[20, 20] = 0.8  # one pixel at 0.8 m: noise, no obstacle
    image = DepthImage(0.0, depth, 20.0, 20.0, 19.5, 19.5, 0.3, 3.0, mount)
    assert layer.update(image, Pose2D(0.02, 1.0, 0.0)) == 0


def test_a_recovery_that_clears_the_costmap_clears_the_voxels(tmp_path):
    sim = world(tmp_path, SHOE)
    layer = new_layer(sim)
    look(sim, layer)
    assert layer.costmap.voxels.any()
    layer.costmap.clear_obstacles()
    assert not layer.costmap.voxels.any()
    sim.remove_obstacle(next(iter(sim.scene.objects)))
    look(sim, layer)
    assert not layer.voxels.any()


def test_bad_poses_and_parameters_are_refused(tmp_path):
    sim = world(tmp_path)
    layer = new_layer(sim)
    image = sim.depth_camera.render(0.0, sim.pose, sim.scene)
    with pytest.raises(NavigationError):
        layer.update(image, Pose2D(math.nan, 0.0, 0.0))
    with pytest.raises(NavigationError):
        VoxelLayerParams(floor_margin_m=2.0, max_height_m=1.0)
    assert VoxelLayerParams.for_body(KAY).max_height_m == pytest.approx(KAY.height_m + 0.1)


def test_what_the_lidar_sees_is_left_to_the_lidar_layer(tmp_path):
    # a person-sized column the lidar sees: marked here, it would stay behind as a trail once they walk away
    sim = world(tmp_path, "  - {name: person, circle: [2.5, 2.0, 0.22], height_m: 1.7}\n", SHOE.replace(
        "2.4, 1.9, 2.6, 2.1", "2.4, 1.2, 2.6, 1.4"))
    image = sim.depth_camera.render(0.0, sim.pose, sim.scene, sim.movers)
    scan = sim.read_lidar(0.0)
    alone = new_layer(sim)
    alone.update(image, sim.pose)
    assert (np.abs(marked_xy(alone)[:, 1] - 2.0) < 0.3).any()  # without the scan: the person is marked
    layer = new_layer(sim)
    layer.update(image, sim.pose, scan)
    xy = marked_xy(layer)
    assert len(xy) > 0 and (np.abs(xy[:, 1] - 1.3) < 0.15).all()  # with it: only the shoe the lidar cannot see


def test_what_is_not_seen_again_decays(tmp_path):
    sim = world(tmp_path, SHOE)
    layer = VoxelLayer(Costmap(sim.world.map), VoxelLayerParams(decay_s=3.0))
    look(sim, layer)
    away = Pose2D(1.0, 2.0, math.pi)  # turned round: the shoe is out of view
    sim.kidnap(away)
    for t in (1.0, 2.9):
        layer.update(sim.depth_camera.render(t, away, sim.scene), away)
        assert layer.columns.any()  # remembered
    layer.update(sim.depth_camera.render(3.1, away, sim.scene), away)
    assert not layer.columns.any() and not layer.voxels.any() and not layer.costmap.voxels.any()


def test_a_mapped_wall_seen_far_off_with_the_cameras_noise_is_not_marked(tmp_path):
    sim = world(tmp_path)  # nothing but the room's walls, all in the map
    layer = new_layer(sim)
    for yaw in (0.0, 0.5, -0.5, math.pi / 2):  # the east wall 2.4 m off, the corners, the north wall
        assert look(sim, layer, Pose2D(3.4, 2.0, yaw), frames=5) == 0


def test_what_the_lidar_now_sees_through_is_cleared_above_its_plane_and_a_table_top_is_not(tmp_path):
    # a cat-sized thing (0.35 m): the far part of its top lies beyond the lidar margin of its returns
    sim = world(tmp_path, "  - {name: ottoman, box: [2.2, 1.7, 2.9, 2.3], height_m: 0.35}\n", TABLE, SHOE.replace(
        "2.4, 1.9, 2.6, 2.1", "2.4, 1.2, 2.6, 1.4"))
    layer = new_layer(sim)
    image = sim.depth_camera.render(0.0, sim.pose, sim.scene, sim.movers)
    layer.update(image, sim.pose, sim.read_lidar(0.0))
    xy = marked_xy(layer)
    top = (np.abs(xy[:, 1] - 2.0) < 0.3) & (xy[:, 0] > 2.4) & (xy[:, 0] < 2.95)
    assert top.any()  # the far part of its top, the camera's
    assert (xy[:, 0] > 2.95).any()  # the table top
    ottoman = next(i for i, item in sim.scene.objects.items() if item.name == "ottoman")
    sim.remove_obstacle(ottoman)
    away = Pose2D(1.0, 2.0, math.pi)  # turned round: only the lidar sees where it was
    sim.kidnap(away)
    layer.update(sim.depth_camera.render(0.1, away, sim.scene, sim.movers), away, sim.read_lidar(0.1))
    xy = marked_xy(layer)
    assert not ((np.abs(xy[:, 1] - 2.0) < 0.3) & (xy[:, 0] < 2.95)).any()  # its beams pass: gone at once
    assert (xy[:, 0] > 2.95).any()  # the lidar passes under the table top: still marked
    assert (np.abs(xy[:, 1] - 1.3) < 0.15).any()  # the shoe under the lidar's plane: still marked


def test_the_compiled_marks_fill_the_voxels_the_numpy_ones_did(numpy_baselines: ModuleType) -> None:
    """`benchmarks/numpy_baselines.py`'s numpy ``_mark`` and the compiled one fill the same voxels, frame after
    frame round the studio, people and the cat included, with every pixel or every other one: a seeded run's
    obstacles stay what they were."""
    sim = build_simulation("studio", 4, params=PARAMS)
    rng = np.random.default_rng(4)
    for stride in (1, 2):
        params = replace(VoxelLayerParams.for_body(KAY), stride=stride)
        ours = VoxelLayer(Costmap(sim.world.map), params)
        before = numpy_baselines.NumpyMarkLayer(Costmap(sim.world.map), params)
        marked = 0
        for i in range(25):
            x, y = float(rng.uniform(0.5, 9.0)), float(rng.uniform(-2.0, 8.0))
            if sim.clearance_at(x, y).clearance_m <= 0.0:
                continue
            pose = Pose2D(x, y, float(rng.uniform(-math.pi, math.pi)))
            image = sim.depth_camera.render(0.1 * i, pose, sim.scene, sim.movers)
            assert ours.update(image, pose) == before.update(image, pose)
            np.testing.assert_array_equal(ours.voxels, before.voxels)
            marked = max(marked, int(ours.voxels.sum()))
        assert marked > 0  # the studio's furniture, or the comparison proves little


def test_the_marked_voxels_of_a_window_come_in_the_order_of_a_full_search(tmp_path) -> None:
    """Clearing looks only into the marked columns of its window; it must find every marked voxel, in the order
    ``np.nonzero`` of the whole block gives (the order the cleared voxels are counted and kept in), also while a
    column is still up whose voxels a first clearing emptied."""
    layer = new_layer(world(tmp_path))
    rng = np.random.default_rng(5)
    layer.voxels[:] = rng.random(layer.voxels.shape) < 0.01
    layer.columns[:] = layer.voxels.any(axis=2)
    layer.columns[3, 4] = True  # up, with nothing in it
    layer.voxels[3, 4] = False
    found = []
    for box, band in (((0, 80, 0, 120), (0, layer.params.layers)), ((10, 50, 20, 90), (2, 5)), ((2, 6, 3, 8), (0, 3))):
        rs, re, cs, ce = box
        want = np.nonzero(layer.voxels[rs:re, cs:ce, band[0]:band[1]])
        got = layer._marked_in(box, band)
        for a, b, offset in zip(got, want, (rs, cs, band[0]), strict=True):
            np.testing.assert_array_equal(a, b + offset)
        found.append(len(got[0]))
    assert found[0] > 1000 and found[1] > 50  # blocks with plenty in them, not only empty ones
