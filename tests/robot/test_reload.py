"""Hot reload through the file watcher: a valid agent document is swapped in IDLE keeping the blackboard, an
invalid one changes nothing and reports its line and column, a reload requested mid-EXEC waits for IDLE,
and an edited mission takes effect between its steps."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import py_trees
import pytest

from atemr.clock import SimClock
from atemr.fsm.agent import Agent
from atemr.fsm.spec import load_agent
from atemr.robot.reload import ReloadWatcher
from atemr.scheduler import Scheduler
from atemr.trees.fakes import RecordingLink, RecordingPort
from atemr.trees.missions import load_mission

AGENT_YAML = Path(__file__).resolve().parents[2] / "trees" / "agent.yaml"
MISSION = """\
mission:
  name: three-waits
  steps:
    - wait: {duration_s: 1.0}
      name: first
    - wait: {duration_s: 1.0}
      name: second
    - wait: {duration_s: 1.0}
      name: third
"""


def write(path: Path, text: str) -> None:
    """Write and move the time stamp forward (a test may edit twice within the file system's resolution)."""
    before = path.stat().st_mtime_ns if path.exists() else 0
    path.write_text(text)
    os.utime(path, ns=(before + 10**9, before + 10**9))


class Studio:
    """An agent on the fake ports, reading a copy of the shipped document, with its watcher."""

    def __init__(self, tmp_path: Path) -> None:
        self.file = tmp_path / "agent.yaml"
        shutil.copy(AGENT_YAML, self.file)
        (tmp_path / "missions").mkdir()
        self.mission_file = tmp_path / "missions" / "three-waits.yaml"
        self.mission_file.write_text(MISSION)
        self.port, self.link = RecordingPort(), RecordingLink()
        self.clock = SimClock()
        self.link.time_source = self.clock.now
        self.agent = Agent(load_agent(self.file), self.port, self.link)
        self.watcher = ReloadWatcher(self.agent, self.file)
        self.scheduler = Scheduler(self.clock)
        self.scheduler.add(self.agent, 10.0)
        self.scheduler.add(self.watcher, 1.0)
        self.scheduler.start()
        self.scheduler.run(duration=0.3)
        assert self.agent.state == "IDLE.MANUAL"

    def run(self, seconds: float) -> None:
        self.scheduler.run(duration=seconds)

    def command(self, trigger: str, **kwargs: object) -> None:
        self.agent.submit(trigger, **kwargs)
        self.scheduler.step()


@pytest.fixture
def studio(tmp_path: Path) -> Studio:
    return Studio(tmp_path)


def test_a_valid_edit_is_swapped_in_idle_keeping_the_blackboard(studio: Studio) -> None:
    client = py_trees.blackboard.Client(name="test", namespace="/agent")
    client.register_key("operator_note", access=py_trees.common.Access.WRITE)
    client.operator_note = "kept across reloads"
    before, trace = studio.agent.spec, len(studio.agent.trace)
    write(studio.file, studio.file.read_text().replace("period_s: 0.5}", "period_s: 0.2}"))
    studio.run(1.2)
    assert studio.agent.spec is not before and studio.agent.state == "IDLE.MANUAL"
    report = studio.agent.reloads[-1]
    assert (report.kind, report.status, report.origin) == ("agent", "applied", "file watcher")
    assert "-    - {type: PublishStatus, name: status 0x153, params: {period_s: 0.5}}" in report.diff
    assert "+    - {type: PublishStatus, name: status 0x153, params: {period_s: 0.2}}" in report.diff
    storage = py_trees.blackboard.Blackboard.storage
    assert storage["/agent/operator_note"] == "kept across reloads"
    assert storage["/agent/state"] == "IDLE.MANUAL" and "/monitor/status" in storage
    assert len(studio.agent.trace) >= trace and studio.agent.trace[0].trigger == "(initial)"
    snapshot = studio.agent.snapshot()
    assert snapshot["reloads"][-1]["status"] == "applied" and snapshot["reloads"][-1]["diff"] == report.diff


def test_an_invalid_edit_leaves_everything_as_it_was_and_says_where(studio: Studio) -> None:
    before, state = studio.agent.spec, studio.agent.state
    text = studio.file.read_text().replace("{type: Halt, name: halt}", "{type: Hault, name: halt}")
    write(studio.file, text)
    studio.run(1.2)
    report = studio.agent.reloads[-1]
    assert report.status == "invalid" and report.error is not None
    index = text.index("Hault")
    line = text.count("\n", 0, index) + 1
    column = index - text.rfind("\n", 0, index)
    assert (report.error["line"], report.error["column"]) == (line, column)
    assert "unknown node type 'Hault'" in report.error["message"] and "'Halt'" in report.error["message"]
    assert "+" in report.diff and "Hault" in report.diff
    assert studio.agent.spec is before and studio.agent.state == state
    studio.run(2.0)
    assert len(studio.agent.reloads) == 1, "an invalid file is reported once, not at every poll"
    studio.command("set_auto")
    assert studio.agent.state == "IDLE.AUTO", "still running the last good document"
    write(studio.file, text.replace("Hault", "Halt").replace("period_s: 0.5}", "period_s: 0.25}"))
    studio.run(1.2)
    assert studio.agent.reloads[-1].status == "applied" and studio.agent.spec is not before
    assert "Hault" not in studio.agent.reloads[-1].diff, "the diff is against the running version"


def test_a_reload_mid_exec_is_deferred_until_idle(studio: Studio) -> None:
    studio.command("set_auto")
    studio.command("start_mission", mission=load_mission(studio.mission_file))
    assert studio.agent.state == "EXEC"
    before = studio.agent.spec
    write(studio.file, studio.file.read_text().replace("period_s: 0.5}", "period_s: 0.2}"))
    studio.run(1.0)
    report = studio.agent.reloads[-1]
    assert report.status == "deferred" and "applied when IDLE is reached (now EXEC)" in report.reason
    while studio.agent.state == "EXEC":
        assert studio.agent.spec is before, "never applied mid-EXEC"
        studio.scheduler.step()
    studio.scheduler.step()
    assert studio.agent.state == "IDLE.AUTO" and studio.agent.spec is not before
    assert report.status == "applied" and report.applied_t is not None
    assert studio.agent.task_reports[-1]["outcome"] == "reached"


def test_a_newer_edit_supersedes_a_deferred_one(studio: Studio) -> None:
    studio.command("set_auto")
    studio.command("start_mission", mission=load_mission(studio.mission_file))
    text = studio.file.read_text()
    write(studio.file, text.replace("period_s: 0.5}", "period_s: 0.2}"))
    studio.run(1.0)
    write(studio.file, text.replace("period_s: 0.5}", "period_s: 0.25}"))
    studio.run(1.0)
    first, second = studio.agent.reloads[-2], studio.agent.reloads[-1]
    assert (first.status, second.status) == ("superseded", "deferred")
    studio.run(2.0)
    assert studio.agent.state == "IDLE.AUTO" and (first.status, second.status) == ("superseded", "applied")
    assert studio.agent.spec.monitor is not None
    publish = studio.agent.spec.monitor.children[0]
    assert publish.options.period_s == 0.25


def test_the_explicit_reload_action_reports_an_unchanged_file(studio: Studio) -> None:
    before = studio.agent.spec
    studio.watcher.request()
    studio.run(1.2)
    assert studio.agent.reloads[-1].status == "unchanged" and studio.agent.reloads[-1].origin == "reload action"
    assert studio.agent.spec is before


def test_a_mission_edit_applies_between_steps(studio: Studio) -> None:
    studio.command("set_auto")
    studio.command("start_mission", mission=load_mission(studio.mission_file))
    studio.run(0.4)
    progress = studio.agent.snapshot()["task_progress"]
    assert [s["status"] for s in progress["steps"]] == ["running", "pending", "pending"]
    write(studio.mission_file, MISSION.replace("    - wait: {duration_s: 1.0}\n      name: second",
                                               "    - capture_image: {label: edited}\n      name: second")
          .replace("    - wait: {duration_s: 1.0}\n      name: third\n", ""))
    studio.run(0.4)
    report = studio.agent.reloads[-1]
    assert (report.kind, report.status) == ("mission", "applied"), report.reason
    assert "between steps: steps 1-1 now come from the new file" in report.reason
    progress = studio.agent.snapshot()["task_progress"]
    assert [(s["name"], s["status"]) for s in progress["steps"]] == [("first", "running"), ("second", "pending")]
    assert studio.port.images == [], "the running step is not interrupted"
    studio.run(1.5)
    assert studio.agent.state == "IDLE.AUTO"
    done = studio.agent.task_reports[-1]
    assert done["outcome"] == "reached" and [s["status"] for s in done["steps"]] == ["reached", "reached"]
    assert studio.port.images == ["images/edited-0.jpg"]
    assert done["steps"][0]["duration_s"] == pytest.approx(1.0, abs=0.15)


def test_an_invalid_mission_edit_leaves_the_running_mission_alone(studio: Studio) -> None:
    studio.command("set_auto")
    studio.command("start_mission", mission=load_mission(studio.mission_file))
    text = MISSION.replace("duration_s: 1.0}\n      name: third", "duration_s: -4}\n      name: third")
    write(studio.mission_file, text)
    studio.run(1.0)
    report = studio.agent.reloads[-1]
    assert report.status == "invalid" and report.error is not None
    assert report.error["line"] == text[: text.index("-4")].count("\n") + 1
    studio.run(3.0)
    assert studio.agent.task_reports[-1]["outcome"] == "reached"
    assert len(studio.agent.task_reports[-1]["steps"]) == 3


def test_an_edited_mission_that_is_not_running_is_noted_for_its_next_start(studio: Studio) -> None:
    write(studio.mission_file, MISSION.replace("name: three-waits", "name: three-waits-edited"))
    studio.run(1.2)
    report = studio.agent.reloads[-1]
    assert report.status == "saved" and "is not running: its next start uses the new file" in report.reason
