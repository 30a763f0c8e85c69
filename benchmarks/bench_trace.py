"""Agent traces: what recording costs the agent's tick, how big a trace grows, and how fast the replay seeks.

The agent runs the shipped ``trees/agent.yaml`` on the package's fake ports (`atemr.trees.fakes`) at 10 Hz of
simulated time, switching IDLE.MANUAL/IDLE.AUTO every 5 s so the trees change. Rows:

* ticks per second of wall time with the recorder writing a trace file, against the same run unrecorded;
* the trace's size per hour of robot time (goal-free: it says what ``trace.max_file_mb`` holds);
* frames per second of ``TraceTimeline.frame`` at random times in a 15-minute trace (quick or not: a checkpoint
  every 500 records), with checkpoints against replaying every record from the start.

Run: ``.venv/bin/python benchmarks/run trace`` (or ``atemr bench trace``).
"""

from __future__ import annotations

import random
import tempfile
import time
from pathlib import Path
from typing import Any

from atemr.clock import SimClock
from atemr.fsm.agent import DEFAULT_AGENT_FILE, Agent
from atemr.fsm.recording import AgentRecorder
from atemr.fsm.spec import load_agent
from atemr.fsm.trace_timeline import TraceTimeline
from atemr.io.trace_file import TraceWriter, read_trace
from atemr.msgs import Pose2D
from atemr.scheduler import Scheduler
from atemr.trees.context import clear_blackboard
from atemr.trees.fakes import RecordingLink, RecordingPort


def agent_run(seconds: float, trace: Path | None) -> float:
    """Wall seconds to run the agent for ``seconds`` of robot time (recorded to ``trace`` when given)."""
    clear_blackboard()
    clock = SimClock()
    link = RecordingLink()
    agent = Agent(load_agent(DEFAULT_AGENT_FILE), RecordingPort(current_pose=Pose2D(1.0, 2.0, 0.0)), link)
    link.time_source = clock.now
    writer = None
    if trace is not None:
        writer = TraceWriter(trace, max_bytes=1 << 30)
        recorder = AgentRecorder(agent, writer.write)
        writer.preamble = recorder.preamble
        recorder.attach()
    scheduler = Scheduler(clock)
    scheduler.add(agent, 10.0)
    if writer is not None:
        scheduler.add(writer, 1.0)
    scheduler.start()
    start = time.perf_counter()
    for k in range(int(seconds / 5)):
        agent.submit("set_auto" if k % 2 == 0 else "set_manual")
        scheduler.run(duration=5.0)
    took = time.perf_counter() - start
    scheduler.shutdown()
    clear_blackboard()
    return took


def run(quick: bool = False) -> list[dict[str, Any]]:
    # Quick too runs 15 minutes of robot time (under 2 s of CPU): a shorter trace holds two checkpoints, where
    # seeking from the nearest one gains nothing to speak of over replaying from the start, and the row would time
    # what checkpoints are not for.
    seconds = 900.0
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        trace = Path(tmp) / "bench.atrace"
        plain_s = agent_run(seconds, None)
        recorded_s = agent_run(seconds, trace)
        ticks = seconds * 10
        rows.append({"what": f"agent ticks/s recorded vs not ({seconds:g} s of robot time)",
                     "ours": ticks / recorded_s, "baseline": ticks / plain_s, "ratio": plain_s / recorded_s,
                     "goal": None, "unit": "ticks/s"})
        size = trace.stat().st_size
        rows.append({"what": "trace size per hour of robot time (idle, mode switch every 5 s)",
                     "ours": size / seconds * 3600 / 1e6, "baseline": None, "ratio": None, "goal": None,
                     "unit": "MB/h"})
        contents = read_trace(trace)
        timeline = TraceTimeline(contents.records)
        plain = TraceTimeline(contents.records)
        plain._checkpoints = plain._checkpoints[:1]
        rng = random.Random(0)
        times = [rng.uniform(timeline.start_t, timeline.end_t) for _ in range(50 if quick else 200)]
        start = time.perf_counter()
        for t in times:
            timeline.frame(t)
        ours = time.perf_counter() - start
        start = time.perf_counter()
        for t in times:
            plain.frame(t)
        base = time.perf_counter() - start
        rows.append({"what": f"replay frames/s at random times, {len(contents.records)} records, checkpoints vs "
                             "replaying from the start", "ours": len(times) / ours, "baseline": len(times) / base,
                     "ratio": base / ours, "goal": 2.0, "unit": "frames/s"})
    return rows
