"""The depth camera's obstacle layer (issue 24): how many D415 frames per second one core folds into the
costmap, against the camera's 10 frames per second.

Rows (``python benchmarks/bench_depth.py`` or ``./benchmarks/run depth``), CPU time of this single-threaded
process (one core), so the figures do not depend on what else a shared machine runs:

* depth frame → obstacle-layer update at 424 x 240: point cloud in the base frame (stride 2), clearing through
  the marked voxels in view, marking between the floor margin and the robot's height, columns to the costmap;
  frames per second against the camera's 10 Hz (goal >= 3x: at least 30 updates per second);
* the same plus the costmap's recomputation the planners then read (inflation over the changed box): no goal,
  the price of the whole path to a plan;
* one simulated depth frame rendered at 424 x 240, frames per second against the 10 Hz it is rendered at in
  every simulated robot (goal >= 1x);
* the same frame with its noise and dropouts drawn in one compiled loop, against numpy's passes and array draws
  (``numpy_baselines.py``), interleaved, the same images to the bit: no goal, what the compiled finish saves.

The frames come from the simulated D415 in the studio (its dining table on legs and the flower tray under the
lidar's plane, plus a box and a cabinet put in for the benchmark), from poses all round the living room, with
the noise of the real camera: pre-rendered, so the first rows time the layer alone.
"""

from __future__ import annotations

import math
import sys
import time
from typing import Any

import numpy as np
from bench_sim import interleaved_ms
from numpy_baselines import NumpyFinishDepthCamera

from atemr.io.sim.depth import DepthCamera
from atemr.io.sim.simulation import SimParams, build_simulation
from atemr.io.sim.world import Furniture
from atemr.msgs import DepthImage, Pose2D
from atemr.skills.body import KAY
from atemr.skills.nav.costmap import Costmap
from atemr.skills.nav.voxel_layer import VoxelLayer, VoxelLayerParams

CAMERA_HZ = 10.0


def frames(count: int) -> tuple[Any, list[tuple[DepthImage, Pose2D]]]:
    """(simulation, [(frame, pose)]) from ``count`` poses round the studio's living room."""
    sim = build_simulation("studio", 0, params=SimParams(depth_hz=CAMERA_HZ))
    sim.scene.add_object(Furniture("box", "box", (3.3, 3.3, 3.6, 3.6), 0.1))
    sim.scene.add_object(Furniture("cabinet", "box", (4.2, 1.6, 4.6, 2.2), 1.1, clearance_m=0.9))
    rng = np.random.default_rng(0)
    out = []
    for _ in range(count):
        while True:
            pose = Pose2D(float(rng.uniform(2.3, 4.6)), float(rng.uniform(1.5, 3.8)), float(rng.uniform(-math.pi,
                                                                                                           math.pi)))
            if sim.clearance_at(pose.x_m, pose.y_m).clearance_m > 0.05:
                break
        out.append((sim.depth_camera.render(0.0, pose, sim.scene, sim.movers), pose))
    return sim, out


def layer_rows(sim: Any, shots: list[tuple[DepthImage, Pose2D]], rounds: int) -> list[dict[str, Any]]:
    layer = VoxelLayer(Costmap(sim.world.map), VoxelLayerParams.for_body(KAY))
    layer.update(*shots[0])  # warm-up: the projector's rays
    t0 = time.process_time()
    for _ in range(rounds):
        for image, pose in shots:
            layer.update(image, pose)
    rate = rounds * len(shots) / (time.process_time() - t0)
    t0 = time.process_time()
    for _ in range(rounds):
        for image, pose in shots:
            layer.update(image, pose)
            _ = layer.costmap.cost  # the planners' view, recomputed after the layer changed
    with_costmap = rounds * len(shots) / (time.process_time() - t0)
    return [
        {"what": "depth frame 424x240 -> obstacle-layer update (updates/s) vs the D415's 10 Hz",
         "ours": round(rate, 1), "baseline": CAMERA_HZ, "ratio": round(rate / CAMERA_HZ, 2), "goal": 3.0,
         "unit": "updates/s"},
        {"what": "  the same plus the costmap's inflation the planners read", "ours": round(with_costmap, 1),
         "baseline": CAMERA_HZ, "ratio": round(with_costmap / CAMERA_HZ, 2), "goal": None, "unit": "updates/s"},
    ]


def render_row(sim: Any, shots: list[tuple[DepthImage, Pose2D]]) -> dict[str, Any]:
    t0 = time.process_time()
    for _, pose in shots:
        sim.depth_camera.render(0.0, pose, sim.scene, sim.movers)
    fps = len(shots) / (time.process_time() - t0)
    return {"what": "simulated D415 frame 424x240 (frames/s) vs the 10 Hz it runs at", "ours": round(fps, 1),
            "baseline": CAMERA_HZ, "ratio": round(fps / CAMERA_HZ, 2), "goal": 1.0, "unit": "frames/s"}


def finish_row(sim: Any, shots: list[tuple[DepthImage, Pose2D]]) -> dict[str, Any]:
    """The frame rendered with its finish (z-depth, the stereo noise, the range and the dropouts) in one compiled
    loop against numpy's passes and ``Generator``'s array draws (`numpy_baselines.py`), interleaved: the same
    poses, and the same images to the bit from identically seeded generators."""
    params = sim.depth_camera.params
    ours = DepthCamera(params, np.random.default_rng(1))
    base = NumpyFinishDepthCamera(params, np.random.default_rng(1))
    for _, pose in shots:
        a = ours.render(0.0, pose, sim.scene, sim.movers).depth_m
        b = base.render(0.0, pose, sim.scene, sim.movers).depth_m
        if a.tobytes() != b.tobytes():
            raise AssertionError(f"the compiled finish drew another image than numpy's at {pose}")
    calls = [(0.0, pose, sim.scene, sim.movers) for _, pose in shots]
    ours_ms, base_ms = interleaved_ms(ours.render, base.render, calls)
    return {"what": "  the same, its noise and dropouts drawn in one compiled loop (ms/frame) vs numpy's passes",
            "ours": round(ours_ms, 3), "baseline": round(base_ms, 3), "ratio": round(base_ms / ours_ms, 2),
            "goal": None, "unit": "ms"}


def run(quick: bool = False) -> list[dict[str, Any]]:
    sim, shots = frames(10 if quick else 40)
    return [*layer_rows(sim, shots, 1 if quick else 5), render_row(sim, shots), finish_row(sim, shots)]


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        goal = f"goal >= {row['goal']}" if row["goal"] is not None else ""
        print(f"{row['what']:<72} ours {row['ours']:>9} {row['unit']:<10} baseline {row['baseline']:>6} "
              f"ratio {row['ratio']:>7} {goal}")
