"""A simulated day of care routines on the whole headless robot (issue 27): the 09:00 routine runs, the 13:00
one is skipped because the robot is in MANUAL, the 21:00 one runs; the recording (MCAP) and the history
file show the three outcomes with their times.

The robot runs its own simulated clock throughout; the idle hours between the runs (nothing happens in
them) are passed by setting the calendar, as the network time does on a robot without a real-time clock."""

from __future__ import annotations

import json
from datetime import datetime
from pathlib import Path
from zoneinfo import ZoneInfo

import pytest

from atemr.config import load_config
from atemr.fsm.agent import Agent
from atemr.io.recording.mcap_reader import RecordingReader
from atemr.robot import Robot
from atemr.robot.headless import build_headless_robot
from atemr.robot.routines import RoutineRunner

BERLIN = ZoneInfo("Europe/Berlin")
ROUTINES = """
timezone: Europe/Berlin
routines:
  - {name: check-on-resident, mission: look-around, at: "09:00"}
  - {name: lunch-check, mission: look-around, at: "13:00"}
  - {name: evening round, mission: kitchen-check, at: "21:00"}
"""


def epoch(clock_time: str) -> float:
    return datetime.fromisoformat(f"2026-06-03T{clock_time}").replace(tzinfo=BERLIN).timestamp()


def run_until(robot: Robot, done, limit_s: float, what: str) -> None:
    end = robot.clock.now() + limit_s
    while robot.clock.now() < end:
        robot.run(until=robot.clock.now() + 0.5)
        if done():
            return
    raise AssertionError(f"{what}: not within {limit_s:g} robot seconds")


def set_mode(robot: Robot, agent: Agent, mode: str) -> None:
    want = f"IDLE.{mode}"
    for _ in range(40):  # AUTO is refused until every level-1 status is OK (the sensors come up first)
        agent.submit("set_auto" if mode == "AUTO" else "set_manual", origin="test")
        robot.run(until=robot.clock.now() + 0.5)
        if agent.state == want:
            return
    raise AssertionError(f"the agent did not reach {want}: {agent.state}")


@pytest.mark.slow
def test_a_simulated_day_of_routines(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    (data / "routines.yaml").write_text(ROUTINES)
    trace = tmp_path / "day.mcap"
    config = load_config(environ={}, overrides={
        "simulation": True, "ui.enabled": False, "data_dir": str(data), "sim.seed": 2, "trace.file": str(trace),
        "sim.start_time": "2026-06-03T08:59:20+02:00",
    })
    robot = build_headless_robot(config)
    with robot:
        runner = robot.parts.routines
        agent = robot.parts.agent
        assert isinstance(runner, RoutineRunner)
        run_until(robot, lambda: agent.state.startswith("IDLE"), 30, "boot")
        set_mode(robot, agent, "AUTO")
        snapshot = runner.snapshot()
        assert [r["next"] for r in snapshot["routines"]] == [
            "2026-06-03 09:00 CEST", "2026-06-03 13:00 CEST", "2026-06-03 21:00 CEST"]

        run_until(robot, lambda: len(runner.history) == 1, 200, "the 09:00 routine")
        set_mode(robot, agent, "MANUAL")
        runner.calendar.set(epoch("12:59:50"))
        run_until(robot, lambda: len(runner.history) == 2, 30, "the 13:00 routine")
        set_mode(robot, agent, "AUTO")
        runner.calendar.set(epoch("20:59:50"))
        run_until(robot, lambda: len(runner.history) == 3, 300, "the 21:00 routine")
        assert runner.snapshot()["routines"][0]["next"] == "2026-06-04 09:00 CEST"
    outcomes = [(r["time"], r["routine"], r["outcome"], r["reason"]) for r in runner.history]
    assert outcomes == [("09:00", "check-on-resident", "reached", None),
                        ("13:00", "lunch-check", "skipped", "robot in MANUAL"),
                        ("21:00", "evening round", "reached", None)]
    saved = [json.loads(line) for line in (data / "routines-history.jsonl").read_text().splitlines()]
    assert [(r["time"], r["outcome"]) for r in saved] == [("09:00", "reached"), ("13:00", "skipped"),
                                                          ("21:00", "reached")]

    reader = RecordingReader(trace)
    said = [e["text"] for e in (reader.decode(m) for m in reader.messages({"/events"})) if e["kind"] == "routine"]
    assert said == ["09:00 check-on-resident started: mission look-around", "09:00 check-on-resident reached",
                    "13:00 lunch-check skipped: robot in MANUAL",
                    "21:00 evening round started: mission kitchen-check", "21:00 evening round reached"]
