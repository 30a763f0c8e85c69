"""Navigation quality (issue 8's "Done when"): seeded random start/goal pairs through the real command.

    python benchmarks/nav_quality.py                       # 20 pairs on studio and the 4 external maps
    python benchmarks/nav_quality.py --worlds studio --pairs 5 --json out.json
    python benchmarks/nav_quality.py --jobs 1              # one run at a time

For each world, `pick_pairs` draws start/goal poses the way an operator could click them: in free space
of the map with the robot's inflation (the navigator's own costmap: static cost below INSCRIBED), clear
of what the world holds that the map does not (unmapped furniture, with the obstacle layer's padding),
away from drop zones (the studio's balcony edge is free in the map: the cliff sensors, not the map,
keep the robot off it), at least ``--min-distance`` apart and connected (same component of that free
space). Each pair is then run as a subprocess with the command an operator would type,

    atemr mission run --world W --headless --seed N --json --start X,Y,YAW --goal X,Y,YAW

(moving people and the pet of the studio included), and its JSON result judged against the simulator's
ground truth: reached (outcome ``reached`` and the *true* pose within the navigator's tolerances),
collisions, falls, and the RMSE of the localized pose. One markdown table per world and the totals are
printed; the exit code is 1 when the bar is missed (≥ 95 % reached, no collision, no fall, pose RMSE
below 0.10 m on every run), 0 otherwise. Each run has one core, as the robot has: ``--jobs N`` runs N pairs at
once (default: one per core this process may use), each in a data directory of its own. The runs are seeded and
independent, so the rows are the same whatever N; only the wall time falls.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from atemr.domain.maps import OCCUPIED, OccupancyMap
from atemr.io.sim.scene import Scene
from atemr.io.sim.world import World, load_world
from atemr.msgs import Pose2D
from atemr.skills.nav.costmap import INSCRIBED, Costmap
from atemr.skills.nav.navigator import NavParams

ROOT = Path(__file__).resolve().parents[1]
EXTERNAL = ROOT.parent / "shared" / "worlds" / "external"
EXTERNAL_MAPS = ("nav2_depot", "nav2_tb3_sandbox", "nav2_warehouse", "turtlebot3_world")
#: The bar of issue 8.
MIN_REACHED = 0.95
MAX_RMSE_M = 0.10


@dataclass(frozen=True)
class Pair:
    """One run: where the robot is put, where it is sent, the simulation's seed."""

    world: str
    index: int
    seed: int
    start: Pose2D
    goal: Pose2D

    @property
    def distance_m(self) -> float:
        return self.start.distance_to(self.goal)


def default_worlds() -> list[str]:
    """The studio (moving people) and the external maps that are present."""
    return ["studio"] + [str(EXTERNAL / f"{name}.yaml") for name in EXTERNAL_MAPS
                         if (EXTERNAL / f"{name}.yaml").is_file()]


def world_label(world: str) -> str:
    return Path(world).stem if world.endswith(".yaml") else world


def free_space(world: World, params: NavParams | None = None, *, margin_m: float = 0.05
               ) -> tuple[np.ndarray, np.ndarray]:
    """(where a start or goal may be, connected component label of each cell of the space the robot can use).

    Usable: the navigator's static costmap (of the map with the mapped furniture's whole footprint: a table top
    above the lidar's plane too) below INSCRIBED with ``margin_m`` to spare, farther than the inscribed
    radius plus the obstacle layer's padding from unmapped furniture, not over or next to a drop zone. Start/goal
    cells keep ``margin_m`` more from everything (the goal check judges the estimate, which may be off by a few cm).
    """
    p = params or NavParams()
    res = world.map.resolution_m
    # The robot's whole volume must fit: the mapped furniture counts at every height, the footprint of a table
    # top the lidar (and so the map) sees only the legs of included, as if it were drawn in the map.
    scene = Scene(world)
    rows, cols = np.indices(world.map.data.shape)
    xs, ys = world.map.cell_to_world(rows, cols)
    known = world.map.occupied.copy()
    for item in world.furniture:
        if item.mapped:
            known |= item.contains(xs, ys)
    grid = world.map.data.copy()
    grid[known] = OCCUPIED
    costmap = Costmap(OccupancyMap(grid, res, world.map.origin, name=world.map.name), p.costmap)
    usable = costmap.static_cost < INSCRIBED
    # A passage counts when the robot fits with a cell to spare (0.7 m for KAY: the studio's 0.8 m doorways),
    # not through a one-cell slit of the inscribed zone (a 0.65 m gap between a table and a wall).
    walls = known | world.map.unknown
    usable &= ndimage.distance_transform_edt(~walls, sampling=res) > p.costmap.inscribed_radius_m + margin_m
    unmapped = scene.blocked & ~known
    reach = p.costmap.inscribed_radius_m + p.costmap.obstacle_padding_m
    if unmapped.any():
        usable &= ndimage.distance_transform_edt(~unmapped, sampling=res) > reach
    if scene.drop_mask.any():
        usable &= ndimage.distance_transform_edt(~scene.drop_mask, sampling=res) > reach + 0.2
    labels, _ = ndimage.label(usable)  # 4-connected: the planner cuts no corners
    room = ndimage.distance_transform_edt(usable, sampling=res) > margin_m + res
    return usable & room, labels


def pick_pairs(world_name: str, count: int, seed: int, *, min_distance_m: float = 2.0) -> list[Pair]:
    """``count`` seeded start/goal pairs of one world (see the module doc); the same arguments, the same pairs."""
    world = load_world(world_name)
    ok, labels = free_space(world)
    rows, cols = np.nonzero(ok)
    if len(rows) == 0:
        raise SystemExit(f"{world_name}: no free space for a start or goal")
    xs, ys = world.map.cell_to_world(rows, cols)
    comp = labels[rows, cols]
    # The robot is put at its start while people and pets are at theirs: not on a person's first path point,
    # nor anywhere a pet may be when the run begins (its area); goals may be anywhere.
    clear = np.ones(len(rows), dtype=bool)
    for mover in world.movers:
        reach = mover.radius_m + NavParams().costmap.inscribed_radius_m + 0.1
        if mover.area is not None:
            x0, y0, x1, y1 = mover.area
            clear &= ~((xs > x0 - reach) & (xs < x1 + reach) & (ys > y0 - reach) & (ys < y1 + reach))
        else:
            clear &= np.hypot(xs - mover.path[0][0], ys - mover.path[0][1]) > reach
    starts = np.flatnonzero(clear)
    rng = np.random.default_rng([seed, sum(world_label(world_name).encode())])
    pairs: list[Pair] = []
    for index in range(count):
        for _ in range(1000):
            a = int(starts[rng.integers(len(starts))])
            far = np.flatnonzero((comp == comp[a]) & (np.hypot(xs - xs[a], ys - ys[a]) >= min_distance_m))
            if len(far):
                b = int(far[rng.integers(len(far))])
                break
        else:
            raise SystemExit(f"{world_name}: no two connected free poses {min_distance_m} m apart")
        yaw_a, yaw_b = (float(v) for v in rng.uniform(-math.pi, math.pi, 2))
        pairs.append(Pair(world_name, index, seed + index, Pose2D(round(float(xs[a]), 3), round(float(ys[a]), 3),
                                                                  round(yaw_a, 3)),
                          Pose2D(round(float(xs[b]), 3), round(float(ys[b]), 3), round(yaw_b, 3))))
    return pairs


def command(pair: Pair, *, data_dir: Path, timeout_s: float, kidnap: str | None = None) -> list[str]:
    """The `atemr mission run` command line of one pair."""
    def pose(p: Pose2D) -> str:
        return f"{p.x_m},{p.y_m},{p.yaw_rad}"

    out = [sys.executable, "-m", "atemr", "mission", "run", "--world", pair.world, "--headless",
           "--seed", str(pair.seed), "--json", f"--start={pose(pair.start)}", f"--goal={pose(pair.goal)}",
           "--data-dir", str(data_dir), "--timeout", f"{timeout_s:g}"]
    if kidnap is not None:
        out.append(f"--kidnap={kidnap}")  # "=": a negative number must not read as an option
    return out


def judge(pair: Pair, result: dict[str, Any], params: NavParams | None = None) -> dict[str, Any]:
    """One run's row: reached (by the robot's account and within tolerance by ground truth), collisions, ..."""
    p = params or NavParams()
    truth = result.get("true_pose")
    goal = pair.goal
    if truth is not None:
        err_xy = math.hypot(truth["x_m"] - goal.x_m, truth["y_m"] - goal.y_m)
        err_yaw = abs(math.atan2(math.sin(truth["yaw_rad"] - goal.yaw_rad), math.cos(truth["yaw_rad"] - goal.yaw_rad)))
    else:
        err_xy = err_yaw = math.inf
    within = err_xy <= p.xy_tolerance_m and err_yaw <= p.yaw_tolerance_rad
    pose_error = result.get("pose_error") or {}
    return {
        "world": world_label(pair.world), "index": pair.index, "seed": pair.seed,
        "start": [pair.start.x_m, pair.start.y_m, pair.start.yaw_rad],
        "goal": [goal.x_m, goal.y_m, goal.yaw_rad], "distance_m": round(pair.distance_m, 2),
        "outcome": result.get("outcome"), "reason": result.get("reason"),
        "reached": result.get("outcome") == "reached" and within,
        "true_error_m": round(err_xy, 3), "true_error_rad": round(err_yaw, 3),
        "collisions": int(result.get("collisions", 0)), "collision_list": result.get("collision_list", []),
        "falls": len(result.get("falls", [])),
        "rmse_m": pose_error.get("rmse_m"), "max_error_m": pose_error.get("max_m"),
        "time_s": result.get("duration_s"),
    }


def run_pair(pair: Pair, *, data_dir: Path, timeout_s: float, camera: bool = False) -> dict[str, Any]:
    """Run one pair through the real command; a crash or unreadable output is a failed row, not an exception.

    The simulated camera is off unless ``camera`` (navigation does not look at it, and rendering it halves
    the speed of a run), set through the configuration's environment layer (``ATEMR_SIM__CAMERA_HZ=0``).
    """
    env = dict(os.environ)
    if not camera:
        env["ATEMR_SIM__CAMERA_HZ"] = "0"
    # The package under test wins over any installed copy (a worktree run from its root).
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    t0 = time.perf_counter()
    proc = subprocess.run(command(pair, data_dir=data_dir, timeout_s=timeout_s), capture_output=True, text=True,
                          env=env, cwd=ROOT, check=False)
    wall = time.perf_counter() - t0
    try:
        result = json.loads(proc.stdout)
    except json.JSONDecodeError:
        tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        result = {"outcome": "crashed", "reason": f"exit {proc.returncode}: {tail}"}
    row = judge(pair, result)
    row["wall_s"] = round(wall, 1)
    return row


def run_pairs(pairs: list[Pair], *, data_dir: Path, jobs: int, timeout_s: float, camera: bool = False
              ) -> Iterator[tuple[Pair, dict[str, Any]]]:
    """(pair, row) for every pair, in the pairs' order, ``jobs`` runs at a time (threads that each wait on one
    `run_pair` subprocess); each run gets a data directory of its own under ``data_dir``."""
    def one(pair: Pair) -> dict[str, Any]:
        own = data_dir / f"{world_label(pair.world)}-{pair.index}"
        own.mkdir(parents=True, exist_ok=True)
        return run_pair(pair, data_dir=own, timeout_s=timeout_s, camera=camera)

    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        yield from zip(pairs, pool.map(one, pairs), strict=True)


def default_jobs() -> int:
    """One run per core this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    rmse = [r["rmse_m"] for r in rows if r["rmse_m"] is not None]
    times = [r["time_s"] for r in rows if r["reached"] and r["time_s"] is not None]
    return {
        "pairs": len(rows), "reached": sum(r["reached"] for r in rows),
        "collisions": sum(r["collisions"] for r in rows), "falls": sum(r["falls"] for r in rows),
        "max_rmse_m": max(rmse) if rmse else None, "mean_rmse_m": float(np.mean(rmse)) if rmse else None,
        "mean_time_s": float(np.mean(times)) if times else None,
        "no_estimate": sum(r["rmse_m"] is None for r in rows),
    }


def passes(s: dict[str, Any]) -> bool:
    """Issue 8's bar for one world (or the totals)."""
    return (s["pairs"] > 0 and s["reached"] >= MIN_REACHED * s["pairs"] and s["collisions"] == 0
            and s["falls"] == 0 and s["no_estimate"] == 0 and s["max_rmse_m"] is not None
            and s["max_rmse_m"] < MAX_RMSE_M)


def _m(value: float | None, digits: int = 3) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def table(by_world: dict[str, list[dict[str, Any]]]) -> str:
    """The markdown table: one line per world and the totals."""
    lines = ["| world | pairs | reached | collisions | falls | max pose RMSE (m) | mean pose RMSE (m) | "
             "mean time (s) | bar |", "|---|---|---|---|---|---|---|---|---|"]
    everything: list[dict[str, Any]] = []
    for world, rows in by_world.items():
        everything += rows
        s = summary(rows)
        lines.append(f"| {world} | {s['pairs']} | {s['reached']} | {s['collisions']} | {s['falls']} | "
                     f"{_m(s['max_rmse_m'])} | {_m(s['mean_rmse_m'])} | {_m(s['mean_time_s'], 1)} | "
                     f"{'yes' if passes(s) else 'NO'} |")
    s = summary(everything)
    lines.append(f"| **total** | {s['pairs']} | {s['reached']} ({s['reached'] / max(s['pairs'], 1):.0%}) | "
                 f"{s['collisions']} | {s['falls']} | {_m(s['max_rmse_m'])} | {_m(s['mean_rmse_m'])} | "
                 f"{_m(s['mean_time_s'], 1)} | {'yes' if passes(s) else 'NO'} |")
    return "\n".join(lines)


def failures(rows: list[dict[str, Any]]) -> list[str]:
    out = []
    for r in rows:
        bad = []
        if not r["reached"]:
            bad.append(f"{r['outcome']}" + (f" ({r['reason']})" if r["reason"] else "")
                       + f", {r['true_error_m']:.2f} m / {r['true_error_rad']:.2f} rad from the goal")
        if r["collisions"]:
            bad.append("collided with " + ", ".join(c["what"] for c in r["collision_list"]))
        if r["falls"]:
            bad.append("fell")
        if r["rmse_m"] is None or r["rmse_m"] >= MAX_RMSE_M:
            bad.append(f"pose RMSE {_m(r['rmse_m'])} m")
        if bad:
            out.append(f"- {r['world']} #{r['index']} seed {r['seed']} start {r['start']} goal {r['goal']}: "
                       + "; ".join(bad))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", nargs="+", metavar="WORLD",
                        help="world names or map/world YAMLs (default: studio and the four external maps)")
    parser.add_argument("--pairs", type=int, default=20, help="pairs per world (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the pair draw (run i uses seed + i)")
    parser.add_argument("--only", type=int, nargs="+", metavar="I", help="run only these pair indices")
    parser.add_argument("--min-distance", type=float, default=2.0, help="least start-goal distance, m")
    parser.add_argument("--timeout", type=float, default=300.0, help="robot seconds per mission")
    parser.add_argument("--camera", action="store_true", help="keep the simulated camera on (slower)")
    parser.add_argument("--json", type=Path, help="write every run's row here")
    parser.add_argument("--jobs", type=int, default=default_jobs(),
                        help="runs at once, one core each (default: one per core, here %(default)s)")
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error(f"--jobs must be at least 1, got {args.jobs}")
    worlds = args.worlds or default_worlds()
    by_world: dict[str, list[dict[str, Any]]] = {}
    pairs = [pair for world in worlds
             for pair in pick_pairs(world, args.pairs, args.seed, min_distance_m=args.min_distance)
             if args.only is None or pair.index in args.only]
    with tempfile.TemporaryDirectory(prefix="atemr-navq-") as tmp:
        for world in worlds:  # every world listed, even one whose pairs --only left out
            by_world.setdefault(world_label(world), [])
        for pair, row in run_pairs(pairs, data_dir=Path(tmp), jobs=args.jobs, timeout_s=args.timeout,
                                   camera=args.camera):
            label = world_label(pair.world)
            by_world[label].append(row)
            mark = "ok" if row["reached"] and not row["collisions"] else "FAIL"
            print(f"{label} #{pair.index}: {mark} {row['outcome']} {row['distance_m']:.1f} m in "
                  f"{_m(row['time_s'], 1)} s, RMSE {_m(row['rmse_m'])} m, {row['collisions']} collisions "
                  f"({row['wall_s']:.0f} s wall)", file=sys.stderr, flush=True)
    if args.json is not None:
        args.json.write_text(json.dumps(by_world, indent=2))
    print(table(by_world))
    bad = [line for rows in by_world.values() for line in failures(rows)]
    if bad:
        print("\nfailed runs:\n" + "\n".join(bad))
    ok = all(passes(summary(rows)) for rows in by_world.values() if rows)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
