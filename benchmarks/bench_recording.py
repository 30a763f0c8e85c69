"""Recording every run to MCAP: what it costs the whole robot's tick rate, and how big a recording grows.

The whole simulated robot (CAN, motors, agent, localization, navigation: `atemr.robot.headless`) runs a goal
across the studio and back, as fast as the CPU allows, once without a recording and once recording to MCAP
(`atemr.robot.recorder` → `atemr.io.recording.writer_process`, what a paced robot uses, and the inline writer
of headless runs, which encodes and writes on the robot's own thread). Each run is a fresh interpreter (runs in
one process slowed down as robots piled up on its heap, so whichever ran first looked fastest: the order, not the
recording, made most of the difference). A round runs each case back to back, and the ratio is the median of the
rounds' ratios: this shared machine's speed drifts by 10-30 % over minutes, more than recording costs, while a
round's runs follow each other within seconds.
Rows:

* robot seconds per wall second recorded vs not, camera off, with the paced robot's writer process
  (``trace.writer: process``; goal: at least 0.9, at most 10 % slower) and with the headless inline writer;
* the same with the simulated camera on (10 fps) and recorded as JPEG at 2 fps, against the camera on and
  not recorded: once with a viewer keeping the camera rendering in both runs (the dashboard open, or a real
  camera, which delivers its frames anyway; goal 0.9 as above), and once headless with nobody watching, where
  the recording alone makes the simulator render the frames it keeps (the row then includes rendering them,
  which is the simulator's cost, not the recording's; no goal);
* the recording's size per hour of robot time, camera off and camera at 2 fps.

Run: ``.venv/bin/python benchmarks/run recording`` (or ``atemr bench recording``).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from atemr.config import load_config
from atemr.msgs import Pose2D
from atemr.robot.headless import build_headless_robot


def robot_run(seconds: float, folder: Path, *, writer: str | None, camera_hz: float,
              watched: bool = False) -> tuple[float, int]:
    """Wall seconds for ``seconds`` of robot time, and the recording's size in bytes (0 when not recording).
    ``writer``: the recording's ``trace.writer`` (None: no recording); ``watched``: a viewer keeps the simulated
    camera rendering every frame, as the dashboard does while it runs."""
    path = folder / f"bench-{time.perf_counter_ns()}.mcap"
    overrides: dict[str, Any] = {"data_dir": str(folder), "sim.camera_hz": 10.0 if camera_hz else 0.0,
                                 "trace.camera_hz": camera_hz, "trace.max_file_mb": 4096.0}
    if writer is not None:
        overrides["trace.file"] = str(path)
        overrides["trace.writer"] = writer
    robot = build_headless_robot(load_config(environ={}, overrides=overrides))
    if watched and robot.parts.sim is not None:
        robot.parts.sim.camera_source.want("viewer", lambda now: True)
    agent = robot.parts.agent
    with robot:
        robot.run(until=3.0)
        agent.submit("set_auto")
        start = time.perf_counter()
        t = 3.0
        goals = [Pose2D(6.0, 1.1, 0.0), Pose2D(2.6, 2.6, 0.0)]
        while t < seconds:
            if agent.state == "IDLE.AUTO":
                agent.submit("goal", goal=goals[0])
                goals.reverse()
            t += 1.0
            robot.run(until=t)
        took = time.perf_counter() - start
    return took, path.stat().st_size if writer is not None else 0


ROOT = Path(__file__).resolve().parents[1]


def fresh_run(seconds: float, folder: Path, *, writer: str | None, camera_hz: float,
              watched: bool = False) -> tuple[float, int]:
    """`robot_run` in a fresh interpreter (this file run with ``--trial``), so no run inherits another's heap."""
    trial = json.dumps({"seconds": seconds, "folder": str(folder), "writer": writer, "camera_hz": camera_hz,
                        "watched": watched})
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, __file__, "--trial", trial], cwd=ROOT, env=env, capture_output=True,
                          text=True, check=True)
    took, size = json.loads(done.stdout.strip().splitlines()[-1])
    return float(took), int(size)


def paired(seconds: float, folder: Path, camera_hz: float, writers: tuple[str, ...], *, rounds: int,
           watched: bool = False) -> dict[str | None, list[tuple[float, int]]]:
    """Every round runs no recording and then each writer back to back, each in a fresh interpreter: (wall
    seconds, size) per round, by writer (None: not recorded)."""
    out: dict[str | None, list[tuple[float, int]]] = {}
    for _ in range(rounds):
        for writer in (None, *writers):
            out.setdefault(writer, []).append(fresh_run(seconds, folder, writer=writer, camera_hz=camera_hz,
                                                        watched=watched))
    return out


def run(quick: bool = False) -> list[dict[str, Any]]:
    seconds = 20.0 if quick else 30.0
    span = seconds - 3.0
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        sizes = {}
        cases = ((0.0, False, "camera off", ("process", "inline")),
                 (2.0, True, "camera 10 fps watched, recorded at 2 fps", ("process",)),
                 (2.0, False, "camera 10 fps unwatched: rendered only for the recording, at 2 fps", ("process",)))
        for camera_hz, watched, label, writers in cases:
            runs = paired(seconds, folder, camera_hz, writers, rounds=3 if quick else 7, watched=watched)
            counts = watched or not camera_hz  # the recording's own cost, without the simulator's rendering
            plain = [took for took, _ in runs[None]]
            for writer in writers:
                recorded = [took for took, _ in runs[writer]]
                # the median of each round's ratio: this machine's speed drifts over minutes, a round's two runs
                # follow each other within seconds
                ratio = statistics.median(p / r for p, r in zip(plain, recorded, strict=True))
                how = {"process": "paced robot's writer process", "inline": "headless, written inline"}[writer]
                rows.append({"what": f"whole robot, robot s per wall s, recording ({how}) vs none ({label}; median "
                                     f"of {len(plain)} rounds' ratios)",
                             "ours": span / statistics.median(recorded), "baseline": span / statistics.median(plain),
                             "ratio": ratio, "goal": 0.9 if writer == "process" and counts else None,
                             "unit": "x real time"})
            if counts:
                sizes["camera off" if not camera_hz else "camera 10 fps, recorded at 2 fps"] = \
                    runs["process"][-1][1] / seconds * 3600 / 1e6
        for label, mb in sizes.items():
            rows.append({"what": f"recording size per hour of robot time, goals back and forth ({label})",
                         "ours": mb, "baseline": None, "ratio": None, "goal": None, "unit": "MB/h"})
    return rows


if __name__ == "__main__" and sys.argv[1:2] == ["--trial"]:
    spec = json.loads(sys.argv[2])
    print(json.dumps(robot_run(spec["seconds"], Path(spec["folder"]), writer=spec["writer"],
                               camera_hz=spec["camera_hz"], watched=spec["watched"])))
