"""Recording every run to MCAP: what it costs the whole robot's tick rate, and how big a recording grows.

The whole simulated robot (CAN, motors, agent, localization, navigation: `atemr.robot.headless`) runs a goal
across the studio and back, as fast as the CPU allows, once without a recording and once recording to MCAP
(`atemr.robot.recorder` → `atemr.io.recording.mcap_writer`; headless, the writer works inline, so its
compression and file writes are inside the measured time: an upper bound of what the robot's thread pays
on a paced robot, where a thread writes). Runs alternate and the best of each is kept (a shared machine).
Rows:

* robot seconds per wall second recorded vs not, camera off (goal: at least 0.9, at most 10 % slower);
* the same with the simulated camera on (10 fps) and recorded as JPEG at 2 fps, against the camera on and
  not recorded;
* the recording's size per hour of robot time, camera off and camera at 2 fps.

Run: ``.venv/bin/python benchmarks/run recording`` (or ``atemr bench recording``).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

from atemr.config import load_config
from atemr.msgs import Pose2D
from atemr.robot.headless import build_headless_robot


def robot_run(seconds: float, folder: Path, *, record: bool, camera_hz: float) -> tuple[float, int]:
    """Wall seconds for ``seconds`` of robot time, and the recording's size in bytes (0 when not recording)."""
    path = folder / f"bench-{time.perf_counter_ns()}.mcap"
    overrides: dict[str, Any] = {"data_dir": str(folder), "sim.camera_hz": 10.0 if camera_hz else 0.0,
                                 "trace.camera_hz": camera_hz, "trace.max_file_mb": 4096.0}
    if record:
        overrides["trace.file"] = str(path)
    robot = build_headless_robot(load_config(environ={}, overrides=overrides))
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
    return took, path.stat().st_size if record else 0


def best(seconds: float, folder: Path, camera_hz: float) -> tuple[float, float, int]:
    """Best wall time not recorded, recorded, and the recording's size (two alternating runs each)."""
    plain, recorded, size = float("inf"), float("inf"), 0
    for _ in range(2):
        plain = min(plain, robot_run(seconds, folder, record=False, camera_hz=camera_hz)[0])
        took, size = robot_run(seconds, folder, record=True, camera_hz=camera_hz)
        recorded = min(recorded, took)
    return plain, recorded, size


def run(quick: bool = False) -> list[dict[str, Any]]:
    seconds = 20.0 if quick else 60.0
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        sizes = {}
        for camera_hz, label in ((0.0, "camera off"), (2.0, "camera 10 fps, recorded at 2 fps")):
            plain, recorded, size = best(seconds, folder, camera_hz)
            span = seconds - 3.0
            rows.append({"what": f"whole robot, robot s per wall s, recording on vs off ({label})",
                         "ours": span / recorded, "baseline": span / plain, "ratio": plain / recorded, "goal": 0.9,
                         "unit": "x real time"})
            sizes[label] = size / seconds * 3600 / 1e6
        for label, mb in sizes.items():
            rows.append({"what": f"recording size per hour of robot time, goals back and forth ({label})",
                         "ours": mb, "baseline": None, "ratio": None, "goal": None, "unit": "MB/h"})
    return rows
