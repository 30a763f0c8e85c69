"""The simulated D415 (issue 24): depth of the same scene, its geometry, range, noise and seeding."""

import math
from types import ModuleType

import numpy as np
import pytest
from numba import njit

from atemr.errors import ConfigError
from atemr.io.sim import depth
from atemr.io.sim.base import BaseParams
from atemr.io.sim.depth import DepthCamera, DepthCameraParams
from atemr.io.sim.simulation import SimParams, build_simulation
from atemr.io.sim.world import Furniture
from atemr.msgs import CameraMount, Pose2D
from atemr.skills.depth_cloud import depth_to_points

LEVEL = CameraMount(x_m=0.0, z_m=0.5)  # looking straight ahead, half a metre up
IDEAL = DepthCameraParams(subpixel_px=0.0, dropout_prob=0.0, mount=LEVEL)
EXACT = SimParams(base=BaseParams(slip_std=0.0, odom_noise_std=0.0))


def render(sim, params, pose=None, seed=0):
    camera = DepthCamera(params, np.random.default_rng(seed))
    return camera.render(1.0, pose or sim.pose, sim.scene, sim.movers)


def test_the_defaults_are_a_d415_at_424_by_240():
    p = DepthCameraParams()
    assert (p.width, p.height, p.hfov_deg, p.vfov_deg) == (424, 240, 65.0, 40.0)
    assert (p.range_min_m, p.range_max_m) == (0.3, 3.0)
    assert SimParams().depth_hz == 0.0  # a bare simulation renders no depth unless asked


def test_a_wall_ahead_is_at_its_distance_along_the_optical_axis(make_world):
    sim = build_simulation(make_world("start: [4.0, 2.0, 0.0]\n"), 0, params=EXACT)  # east wall's face at 5.9
    image = render(sim, IDEAL)
    assert image.depth_m.shape == (240, 424) and image.depth_m.dtype == np.float32
    # z-depth, not range: the whole wall is at the same depth across the image (where it is within range)
    wall = image.depth_m[100:140, :]
    assert np.allclose(wall[wall > 0], 1.9, atol=0.03)
    assert image.t == 1.0 and image.mount == LEVEL


def test_the_floor_is_where_the_pinhole_model_says(make_world):
    sim = build_simulation(make_world("start: [1.0, 2.0, 0.0]\n"), 0, params=EXACT)
    image = render(sim, IDEAL)
    v = image.height - 1  # the lowest row looks 20° down: the floor is 0.5 / tan(angle) ahead
    angle = math.atan((v - image.cy) / image.fy)
    assert image.depth_m[v, image.width // 2] == pytest.approx(0.5 / math.tan(angle), abs=0.01)


def test_nothing_within_range_is_no_data(make_world):
    sim = build_simulation(make_world("start: [0.6, 2.0, 0.0]\n"), 0, params=EXACT)
    near = render(sim, IDEAL, Pose2D(0.6, 2.0, math.pi))  # the west wall's face 0.5 m ahead: in range
    far = render(sim, IDEAL, Pose2D(0.6, 2.0, 0.0))  # the east wall 5.3 m ahead: beyond 3 m
    assert (near.depth_m[100:140, :] > 0).all()
    assert (far.depth_m[110:130, 200:224] == 0).all()  # no data is 0, as the SDK gives it


def test_a_table_top_is_seen_between_its_clearance_and_its_height(make_world):
    body = "furniture:\n  - {name: table, box: [2.0, 1.0, 3.0, 3.0], clearance_m: 0.70, height_m: 0.75}\n"
    sim = build_simulation(make_world(body + "start: [1.0, 2.0, 0.0]\n"), 0, params=EXACT)
    mount = CameraMount(x_m=0.1, z_m=0.9, pitch_rad=math.radians(20))
    image = render(sim, DepthCameraParams(subpixel_px=0.0, dropout_prob=0.0, mount=mount))
    points = depth_to_points(image)
    on_table = points[(points[:, 0] > 0.95) & (points[:, 0] < 2.0) & (points[:, 2] > 0.05)]
    assert len(on_table) > 1000
    # the front face (x = 2.0 world, 1.0 ahead of the base) and the top surface: all between 0.70 and 0.75 m
    assert on_table[:, 2].min() == pytest.approx(0.70, abs=0.01)
    assert on_table[:, 2].max() == pytest.approx(0.75, abs=0.01)
    assert on_table[:, 0].min() == pytest.approx(1.0, abs=0.01)
    # and under it the floor continues: points at floor height beyond the table's front edge
    floor = points[(points[:, 0] > 1.1) & (np.abs(points[:, 2]) < 0.02)]
    assert len(floor) > 0


def test_noise_grows_with_the_square_of_the_depth():
    p = DepthCameraParams()
    near, far = p.noise_std_m(np.array([1.0, 3.0], dtype=np.float32))
    assert far == pytest.approx(9 * near)
    assert 0.002 < near < 0.008 and 0.02 < far < 0.06  # the D415's few millimetres at 1 m, centimetres at 3 m


def test_noisy_frames_are_seeded(make_world):
    sim = build_simulation(make_world("start: [4.0, 2.0, 0.0]\n"), 0, params=EXACT)
    params = DepthCameraParams(mount=LEVEL)
    a, b, c = render(sim, params, seed=3), render(sim, params, seed=3), render(sim, params, seed=4)
    assert np.array_equal(a.depth_m, b.depth_m)
    assert not np.array_equal(a.depth_m, c.depth_m)
    wall = a.depth_m[100:140, 100:300]
    wall = wall[wall > 0]
    assert 0.005 < wall.std() < 0.03  # about 1.6 cm at 1.9 m


def test_the_depth_camera_runs_at_its_rate_and_does_not_change_the_trajectory():
    plain = build_simulation("studio", 5)
    seen = build_simulation("studio", 5, params=SimParams(depth_hz=10.0))
    assert (seen.depth_source, 10.0) in seen.components()
    assert all(c is not plain.depth_source for c, _ in plain.components())
    for sim in (plain, seen):
        sim.command_twist(0.3, 0.2)
    from atemr.clock import SimClock
    from atemr.scheduler import Scheduler

    for sim in (plain, seen):
        sched = Scheduler(SimClock())
        sim.attach(sched)
        sched.run(duration=2.0)
    assert plain.pose == seen.pose
    assert seen.depth_source.count == 21 and seen.depth_source.latest is not None


def test_bad_parameters_are_refused():
    with pytest.raises(ConfigError):
        DepthCameraParams(range_min_m=3.0, range_max_m=0.3)
    with pytest.raises(ConfigError):
        SimParams(depth_hz=-1.0)


def test_the_compiled_shape_tests_see_what_the_numpy_ones_saw(numpy_baselines: ModuleType) -> None:
    """Furniture (slab tests) and people and the cat (cylinders, their sides and caps) hit by the compiled loops
    give the images, to the bit, of `benchmarks/numpy_baselines.py`'s numpy tests, with noise and without: a
    seeded run's depth frames stay what they were. Each pose looks at a person or a piece of furniture."""
    sim = build_simulation("studio", 2)
    rng = np.random.default_rng(2)
    targets = [(m.x_m, m.y_m) for m in sim.movers.items]
    targets += [((o.params[0] + o.params[2]) / 2, (o.params[1] + o.params[3]) / 2)
                for o in sim.scene.objects.values() if o.shape == "box"]
    assert len(targets) > 3
    for params in (DepthCameraParams(), IDEAL):
        ours = DepthCamera(params, np.random.default_rng(9))
        before = numpy_baselines.NumpyShapesDepthCamera(params, np.random.default_rng(9))
        for tx, ty in targets:
            for _ in range(3):
                away, bearing = rng.uniform(0.4, 2.5), rng.uniform(-math.pi, math.pi)
                x, y = tx + away * math.cos(bearing), ty + away * math.sin(bearing)
                pose = Pose2D(x, y, math.atan2(ty - y, tx - x) + rng.uniform(-0.3, 0.3))
                a = ours.render(1.0, pose, sim.scene, sim.movers).depth_m
                b = before.render(1.0, pose, sim.scene, sim.movers).depth_m
                assert a.tobytes() == b.tobytes(), pose


@pytest.mark.parametrize("noise", [(0.08, 0.002), (4.0, 0.3), (0.0, 0.002), (0.08, 0.0), (0.0, 0.0)],
                         ids=["d415", "very-noisy", "dropouts-only", "noise-only", "ideal"])
def test_the_compiled_finish_draws_numpys_noise_to_the_bit(numpy_baselines: ModuleType, noise) -> None:
    """The image finished in one compiled loop (`depth._finish`, its normals and uniforms drawn one at a time)
    is, to the bit, what numpy's passes and ``Generator``'s array draws made (`benchmarks/numpy_baselines.py`),
    and leaves the generator where they left it: a seeded run's frames, and every draw after them, stay what they
    were. Poses all round the studio, people and the cat in it; noise and dropouts on and off."""
    subpixel, dropout = noise
    sim = build_simulation("studio", 2)
    params = DepthCameraParams(subpixel_px=subpixel, dropout_prob=dropout)
    ours = DepthCamera(params, np.random.default_rng(8))
    before = numpy_baselines.NumpyFinishDepthCamera(params, np.random.default_rng(8))
    rng = np.random.default_rng(3)
    for _ in range(25):
        pose = Pose2D(float(rng.uniform(1.0, 8.0)), float(rng.uniform(1.0, 6.0)), float(rng.uniform(-math.pi, math.pi)))
        a = ours.render(1.0, pose, sim.scene, sim.movers).depth_m
        b = before.render(1.0, pose, sim.scene, sim.movers).depth_m
        assert a.tobytes() == b.tobytes(), pose
    assert ours.rng.bit_generator.state == before.rng.bit_generator.state


@njit
def _compiled_draws(rng: np.random.Generator, normals: np.ndarray, uniforms: np.ndarray) -> None:
    bitgen = rng.bit_generator
    for i in range(normals.shape[0]):
        normals[i] = depth._standard_normal_f(bitgen)
    for i in range(uniforms.shape[0]):
        uniforms[i] = depth._uniform_f(bitgen)


def test_the_compiled_draws_are_numpys_float32_draws() -> None:
    """`depth._standard_normal_f` and `_uniform_f` draw ``Generator.standard_normal(dtype=float32)`` and
    ``Generator.random(dtype=float32)``, bit for bit, over about three million draws: the tail beyond the
    ziggurat's base strip and its wedges included. Seed 17's draw 418,776 is a wedge that numpy tests in float64
    and numba's own ``standard_normal`` in float32 (which answers otherwise, and drifts from there on)."""
    ours, numpys = np.random.default_rng(17), np.random.default_rng(17)
    normals, none = np.empty(500_000, dtype=np.float32), np.empty(0, dtype=np.float32)
    _compiled_draws(ours, normals, none)
    assert normals.tobytes() == numpys.standard_normal(500_000, dtype=np.float32).tobytes()
    n = 101_760  # then as a depth frame draws them: every pixel's normal, then every pixel's uniform
    normals, uniforms = np.empty(n, dtype=np.float32), np.empty(n, dtype=np.float32)
    tail = 0
    for _ in range(12):
        _compiled_draws(ours, normals, uniforms)
        expected = numpys.standard_normal(n, dtype=np.float32)
        assert normals.tobytes() == expected.tobytes()
        assert uniforms.tobytes() == numpys.random(n, dtype=np.float32).tobytes()
        tail += int((np.abs(expected) > 3.6541528).sum())
    assert tail > 100  # the tail's loop ran
    assert ours.bit_generator.state == numpys.bit_generator.state


def test_a_standing_camera_keeps_what_does_not_move_and_sees_what_does() -> None:
    """A robot standing still sees the same walls and furniture frame after frame, so the camera keeps that view
    for its pose and adds only the people and pets: its frames are, to the bit, a fresh camera's (nothing kept)
    while the carer and the cat walk, and a box put down in front of it, or taken away, is seen at once."""
    sim = build_simulation("studio", 4)
    pose = Pose2D(3.0, 2.6, 1.45)  # facing the carer's walk along y = 4.25
    standing = DepthCamera(IDEAL, np.random.default_rng(0))

    def fresh() -> np.ndarray:
        return DepthCamera(IDEAL, np.random.default_rng(0)).render(0.0, pose, sim.scene, sim.movers).depth_m

    first = standing.render(0.0, pose, sim.scene, sim.movers).depth_m
    kept = standing._static
    assert kept is not None and first.tobytes() == fresh().tobytes()
    changed = 0
    for k in range(1, 60):
        sim.step_to(k * 0.5)
        image = standing.render(0.0, pose, sim.scene, sim.movers).depth_m
        assert image.tobytes() == fresh().tobytes(), k
        assert standing._static is kept  # the view was kept, not made again
        changed += image.tobytes() != first.tobytes()
    assert changed > 20, changed  # the carer walked through the view meanwhile
    box = sim.scene.add_object(Furniture("box", "box", (2.9, 3.4, 3.3, 3.7), 0.6))
    with_box = standing.render(0.0, pose, sim.scene, sim.movers).depth_m
    assert with_box.tobytes() == fresh().tobytes() and with_box.tobytes() != first.tobytes()
    sim.scene.remove_object(box)
    assert standing.render(0.0, pose, sim.scene, sim.movers).depth_m.tobytes() == fresh().tobytes()
