"""The compiled loops (numba) are ready before the robot's first tick, for the very calls its ticks make.

Each module compiles or loads its loops when its part is built (`load_compiled`), with the argument types of the
calls the robot makes later. If those types drifted apart (a float64 image where the camera gives float32, a
read-only array), numba would compile a second version in the middle of a tick: a stall of half a second or more
on a checkout's first run. A fresh process is the only place where "no second version" means anything, so the
robot runs in one.
"""

from __future__ import annotations

import json
import subprocess
import sys

PROBE = """
import json
import numpy as np
from atemr.config import load_config
from atemr.io.sim import depth, raycast
from atemr.msgs import Pose2D, Twist
from atemr.robot.core import Ticker
from atemr.robot.headless import build_headless_robot
from atemr.skills import hexpattern
from atemr.skills.localization import likelihood_field
from atemr.skills.nav import costmap, global_planner, local_planner, voxel_layer

loops = {"walk_rays": raycast._walk_rays, "traced": likelihood_field._traced, "sampled": likelihood_field._sampled,
         "marks": voxel_layer._marks, "box_hits": depth._box_hits, "cylinder_hits": depth._cylinder_hits,
         "weights": global_planner._weights_into, "cells": likelihood_field._cells_into,
         "clear_beams": costmap._clear_beams, "circles": raycast._circle_hits,
         "sectors": hexpattern._sector_stats, "finish": depth._finish, "rollouts": local_planner._rollout_poses,
         "rollouts_valid": local_planner._rollouts_valid}
robot = build_headless_robot(load_config(environ={}, overrides={"sim.camera_hz": 10.0, "sim.seed": 2}))
built = {name: len(loop.signatures) for name, loop in loops.items()}
inputs = robot.parts.inputs
robot.add(Ticker("test.joystick", lambda now: inputs.operate(Twist(0.3, 0.4), now)), 10.0)
robot.start()
robot.scheduler.run(duration=15.0)
# The global search's walk (many poses) as FIND POSITION makes it, on the robot's own field.
field = robot.parts.localization.localizer.field
rng = np.random.default_rng(0)
poses = np.column_stack([rng.uniform(0, 9, 3000), rng.uniform(-2, 8, 3000), rng.uniform(-3, 3, 3000)])
field.crossings(poses, (0.1, 0.0), rng.uniform(-5, 5, (90, 2)), 0.1)
# A plan on the robot's own costmap, and a replan after it changed (the weights patched in a window).
navigator = robot.parts.navigation.navigator
planner = global_planner.GlobalPlanner(navigator.costmap)
path = planner.plan((2.6, 2.6), (7.0, 3.0))
assert path is not None
navigator.costmap.cost[60:64, 60:64] = 200
planner.plan((2.6, 2.6), (7.0, 3.0))
# Every loop reached through the robot's own parts, whatever the run happened to meet: the cameras facing each
# piece of furniture and each person, the depth layer taking those frames, the field scoring particles.
sim = robot.parts.sim
targets = [((o.params[0] + o.params[2]) / 2, (o.params[1] + o.params[3]) / 2)
           for o in sim.scene.objects.values() if o.shape == "box"] + [(m.x_m, m.y_m) for m in sim.movers.items]
layer = robot.parts.navigation.voxels
for k, (tx, ty) in enumerate(targets):
    pose = Pose2D(tx - 1.2, ty, 0.0)
    image = sim.depth_camera.render(20.0 + k, pose, sim.scene, sim.movers)
    sim.camera.render(pose, sim.scene, sim.movers)
    layer.update(image, pose, sim.read_lidar(20.0 + k))
field.log_likelihood(poses[:500], rng.uniform(-5, 5, (60, 2)))
# The navigator's obstacle layer clearing a scan's beams through what it holds.
navigator.costmap.obstacles[40:80, 40:80] = True
navigator.costmap.update_from_scan(sim.read_lidar(30.0), sim.pose)
# The local planner following a plan on that costmap, and evading from inside the inscribed radius.
navigator.local.compute(Pose2D(2.6, 2.6, 0.0), Twist(0.2, 0.1), path.points, (7.0, 3.0), 0.1, zone=(1.0, 2.0))
near = Pose2D(*(float(v) for v in navigator.costmap.map.cell_to_world(39, 60)), 0.0)  # by the marked block
navigator.local.compute(near, Twist(), path.points, (7.0, 3.0), 0.1)
navigator.local.evade(near, Twist())
ran = {name: len(loop.signatures) for name, loop in loops.items()}
robot.shutdown()
print(json.dumps({"built": built, "ran": ran}))
"""


def test_each_loop_is_compiled_once_when_the_robot_is_built_and_never_in_a_tick() -> None:
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=300, check=True)
    counts = json.loads(out.stdout.strip().splitlines()[-1])
    assert counts["built"] == dict.fromkeys(counts["built"], 1), counts  # all ready before the first tick
    assert counts["ran"] == counts["built"], counts  # and no tick needed another version
