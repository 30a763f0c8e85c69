"""Objects with a vertical extent (issue 24): the lidar sees only what crosses its plane, the robot's volume
meets everything at its parts' heights, and a collision names the object and the part."""

import math

import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.errors import ConfigError
from atemr.io.sim.base import BaseParams
from atemr.io.sim.simulation import SimParams, build_simulation
from atemr.io.sim.world import load_world
from atemr.scheduler import Scheduler
from atemr.skills.body import KAY

EXACT = SimParams(base=BaseParams(slip_std=0.0, odom_noise_std=0.0))

#: A table 1.2 m deep across the robot's way (x 3.0..4.2), top 0.70..0.75 m, legs at its corners only.
TABLE = """furniture:
  - {name: table, box: [3.0, 1.0, 4.2, 3.0], clearance_m: 0.70, height_m: 0.75}
  - {name: leg, box: [3.0, 1.0, 3.05, 1.05], height_m: 0.70}
  - {name: leg, box: [3.0, 2.95, 3.05, 3.0], height_m: 0.70}
  - {name: leg, box: [4.15, 1.0, 4.2, 1.05], height_m: 0.70}
  - {name: leg, box: [4.15, 2.95, 4.2, 3.0], height_m: 0.70}
  - {name: shoe, box: [1.0, 0.4, 1.3, 0.55], height_m: 0.10}
"""


def run(sim, seconds):
    sched = Scheduler(SimClock())
    sim.attach(sched)
    sched.run(duration=seconds)


def test_an_object_spans_its_clearance_to_its_height(make_world):
    world = load_world(make_world(TABLE + "start: [1.0, 2.0, 0.0]\n"))
    table = world.furniture[0]
    assert (table.clearance_m, table.height_m) == (0.70, 0.75)
    assert table.spans(0.72, 0.72) and table.spans(0.5, 1.0)
    assert not table.spans(0.2, 0.2) and not table.spans(0.0, 0.3)
    assert world.furniture[1].clearance_m == 0.0


@pytest.mark.parametrize("item, message", [
    ("{name: t, box: [1, 1, 2, 2], clearance_m: 0.8, height_m: 0.75}", r"clearance_m must be within \[0, height_m\)"),
    ("{name: t, box: [1, 1, 2, 2], clearance_m: -0.1}", "clearance_m must be within"),
])
def test_a_clearance_above_the_top_is_refused_at_its_place(make_world, item, message):
    with pytest.raises(ConfigError, match=message) as err:
        load_world(make_world(f"furniture:\n  - {item}\n"))
    assert "furniture[0].clearance_m" in str(err.value)


def test_the_lidar_sees_the_legs_and_not_the_top_nor_the_shoe(make_world):
    sim = build_simulation(make_world(TABLE + "start: [1.0, 2.0, 0.0]\n"), 0, params=EXACT)
    lidar = sim.lidar
    ranges = lidar.true_ranges(sim.pose, sim.scene, np.zeros((0, 2)), np.zeros(0))
    ahead = ranges[np.argmin(np.abs(lidar.angles_rad))]
    # the beam straight ahead passes under the table (x 3.0..4.2) to the far wall (x 5.9, sensor at 1.1)
    assert ahead == pytest.approx(5.9 - 1.1, abs=0.06)
    to_leg = math.atan2(1.025 - 2.0, 3.025 - 1.1)
    hit = ranges[np.argmin(np.abs(lidar.angles_rad - to_leg))]
    assert hit < math.hypot(3.05 - 1.1, 1.0 - 2.0)  # the near leg stops the beam
    to_shoe = math.atan2(0.475 - 2.0, 1.15 - 1.1)
    assert ranges[np.argmin(np.abs(lidar.angles_rad - to_shoe))] > 1.6  # under the plane: the wall beyond


def test_the_base_passes_under_the_top_and_the_mast_hits_its_edge(make_world):
    sim = build_simulation(make_world(TABLE + "start: [1.0, 2.0, 0.0]\n"), 0, params=EXACT)
    assert sim.clearance_at(2.9, 2.0).clearance_m > 0  # the base under the top's edge: only the mast could touch
    sim.command_twist(0.5, 0.0)
    run(sim, 6.0)
    assert len(sim.collisions) == 1
    hit = sim.collisions[0]
    assert (hit.what, hit.part) == ("table", "mast")
    # stopped where the mast meets the top's edge, the base already under it
    assert hit.pose.x_m == pytest.approx(3.0 - KAY.parts[1].radius_m, abs=0.03)
    assert sim.pose.x_m < 3.0


def test_the_base_meets_a_shoe_under_the_lidar_plane(make_world):
    sim = build_simulation(make_world(TABLE + "start: [1.15, 1.5, -1.5708]\n"), 0, params=EXACT)
    sim.command_twist(0.3, 0.0)
    run(sim, 4.0)
    assert [(c.what, c.part) for c in sim.collisions] == [("shoe", "base")]
    assert sim.pose.y_m == pytest.approx(0.55 + 0.25, abs=0.03)


def test_a_shelf_above_the_robot_is_no_obstacle(make_world):
    shelf = "furniture:\n  - {name: high shelf, box: [3.0, 1.5, 3.5, 2.5], clearance_m: 1.5, height_m: 1.6}\n"
    sim = build_simulation(make_world(shelf + "start: [1.0, 2.0, 0.0]\n"), 0, params=EXACT)
    sim.command_twist(0.5, 0.0)
    run(sim, 6.0)
    assert sim.collisions == [] and sim.pose.x_m > 3.9


def test_the_studio_dining_table_stands_on_legs_and_a_tray_lies_under_the_lidar():
    world = load_world("studio")
    table = next(f for f in world.furniture if f.name == "dining table")
    assert table.clearance_m == pytest.approx(0.70) and table.height_m == pytest.approx(0.75)
    assert sum(f.name == "dining table leg" for f in world.furniture) == 4
    assert any(f.height_m < 0.2 and not f.mapped for f in world.furniture)


def test_a_body_whose_base_is_not_the_footprint_is_refused():
    with pytest.raises(ConfigError, match="footprint"):
        SimParams(base=BaseParams(footprint_radius_m=0.3))
