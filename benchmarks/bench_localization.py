"""Localization speed and accuracy: AMCL, ICP, and the pose error of the whole pipeline.

Rows (``python benchmarks/bench_localization.py`` or ``./benchmarks/run localization``):

* AMCL update (motion + likelihood field + resampling) at a fixed 2,000 particles × 60 beams on studio
  scans from the simulator: updates per second against the 20/s requirement (goal >= 1x);
* the likelihood-field weighting alone, vectorised over particles × beams, against the same table
  look-ups done per particle in a Python loop (the baseline), same answers; goal >= 10x;
* point-to-line ICP of two consecutive 360-beam simulator scans (k-d tree correspondences) against a
  simple point-to-point ICP with brute-force nearest neighbours and an SVD step (PythonRobotics'
  ``icp_matching``), both run to convergence from the same odometry guess; goal >= 2x;
* the ICP target of one scan with its line normals from neighbouring beams (the pipeline's) against the same
  from a k-d tree query of nearest neighbours: targets per second (goal >= 1x), and the median match error of
  each over the drive's consecutive scans;
* map agreement's beam walks (`LikelihoodField.crossings`: does each beam pass through a wall, under each
  pose), compiled, against the numpy walks they replaced (``numpy_baselines.py``), with the same answers: one
  thinned scan at the robot's pose (sampled every half cell, what the localizer does at every scan) and the
  same scan under 500 poses (sphere tracing, as the global search does); goal >= 1x;
* pose RMSE against ground truth over a seeded two-lap drive of the studio's living room: the
  localizer (AMCL + map EKF + monitor, started from the true start pose) against the 0.10 m target
  (goal >= 1x: ratio = target / ours), and, for scale, the wheel odometry alone over the same drive.
"""

from __future__ import annotations

import importlib.util
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from numpy_baselines import NumpyLikelihoodField

from atemr.io.sim.maps import load_map
from atemr.skills.localization.amcl import Amcl, AmclParams
from atemr.skills.localization.geometry import as_array, as_pose, compose, relative, transform_points
from atemr.skills.localization.icp import IcpTarget, icp
from atemr.skills.localization.likelihood_field import LikelihoodField
from atemr.skills.localization.localizer import Localizer
from atemr.skills.localization.map_agreement import AgreementParams
from atemr.skills.localization.scan import scan_points

ROOT = Path(__file__).resolve().parents[1]


def _simdrive() -> ModuleType:
    name = "atemr_test_simdrive"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "tests" / "skills" / "localization" / "simdrive.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def best_rate(fn: Callable[[], Any], repeats: int, min_s: float = 0.2) -> float:
    """Calls per second: the best of ``repeats`` timed batches (each at least ``min_s`` long)."""
    best = math.inf
    for _ in range(repeats):
        n, t0 = 0, time.perf_counter()
        while True:
            fn()
            n += 1
            dt = time.perf_counter() - t0
            if dt >= min_s:
                break
        best = min(best, dt / n)
    return 1.0 / best


def loop_log_likelihood(amcl: Amcl, particles: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Baseline: the same likelihood-field look-up, one particle at a time in Python."""
    out = np.empty(particles.shape[0])
    for i, pose in enumerate(particles):
        out[i] = amcl.field.log_likelihood(pose[None, :], points)[0]
    return out


def point_to_point_icp(src: np.ndarray, tgt: np.ndarray, guess: np.ndarray, iters: int = 60) -> np.ndarray:
    """Baseline: PythonRobotics-style ICP — brute-force nearest neighbours, SVD (Kabsch) step."""
    pose = guess.copy()
    for _ in range(iters):
        moved = transform_points(pose, src)
        d2 = ((moved[:, None, :] - tgt[None, :, :]) ** 2).sum(axis=2)
        q = tgt[np.argmin(d2, axis=1)]
        mc, qc = moved.mean(axis=0), q.mean(axis=0)
        u, _, vt = np.linalg.svd((moved - mc).T @ (q - qc))
        rot = vt.T @ u.T
        if np.linalg.det(rot) < 0:
            vt[1] *= -1
            rot = vt.T @ u.T
        dth = math.atan2(rot[1, 0], rot[0, 0])
        t = qc - rot @ mc
        step = np.array([t[0], t[1], dth])
        pose = compose(step, pose)
        if math.hypot(t[0], t[1]) < 1e-4 and abs(dth) < 1e-4:
            break
    return pose


def scan_target_row(rec: Any, tgt: np.ndarray, repeats: int, quick: bool) -> dict[str, Any]:
    """The scan matcher's target of a scan: line normals from neighbouring beams (what the pipeline builds)
    against a k-d tree query of each point's nearest neighbours, and the match error of each over the drive's
    consecutive scans."""
    errors_by: dict[str, list[float]] = {"beams": [], "tree": []}
    for j in range(0, len(rec.scans) - 1, 5 if quick else 1):
        s_pts, t_pts = scan_points(rec.scans[j + 1]), scan_points(rec.scans[j])
        g = as_pose(relative(as_array(rec.odom[j]), as_array(rec.odom[j + 1])))
        step = relative(as_array(rec.truth[j]), as_array(rec.truth[j + 1]))
        for name, target in (("beams", IcpTarget.from_scan(t_pts)), ("tree", IcpTarget(t_pts))):
            errors_by[name].append(math.hypot(*(as_array(icp(s_pts, target, g).pose)[:2] - step[:2])))
    beams, tree = (float(np.median(errors_by[k])) * 1000 for k in ("beams", "tree"))
    r_beams = best_rate(lambda: IcpTarget.from_scan(tgt), repeats)
    r_tree = best_rate(lambda: IcpTarget(tgt), repeats)
    return {"what": f"  ICP target of a 360-beam scan: normals from neighbouring beams vs a k-d tree query "
                    f"(median error over the drive's scans {beams:.2f} mm vs {tree:.2f} mm)",
            "ours": round(r_beams, 1), "baseline": round(r_tree, 1), "ratio": round(r_beams / r_tree, 2),
            "goal": 1.0, "unit": "targets/s"}


def crossings_rows(grid: Any, rec: Any, repeats: int) -> list[dict[str, Any]]:
    """Map agreement's beam walks, compiled, against the numpy ones they replaced: the same booleans."""
    ours, base = LikelihoodField(grid), NumpyLikelihoodField(grid)
    pts = scan_points(rec.scans[60], max_beams=AgreementParams().max_beams)  # as many beams as `measure` walks
    rng = np.random.default_rng(0)
    many = np.column_stack([rng.normal(rec.truth[60].x_m, 0.5, 500), rng.normal(rec.truth[60].y_m, 0.5, 500),
                            rng.uniform(-math.pi, math.pi, 500)])
    rows = []
    for what, poses in (("one pose (sampled every half cell)", as_array(rec.truth[60])[None, :]),
                        ("500 poses (sphere tracing)", many)):
        def walk(field: LikelihoodField, poses: np.ndarray = poses) -> np.ndarray:
            return field.crossings(poses, (0.1, 0.0), pts, 0.1)

        assert np.array_equal(walk(ours), walk(base))  # the same answers, or the comparison means nothing
        fast, slow = best_rate(lambda: walk(ours), repeats), best_rate(lambda: walk(base), repeats)
        rows.append({"what": f"  map agreement's beam walks, {len(pts)} beams x {what}: compiled vs numpy",
                     "ours": round(fast, 1), "baseline": round(slow, 1), "ratio": round(fast / slow, 2), "goal": 1.0,
                     "unit": "walks/s"})
    return rows


def run(quick: bool = False) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    rec = _simdrive().drive(seed=3, laps=1 if quick else 2, max_s=90.0)
    grid = load_map(ROOT / "atemr" / "worlds" / "studio" / "studio.yaml")
    repeats = 2 if quick else 5

    # AMCL at a fixed 2,000 particles, forced to update on every call
    params = AmclParams(min_particles=2000, max_particles=2000, max_beams=60, update_min_d_m=0.0,
                        update_min_a_rad=0.0)
    amcl = Amcl(grid, np.random.default_rng(0), params)
    amcl.initialize(rec.truth[0])
    clouds = [scan_points(s) for s in rec.scans]
    k = [0]

    def one_update() -> None:
        i = k[0] % len(rec.scans)
        if i == 0:
            amcl.initialize(rec.truth[0])
        amcl.update(rec.scans[i].t, rec.odom[i], clouds[i])
        k[0] += 1

    rate = best_rate(one_update, repeats)
    assert amcl.particles.shape[0] == 2000
    rows.append({"what": "AMCL update, 2,000 particles x 60 beams (vs the 20/s requirement)", "ours": round(rate, 1),
                 "baseline": 20.0, "ratio": round(rate / 20.0, 2), "goal": 1.0, "unit": "updates/s"})

    pts = scan_points(rec.scans[40], max_beams=60)
    particles = amcl.particles.copy()
    assert np.allclose(amcl.field.log_likelihood(particles, pts), loop_log_likelihood(amcl, particles, pts))
    fast = best_rate(lambda: amcl.field.log_likelihood(particles, pts), repeats)
    slow = best_rate(lambda: loop_log_likelihood(amcl, particles, pts), 1 if quick else 2)
    rows.append({"what": "  likelihood field, 2,000 x 60: vectorised vs per-particle Python loop",
                 "ours": round(fast, 1), "baseline": round(slow, 1), "ratio": round(fast / slow, 1), "goal": 10.0,
                 "unit": "weightings/s"})

    # ICP on two consecutive 360-beam scans, from the odometry guess
    i = 120
    src, tgt = scan_points(rec.scans[i + 1]), scan_points(rec.scans[i])
    guess = relative(as_array(rec.odom[i]), as_array(rec.odom[i + 1]))
    truth = relative(as_array(rec.truth[i]), as_array(rec.truth[i + 1]))
    ours = icp(src, tgt, as_pose(guess))
    base = point_to_point_icp(src, tgt, guess)
    err_ours = math.hypot(*(as_array(ours.pose)[:2] - truth[:2]))
    err_base = math.hypot(*(base[:2] - truth[:2]))
    r_ours = best_rate(lambda: icp(src, tgt, as_pose(guess)), repeats)
    r_base = best_rate(lambda: point_to_point_icp(src, tgt, guess), 1 if quick else 2)
    rows.append({"what": f"ICP, two 360-beam scans: point-to-line + k-d tree ({ours.iterations} it, "
                         f"err {err_ours * 1000:.1f} mm) vs point-to-point brute force (err {err_base * 1000:.1f} mm)",
                 "ours": round(r_ours, 1), "baseline": round(r_base, 1), "ratio": round(r_ours / r_base, 1),
                 "goal": 2.0, "unit": "matches/s"})

    rows.append(scan_target_row(rec, tgt, repeats, quick))
    rows.extend(crossings_rows(grid, rec, repeats))

    # Pose RMSE of the whole pipeline over the drive
    loc = Localizer(grid, np.random.default_rng(1))
    loc.set_initial_pose(0.0, rec.truth[0])
    errors, odo_errors = [], []
    start = as_array(rec.truth[0])
    for j, scan in enumerate(rec.scans):
        loc.update(scan.t, rec.odom[j], scan)
        e = loc.estimate
        errors.append(math.inf if e is None else e.pose.distance_to(rec.truth[j]))
        odo = as_pose(compose(start, as_array(rec.odom[j])))
        odo_errors.append(odo.distance_to(rec.truth[j]))
    rmse = float(np.sqrt(np.mean(np.square(errors))))
    odo_rmse = float(np.sqrt(np.mean(np.square(odo_errors))))
    rows.append({"what": f"pose RMSE vs ground truth, {len(rec.scans) / 10:.0f} s seeded drive (target 0.10 m; "
                         f"ratio = target / ours)", "ours": round(rmse, 4), "baseline": 0.10,
                 "ratio": round(0.10 / rmse, 1), "goal": 1.0, "unit": "m"})
    rows.append({"what": "  wheel odometry alone over the same drive (ratio = its RMSE / ours)",
                 "ours": round(rmse, 4), "baseline": round(odo_rmse, 4), "ratio": round(odo_rmse / rmse, 1),
                 "goal": None, "unit": "m"})
    return rows


if __name__ == "__main__":
    quick = "--quick" in sys.argv
    for row in run(quick=quick):
        print(f"{row['what']}: ours {row['ours']} {row['unit']}, baseline {row['baseline']}, ratio {row['ratio']}"
              f" (goal {row['goal']})")
