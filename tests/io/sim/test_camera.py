"""The first-person camera: size, horizon, walls ahead, objects, people and drops in view."""

import math

import numpy as np
import pytest

from atemr.errors import ConfigError
from atemr.io.sim.camera import Camera, CameraParams
from atemr.io.sim.simulation import SimParams, build_simulation
from atemr.io.sim.world import Furniture
from atemr.msgs import Pose2D


def is_wall(px):
    r, _, b = (int(v) for v in px)
    return abs(r - b) < 25 and r > 60  # the grey-beige walls


def is_floor(px):
    r, g, b = (int(v) for v in px)
    return r - b > 30 and r > g > b  # warm wooden floor


@pytest.fixture
def room_sim(make_world, ideal_wheels):
    def build(body="start: [1.0, 2.0, 0.0]\n", width_m=6.0):
        return build_simulation(make_world(body, width_m=width_m), 0, params=SimParams(camera_hz=10),
                                wheels=ideal_wheels)

    return build


def test_image_size_and_type(room_sim):
    img = room_sim().render_camera(0.0)
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    small = Camera(CameraParams(width=160, height=120)).render(Pose2D(1.0, 2.0, 0.0), room_sim().scene)
    assert small.shape == (120, 160, 3)


def test_wall_projection_and_horizon(room_sim):
    # facing the east wall (inner face x = 5.9) from x = 1.0 + 0.12 (camera mount): 4.78 m away
    sim = room_sim()
    p = sim.camera.params
    img = sim.render_camera(0.0)
    f = p.focal_px
    depth = 5.9 - 1.12
    top = 240 - f * (2.5 - p.height_m) / depth
    bottom = 240 + f * p.height_m / depth
    col = 320
    assert is_wall(img[int(top) + 3, col]) and is_wall(img[int(bottom) - 3, col])
    assert is_floor(img[int(bottom) + 3, col])
    assert img[int(top) - 3, col].min() > 200  # the bright ceiling above the wall
    # the horizon (camera height) sits at the image centre: wall above and below it, floor only below
    assert is_wall(img[238, col]) and is_wall(img[242, col])
    assert not any(is_floor(img[r, col]) for r in range(0, 240))


def test_open_floor_meets_the_ceiling_at_the_horizon(room_sim):
    # a room far larger than the camera's range: no wall in view, floor below the centre row, ceiling above
    sim = room_sim("start: [2.0, 2.0, 0.0]\n", width_m=40.0)
    sim.camera = Camera(CameraParams(max_range_m=15.0, hfov_deg=30.0))
    img = sim.render_camera(0.0)
    assert is_floor(img[479, 320]) and is_floor(img[440, 320])
    # just below the centre row the floor is far away and hazy, just above it is the bright ceiling
    assert img[241, 320].max() < 200 and img[238, 320].min() > 215 and img[0, 320].min() > 180
    assert all(img[r, 320].max() < 200 for r in range(241, 480))


def test_a_wall_straight_ahead_fills_the_centre(room_sim):
    sim = room_sim("start: [5.4, 2.0, 0.0]\n")  # camera 0.38 m from the wall
    img = sim.render_camera(0.0)
    centre = img[120:360, 160:480]
    grey = (np.abs(centre[..., 0].astype(int) - centre[..., 2]) < 25) & (centre[..., 0] > 60)
    assert grey.all()


def test_furniture_and_people_are_coloured_blocks(room_sim):
    sim = room_sim(
        "start: [1.0, 2.0, 0.0]\n"
        "furniture:\n  - {name: box, box: [3.0, 1.8, 3.4, 2.2], height_m: 0.5, color: [0, 0, 255]}\n"
        "moving:\n  - {name: visitor, kind: person, path: [[2.5, 2.6], [2.5, 2.61]], speed_mps: 0.001,"
        " color: [255, 0, 0]}\n"
    )
    img = sim.render_camera(0.0).astype(int)
    # the box is low: blue below the horizon in the middle, the wall above it
    below = img[420, 320]  # spans rows 240 + f * 0.5 / 1.88 (= 364) down to the bottom
    assert below[2] > 150 and below[0] < 60
    assert is_wall(img[300, 320]) and is_wall(img[200, 320])
    # the person, to the left of centre (bearing atan2(0.6, 1.38)), is red and taller than the camera
    u = int(320 - sim.camera.params.focal_px * math.tan(math.atan2(0.6, 1.38)))
    assert img[150, u][0] > 150 and img[150, u][1] < 80


@pytest.mark.parametrize("moving", ["", "moving:\n  - {name: visitor, kind: person, path: [[0.5, 3.5], [0.5, 3.51]],"
                                     " speed_mps: 0.001, color: [255, 0, 0]}\n"], ids=["nobody", "nobody-in-view"])
def test_furniture_is_drawn_with_nobody_in_view(room_sim, moving):
    """The furniture does not need a person in front of the camera to be seen (it was drawn only when someone was:
    a carer watching an empty room saw no table)."""
    sim = room_sim("start: [1.0, 2.0, 0.0]\n"
                   "furniture:\n  - {name: box, box: [3.0, 1.8, 3.4, 2.2], height_m: 0.5, color: [0, 0, 255]}\n"
                   + moving)
    img = sim.render_camera(0.0).astype(int)
    below = img[420, 320]
    assert below[2] > 150 and below[0] < 60  # blue, below the horizon in the middle
    red = (img[..., 0] > 150) & (img[..., 1] < 80) & (img[..., 2] < 80)
    assert not red.any()  # the visitor, if any, is behind the camera


def test_drop_zone_floor_is_dark(room_sim):
    sim = room_sim("start: [1.0, 2.0, 0.0]\ndrop_zones:\n  - {name: hole, box: [1.5, 0.5, 5.0, 3.5]}\n")
    img = sim.render_camera(0.0).astype(int)
    assert img[400, 320].sum() < 200  # the floor 2.9 m ahead is over the hole
    assert is_floor(img[400, 20]) or img[400, 20].sum() > 300  # to the side it is floor


def test_rendering_is_deterministic(room_sim):
    a = room_sim().render_camera(0.0)
    b = room_sim().render_camera(0.0)
    assert np.array_equal(a, b)


def test_camera_params_are_validated():
    with pytest.raises(ConfigError, match=r"camera\.hfov_deg"):
        CameraParams(hfov_deg=200)
    with pytest.raises(ConfigError, match="image size"):
        CameraParams(width=4)


def test_a_standing_camera_keeps_what_does_not_move_and_sees_what_does():
    """A robot standing still (a carer watching it) sees the same walls and furniture frame after frame, so the
    camera keeps that view for its pose and paints only the people and pets onto it: its pictures are, to the
    bit, a fresh camera's while the carer walks through the view, and a box put down or taken away is seen at
    once."""
    sim = build_simulation("studio", 4)
    pose = Pose2D(3.0, 2.6, 1.45)  # facing the carer's walk along y = 4.25
    standing = Camera(sim.camera.params)

    def fresh():
        return Camera(sim.camera.params).render(pose, sim.scene, sim.movers)

    first = standing.render(pose, sim.scene, sim.movers)
    kept = standing._static
    assert kept is not None and np.array_equal(first, fresh())
    seen = 0
    for k in range(1, 60):
        sim.step_to(k * 0.5)
        image = standing.render(pose, sim.scene, sim.movers)
        assert np.array_equal(image, fresh()), k
        assert standing._static is kept  # the view was kept, not made again
        seen += not np.array_equal(image, first)
    assert 20 < seen < 59, seen  # the carer walked into the view and out of it again
    box = sim.scene.add_object(Furniture("box", "box", (2.9, 3.4, 3.3, 3.7), 0.6, color=(255, 0, 0)))
    with_box = standing.render(pose, sim.scene, sim.movers)
    assert np.array_equal(with_box, fresh()) and not np.array_equal(with_box, first)
    sim.scene.remove_object(box)
    assert np.array_equal(standing.render(pose, sim.scene, sim.movers), fresh())
