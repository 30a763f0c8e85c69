"""The agent end to end on fake ports and a simulated clock: start-up, commands, faults, missions, mapping,
restart, power-off, reload, snapshot and trace replay."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import py_trees
import pytest

from atemr.clock import SimClock
from atemr.domain.places import Place, Places
from atemr.domain.status import AtReturn, BatteryStatus, ComponentHealth, PowerState, StateCode
from atemr.errors import HardwareError
from atemr.fsm.agent import Agent
from atemr.fsm.machine import replay
from atemr.fsm.spec import AgentSpec
from atemr.msgs import Pose2D, Twist
from atemr.scheduler import Scheduler
from atemr.trees.context import clear_blackboard
from atemr.trees.fakes import RecordingLink, RecordingPort, StraightLineNavigation
from atemr.trees.missions import parse_mission
from atemr.yamlsafe import load_yaml

AGENT_YAML = Path(__file__).resolve().parents[2] / "trees" / "agent.yaml"


class Rig:
    """An agent on a scheduler at 10 Hz with a simulated clock."""

    def __init__(self, spec: AgentSpec, port: RecordingPort, link: RecordingLink,
                 navigation: StraightLineNavigation | None = None) -> None:
        self.clock = SimClock()
        self.halts = 0
        self.navigation = navigation
        self.agent = Agent(spec, port, link, navigation=navigation, on_halt=self._halted)
        link.time_source = self.clock.now
        self.port, self.link = port, link
        self.scheduler = Scheduler(self.clock)
        self.scheduler.add(self.agent, 10.0)
        self.scheduler.start()

    def _halted(self) -> None:
        self.halts += 1

    def run(self, seconds: float) -> None:
        self.scheduler.run(duration=seconds)

    def command(self, trigger: str, **kwargs: object) -> object:
        command_id = self.agent.submit(trigger, **kwargs)
        self.scheduler.step()  # exactly one agent tick handles it
        result = self.agent.result(command_id)
        assert result is not None
        return result


@pytest.fixture
def rig(agent_spec: AgentSpec, port: RecordingPort, link: RecordingLink) -> Rig:
    return Rig(agent_spec, port, link)


def start_mission(rig: Rig, text: str) -> object:
    """Send the mission written in ``text`` (a mission file's YAML) to the agent; the command's result."""
    return rig.command("start_mission", mission=parse_mission(load_yaml("m.yaml", text=text), "m.yaml"))


def idle(rig: Rig) -> Rig:
    rig.run(0.3)
    assert rig.agent.state == "IDLE.MANUAL"
    return rig


def test_start_up_checks_then_acknowledges_power_on(rig: Rig) -> None:
    rig.run(0.2)
    assert rig.agent.state == "IDLE.MANUAL"
    assert [s for _, s in rig.link.power_states] == [PowerState.RUNNING]
    assert rig.link.statuses[-1][1].state == StateCode.IDLE
    assert rig.port.modes[-1] == "MANUAL"


def test_a_critical_component_missing_at_start_up_powers_off(rig: Rig) -> None:
    del rig.port.components["lidar"]
    rig.run(4.9)
    assert rig.agent.state == "STARTUP"
    rig.run(1.0)
    assert rig.agent.state == "SHUTDOWN.POWEROFF" and rig.agent.halted and rig.halts == 1
    assert [s for _, s in rig.link.power_states] == [PowerState.POWER_OFF_ACK]
    failure = next(r for r in rig.agent.trace if r.trigger == "critical_failure")
    assert "lidar" in failure.reason and "not reported" in failure.reason
    assert isinstance(rig.agent.context.error, HardwareError) and rig.agent.context.error.critical
    assert rig.link.statuses[-1][1].state == StateCode.SHUTDOWN
    ticks = rig.agent.ticks
    rig.run(1.0)
    assert rig.agent.ticks == ticks, "a halted agent does no more work"


def test_a_trigger_invalid_in_the_state_is_refused_with_a_reason(rig: Rig) -> None:
    idle(rig)
    assert rig.agent.precheck("set_auto") is None
    assert "'cancel' is not valid in state IDLE.MANUAL" in str(rig.agent.precheck("cancel"))
    result = rig.command("cancel")
    assert not result.accepted and result.dest is None  # type: ignore[attr-defined]
    assert "'cancel' is not valid in state IDLE.MANUAL" in result.reason  # type: ignore[attr-defined]
    assert rig.agent.state == "IDLE.MANUAL"
    assert rig.command("no_such_trigger").accepted is False  # type: ignore[attr-defined]


def test_a_goal_in_manual_mode_is_an_invalid_goal(rig: Rig) -> None:
    """A goal is valid in AUTO mode only; in MANUAL it goes to Error with the reason, then back
    (docs/agent.md#the-lifecycle)."""
    idle(rig)
    result = rig.command("goal", goal=Pose2D(1.0, 1.0, 0.0))
    assert result.accepted and result.dest == "ERROR"  # type: ignore[attr-defined]
    assert "AUTO mode only" in result.reason and "MANUAL" in result.reason  # type: ignore[attr-defined]
    rig.run(0.2)
    assert rig.agent.state == "IDLE.MANUAL" and rig.agent.context.error is None


def test_an_invalid_goal_goes_through_error_back_to_idle(rig: Rig) -> None:
    idle(rig)
    assert rig.command("set_auto").accepted  # type: ignore[attr-defined]
    result = rig.command("goal", goal=Pose2D(math.nan, 0.0, 0.0))
    assert result.dest == "ERROR" and "non-finite" in result.reason  # type: ignore[attr-defined]
    rig.run(0.2)
    assert rig.agent.state == "IDLE.AUTO"  # a failed goal in AUTO hands AUTO back: the next goal needs no switch
    assert not rig.agent.context.task_failed
    triggers = [r.trigger for r in rig.agent.trace if r.accepted]
    assert triggers[-2:] == ["goal", "recover"]
    codes = [k for k, _ in itertools.groupby(s.state for _, s in rig.link.statuses)]
    assert codes[-3:] == [StateCode.IDLE, StateCode.ERROR, StateCode.IDLE], "even a one-tick state is published"


def test_set_auto_is_refused_while_a_motor_is_unhealthy(rig: Rig) -> None:
    idle(rig)
    rig.port.components["left_motor"] = ComponentHealth(False, "error flag: over-temperature")
    # the command is handled before the Monitor has seen the fault: the level-1 guard refuses it
    result = rig.command("set_auto")
    assert not result.accepted and "left_motor" in result.reason  # type: ignore[attr-defined]
    rig.run(0.2)  # the Monitor reports the fault; the agent holds ERROR while the motor stays unhealthy
    result = rig.command("set_auto")
    assert not result.accepted and "not valid in state ERROR" in result.reason  # type: ignore[attr-defined]


def test_a_motor_fault_stops_the_robot_and_passes_through_error(rig: Rig) -> None:
    idle(rig)
    stops = rig.port.stops
    rig.port.components["right_motor"] = ComponentHealth(False, "silent")
    rig.port.faults_latched = "right motor (id 2) not answering"
    rig.run(0.3)
    fault = next(r for r in rig.agent.trace if r.trigger == "fault")
    assert fault.dest == "ERROR" and "right_motor: silent" in fault.reason
    assert rig.port.stops > stops
    # non-critical, but its cause lasts: ERROR holds (asking the robot to clear the latched fault) until it is gone
    rig.run(1.0)
    assert rig.agent.state == "ERROR" and rig.port.fault_clears >= 10
    assert not any(r.trigger in ("recover", "escalate") for r in rig.agent.trace)
    rig.port.faults_latched = None
    rig.port.components["right_motor"] = ComponentHealth(True)
    rig.run(0.2)
    assert rig.agent.state == "IDLE.MANUAL"
    assert sum(r.trigger == "fault" for r in rig.agent.trace) == 1, "a component still bad does not loop"


def test_heartbeat_loss_is_a_fault_and_clears_the_heartbeat_bit(rig: Rig) -> None:
    idle(rig)
    rig.link.heartbeat = False
    rig.run(0.3)
    assert any(r.trigger == "fault" and "heartbeat" in r.reason for r in rig.agent.trace)
    assert not rig.link.statuses[-1][1].agent_ok()["HEARTBEAT"]


def test_status_0x153_at_2_hz_and_on_every_change(rig: Rig) -> None:
    idle(rig)
    start = len(rig.link.statuses)
    rig.run(5.0)
    periodic = rig.link.statuses[start:]
    assert 9 <= len(periodic) <= 11
    gaps = [b[0] - a[0] for a, b in itertools.pairwise(periodic)]
    assert all(abs(g - 0.5) < 1e-6 for g in gaps)
    before = len(rig.link.statuses)
    rig.command("set_auto")  # IDLE.AUTO's tree runs SetMode(AUTO) in the next tick ...
    rig.scheduler.step()  # ... and the Monitor publishes the new AUTO bit in the one after
    rig.scheduler.step()
    t, status = rig.link.statuses[-1]
    assert len(rig.link.statuses) == before + 1 and status.auto_mode
    assert t - periodic[-1][0] < 0.5, "a change is sent at once, not at the next period"


def test_joystick_is_forwarded_in_manual_and_zeroed_when_leaving(rig: Rig) -> None:
    idle(rig)
    rig.port.joystick_command = (Twist(0.3, 0.1), rig.clock.now())
    rig.run(0.1)
    assert rig.port.commands[-1][:2] == ("joystick", Twist(0.3, 0.1))
    rig.run(0.6)  # the joystick command is now older than 0.5 s
    assert rig.port.commands[-1][:2] == ("joystick", Twist())
    rig.port.joystick_command = (Twist(0.3, 0.1), rig.clock.now())
    rig.command("set_auto")
    joystick = [c for c in rig.port.commands if c[0] == "joystick"]
    assert joystick[-1][1] == Twist(), "DriveJoystick commands zero in terminate"


MISSION = """
mission:
  name: look-around
  steps:
    - capture_image: {label: front}
    - rotate: {angle_rad: 1.5708}
      timeout_s: 10
    - capture_image: {label: left}
    - wait: {duration_s: 1.0}
"""


def test_a_mission_runs_in_exec_and_returns_to_idle(rig: Rig) -> None:
    idle(rig)
    rig.port.dt_s = 0.1
    rig.command("set_auto")
    mission = parse_mission(load_yaml("m.yaml", text=MISSION), "m.yaml")
    result = rig.command("start_mission", mission=mission)
    assert result.dest == "EXEC", result  # type: ignore[attr-defined]
    rig.run(10.0)
    assert rig.agent.state == "IDLE.AUTO"
    assert rig.port.images == ["images/front-0.jpg", "images/left-1.jpg"]
    assert rig.port.current_pose is not None and abs(rig.port.current_pose.yaw_rad - math.pi / 2) < 0.06
    reached = next(r for r in rig.agent.trace if r.trigger == "reached")
    assert reached.source == "EXEC" and rig.agent.context.task is None
    report = rig.agent.task_reports[-1]
    assert report["mission"] == "look-around" and report["outcome"] == "reached"
    assert [s["status"] for s in report["steps"]] == ["reached"] * 4
    rotate = report["steps"][1]
    assert rotate["kind"] == "rotate" and 1.5 < rotate["duration_s"] < 6.0
    assert rotate["final_pose"]["yaw_rad"] == pytest.approx(math.pi / 2, abs=0.06)
    assert report["steps"][3]["duration_s"] == pytest.approx(1.0, abs=0.11)
    assert json.loads(json.dumps(rig.agent.snapshot()))["last_task"]["outcome"] == "reached"


def test_a_step_timeout_fails_the_mission_into_error(rig: Rig) -> None:
    idle(rig)
    rig.command("set_auto")
    text = "mission:\n  name: too-slow\n  steps:\n    - wait: {duration_s: 5}\n      timeout_s: 1\n"
    start_mission(rig, text)
    rig.run(1.5)
    failed = next(r for r in rig.agent.trace if r.trigger == "failed")
    assert failed.dest == "ERROR" and "timed out after 1 s" in failed.reason
    report = rig.agent.task_reports[-1]
    assert report["outcome"] == "failed" and report["steps"][0]["status"] == "failed"
    assert report["steps"][0]["duration_s"] == pytest.approx(1.0, abs=0.11)
    rig.run(0.2)
    assert rig.agent.state == "IDLE.AUTO"  # back to AUTO: the carer's next routine may start


def test_a_goal_sent_in_manual_or_a_failure_with_level1_not_ok_recovers_to_manual(rig: Rig) -> None:
    """Error hands AUTO back only after a goal or a mission that failed in AUTO, and only while the level-1
    statuses are OK: a goal sent in MANUAL stays in MANUAL, and so does a failure after which a motor is bad."""
    idle(rig)
    assert rig.command("goal", goal=Pose2D(1.0, 0.0, 0.0)).dest == "ERROR"  # type: ignore[attr-defined]
    rig.run(0.2)
    assert rig.agent.state == "IDLE.MANUAL"
    rig.port.is_localized = True
    rig.command("set_auto")
    text = "mission:\n  name: too-slow\n  steps:\n    - wait: {duration_s: 5}\n      timeout_s: 1\n"
    start_mission(rig, text)
    rig.run(0.5)
    rig.port.is_localized = False  # lost on the way: AUTO would drive by a map it is not on
    rig.run(1.0)
    failed = next(r for r in rig.agent.trace if r.trigger == "failed")
    recover = next(r for r in reversed(rig.agent.trace) if r.trigger == "recover")
    assert failed.dest == "ERROR" and recover.t > failed.t
    assert recover.dest == "IDLE.MANUAL" and rig.agent.state == "IDLE.MANUAL"


def test_cancel_stops_the_task(rig: Rig) -> None:
    idle(rig)
    rig.port.dt_s = 0.01
    rig.command("set_auto")
    text = "mission:\n  name: spin\n  steps:\n    - rotate: {angle_rad: 12}\n"
    start_mission(rig, text)
    rig.run(0.5)
    assert rig.agent.state == "EXEC" and rig.port.commands[-1][1].angular_radps > 0
    progress = rig.agent.snapshot()["task_progress"]
    assert progress["outcome"] == "running" and progress["steps"][0]["status"] == "running"
    assert rig.command("cancel").dest == "IDLE.AUTO"  # type: ignore[attr-defined]
    agent_cmds = [c for c in rig.port.commands if c[0] == "agent"]
    assert agent_cmds[-1][1] == Twist(), "Rotate commands zero when interrupted"
    report = rig.agent.task_reports[-1]
    assert report["outcome"] == "cancelled" and report["steps"][0]["status"] == "interrupted"


def test_a_mission_needing_navigation_is_refused_with_the_reason(rig: Rig) -> None:
    idle(rig)
    rig.command("set_auto")
    text = "mission:\n  name: go\n  steps:\n    - go_to: {x_m: 1, y_m: 2}\n"
    result = start_mission(rig, text)
    assert not result.accepted  # type: ignore[attr-defined]
    assert "drives to poses (steps 0) and navigation is not available on this robot" in result.reason  # type: ignore
    assert rig.agent.state == "IDLE.AUTO"


def test_mapping_begin_save_discard(rig: Rig) -> None:
    idle(rig)
    result = rig.command("begin_mapping")
    assert not result.accepted and "mapping is not available" in result.reason  # type: ignore[attr-defined]
    rig.port.mapping_available = True
    assert rig.command("begin_mapping").dest == "MAPPING"  # type: ignore[attr-defined]
    assert rig.link.statuses[-1][1].state == StateCode.MAPPING
    bad = rig.command("save_map", name="../etc/passwd")
    assert not bad.accepted and "map name" in bad.reason  # type: ignore[attr-defined]
    assert rig.command("save_map", name="kitchen").dest == "IDLE.MANUAL"  # type: ignore[attr-defined]
    rig.command("begin_mapping")
    rig.command("discard_map")
    assert rig.port.maps == ["kitchen", None] and rig.agent.state == "IDLE.MANUAL"
    rig.command("begin_mapping")
    rig.port.components["left_motor"] = ComponentHealth(False, "silent")
    rig.run(0.3)
    assert rig.port.maps == ["kitchen", None, None] and not rig.port.mapping, "a fault drops the unsaved map"


def test_restart_runs_start_up_again(rig: Rig) -> None:
    idle(rig)
    assert rig.command("restart").dest == "SHUTDOWN.RESTART"  # type: ignore[attr-defined]
    rig.run(0.5)
    assert rig.agent.state == "IDLE.MANUAL"
    states = [r.dest for r in rig.agent.trace if r.accepted]
    assert states[-3:] == ["SHUTDOWN.RESTART", "STARTUP", "IDLE.MANUAL"]
    assert [s for _, s in rig.link.power_states] == [PowerState.RUNNING, PowerState.INITIALISING,
                                                     PowerState.RUNNING]


def test_power_off_request_from_the_secondary_core(rig: Rig) -> None:
    idle(rig)
    rig.link.power_off = True
    rig.run(0.6)
    assert rig.agent.halted and rig.agent.state == "SHUTDOWN.POWEROFF"
    assert rig.link.power_states[-1][1] == PowerState.POWER_OFF_ACK
    assert rig.link.statuses[-1][1].state == StateCode.SHUTDOWN


def test_snapshot_is_json_and_counts_ticks(rig: Rig) -> None:
    idle(rig)
    rig.run(1.0)
    snap = json.loads(json.dumps(rig.agent.snapshot()))
    assert snap["state"] == "IDLE.MANUAL" and snap["code"] == 2
    assert snap["tree"]["name"] == "manual" and snap["tree"]["status"] == "RUNNING"
    joystick = snap["tree"]["children"][1]
    assert joystick["type"] == "DriveJoystick" and joystick["ticks"] >= 10
    assert snap["monitor"]["ticks"] == rig.agent.ticks
    state = snap["blackboard"]["/agent/state"]
    assert state["value"] == "IDLE.MANUAL" and state["by"] == "agent/agent"
    assert state["t"] == next(r.t for r in rig.agent.trace if r.dest == "IDLE.MANUAL")  # when it got that value
    assert "/monitor/status" in snap["blackboard"]
    assert snap["transitions"][-1]["dest"] == "IDLE.MANUAL" and "set_auto" in snap["valid_triggers"]
    assert "SHUTDOWN.POWEROFF" in snap["machine"]["states"]
    assert {"trigger": "cancel", "source": ["EXEC"], "dest": "IDLE.AUTO"} in snap["machine"]["transitions"]


def test_the_blackboard_gets_back_what_it_lost(rig: Rig) -> None:
    """The agent and the status leaf write their keys only when they change; a blackboard cleared under them (or a
    status overwritten by someone else) has them again after the next tick."""
    idle(rig)
    rig.run(0.5)
    storage = py_trees.blackboard.Blackboard.storage
    status = storage["/monitor/status"]
    rig.run(0.5)
    assert storage["/monitor/status"] is status  # unchanged: not written again
    clear_blackboard()
    storage["/monitor/status"] = {"state": "stale"}
    rig.run(0.2)
    assert storage["/agent/state"] == "IDLE.MANUAL" and storage["/agent/mode"] == rig.agent.context.mode
    assert storage["/agent/last_transition"]["dest"] == "IDLE.MANUAL"
    assert storage["/monitor/status"] == status


def test_trace_replays_to_the_same_states(rig: Rig, agent_spec: AgentSpec) -> None:
    idle(rig)
    rig.command("set_auto")
    rig.command("goal", goal=Pose2D(math.inf, 0, 0))
    rig.run(0.3)
    rig.command("restart")
    rig.run(0.5)
    rig.link.power_off = True
    rig.run(0.3)
    recorded = [r for r in rig.agent.trace if r.accepted and r.trigger != "(initial)"]
    replayed = replay(agent_spec, rig.agent.trace)
    assert [(r.trigger, r.source, r.dest) for r in replayed] == [(r.trigger, r.source, r.dest) for r in recorded]
    tampered = [*rig.agent.trace]
    tampered.insert(3, tampered[3].__class__(0.0, "reached", "IDLE.AUTO", "IDLE.AUTO", True))
    assert any(not r.accepted for r in replay(agent_spec, tampered))


def test_reload_applies_only_in_idle_and_only_when_valid(rig: Rig, tmp_path: Path) -> None:
    """Valid: applied in IDLE; requested mid-EXEC: deferred (never applied there) until IDLE is reached."""
    idle(rig)
    text = AGENT_YAML.read_text().replace("period_s: 0.5}", "period_s: 0.2}")
    good = tmp_path / "agent.yaml"
    good.write_text(text)
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("type: Halt", "type: Hault"))
    result = rig.command("__reload__", path=str(bad))
    assert not result.accepted and "bad.yaml:" in result.reason and "Halt" in result.reason  # type: ignore
    rig.agent.submit_reload(good)
    rig.scheduler.step()
    assert rig.agent.results[-1].accepted and rig.agent.state == "IDLE.MANUAL"
    start = len(rig.link.statuses)
    rig.run(2.0)
    assert len(rig.link.statuses) - start >= 9, "the new document's 5 Hz status is in force"
    assert rig.agent.trace[0].trigger == "(initial)", "the trace survives the reload"
    rig.command("set_auto")
    rig.command("start_mission", mission=parse_mission(
        load_yaml("w.yaml", text="mission:\n  name: w\n  steps:\n    - wait: {duration_s: 3}\n"), "w.yaml"))
    good.write_text(text.replace("period_s: 0.5}", "period_s: 0.25}"))
    before = rig.agent.spec
    rig.agent.submit_reload(good)
    rig.scheduler.step()
    assert "deferred: applied when IDLE is reached (now EXEC)" in rig.agent.results[-1].reason
    while rig.agent.state == "EXEC":
        assert rig.agent.spec is before, "never applied mid-EXEC"
        rig.scheduler.step()
    rig.scheduler.step()
    assert rig.agent.state == "IDLE.AUTO" and rig.agent.spec is not before
    assert rig.agent.reloads[-1].status == "applied"


class ExplodingPort(RecordingPort):
    """A port whose camera has a bug (raises something that is not an AtemrError)."""

    def capture_image(self, label: str) -> str:
        raise RuntimeError("driver bug")


def test_a_leaf_bug_fails_the_task_and_the_agent_carries_on(agent_spec: AgentSpec, link: RecordingLink) -> None:
    rig = Rig(agent_spec, ExplodingPort(), link)
    idle(rig)
    rig.command("set_auto")
    text = "mission:\n  name: photo\n  steps:\n    - capture_image: {label: x}\n"
    start_mission(rig, text)
    rig.run(0.5)
    failed = next(r for r in rig.agent.trace if r.trigger == "failed")
    assert "driver bug" in failed.reason and rig.agent.state == "IDLE.AUTO"
    assert any("driver bug" in e for e in rig.agent.errors)


def test_commands_from_many_threads_are_all_answered(rig: Rig) -> None:
    import threading

    idle(rig)
    ids: list[int] = []
    lock = threading.Lock()

    def spam() -> None:
        for _ in range(50):
            command_id = rig.agent.submit("set_manual", origin="thread")
            with lock:
                ids.append(command_id)

    threads = [threading.Thread(target=spam) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    rig.scheduler.step()
    assert len(set(ids)) == 200
    answered = {r.id: r for r in rig.agent.results}
    assert all(i in answered and not answered[i].accepted for i in ids)


def test_from_config_uses_the_shipped_document(port: RecordingPort, link: RecordingLink) -> None:
    from atemr.config import load_config

    agent = Agent.from_config(load_config(environ={}), port, link)
    assert agent.spec.file is not None and agent.spec.file.endswith("trees/agent.yaml")
    agent.tick(0.0)
    assert agent.state == "IDLE.MANUAL"


def test_a_fault_during_exec_ends_the_task(rig: Rig) -> None:
    idle(rig)
    rig.command("set_auto")
    text = "mission:\n  name: w\n  steps:\n    - wait: {duration_s: 5}\n"
    start_mission(rig, text)
    rig.run(0.5)
    rig.port.components["left_motor"] = ComponentHealth(False, "over-temperature")
    rig.run(0.3)
    assert rig.agent.context.task is None and rig.agent.state == "ERROR"  # until the motor is healthy again
    rig.port.components["left_motor"] = ComponentHealth(True)
    rig.run(0.2)
    assert rig.agent.state == "IDLE.MANUAL"
    report = rig.agent.task_reports[-1]
    assert report["outcome"] == "fault" and report["steps"][0]["status"] == "interrupted"
    fault = next(r for r in rig.agent.trace if r.trigger == "fault")
    assert fault.source == "EXEC" and "left_motor: over-temperature" in fault.reason


def test_a_goal_with_navigation_runs_in_exec(agent_spec: AgentSpec, link: RecordingLink) -> None:
    port = RecordingPort(current_pose=Pose2D(2.6, 2.6, 0.0))
    navigation = StraightLineNavigation(port, speed_mps=1.0)
    rig = Rig(agent_spec, port, link, navigation)
    idle(rig)
    rig.command("set_auto")
    navigation.refuse = "goal (9.00, 9.00, 0.00 rad) is outside the map"
    refused = rig.command("goal", goal=Pose2D(9, 9, 0))
    assert refused.dest == "ERROR" and "outside the map" in refused.reason  # type: ignore[attr-defined]
    rig.run(0.3)
    rig.command("set_auto")
    navigation.refuse = None
    assert rig.command("goal", goal=Pose2D(3.6, 2.6, 1.0)).dest == "EXEC"  # type: ignore[attr-defined]
    rig.run(0.5)
    feedback = rig.agent.snapshot()["task_progress"]["steps"][0]
    assert feedback["status"] == "running" and 0.3 < feedback["distance_left_m"] < 0.8
    rig.run(1.5)
    assert rig.agent.state == "IDLE.AUTO" and port.current_pose == Pose2D(3.6, 2.6, 1.0)
    report = rig.agent.task_reports[-1]
    assert report["outcome"] == "reached" and report["steps"][0]["position_error_m"] == 0.0


@pytest.mark.parametrize(("at_return", "goal_outcome"), [("cancel", "cancelled"), ("finish", "reached")])
def test_the_monitor_ends_the_task_at_the_return_limit_and_sends_the_robot_home(
        agent_spec: AgentSpec, link: RecordingLink, at_return: AtReturn, goal_outcome: str) -> None:
    port = RecordingPort(current_pose=Pose2D(2.6, 2.6, 0.0))
    dock = Places([Place("home", Pose2D(0.5, 0.5, 0.0), "dock")])
    rig = Rig(agent_spec, port, link, StraightLineNavigation(port, speed_mps=1.0, known_places=dock))
    idle(rig)
    rig.command("set_auto")
    assert rig.command("goal", goal=Pose2D(4.6, 2.6, 0.0)).dest == "EXEC"  # type: ignore[attr-defined]
    rig.run(0.5)
    port.battery_status = BatteryStatus(9.0, 24.6, warn_percent=20.0, return_percent=10.0, critical_percent=5.0,
                                        at_return=at_return)
    rig.run(8.0)
    goal, home = rig.agent.task_reports[-2], rig.agent.task_reports[-1]
    assert goal["outcome"] == goal_outcome
    assert home["mission"] == "to home to charge" and home["outcome"] == "reached"
    assert rig.agent.state == "IDLE.AUTO" and port.current_pose == Pose2D(0.5, 0.5, 0.0)
    by_battery = [r.trigger for r in rig.agent.trace if r.origin == "battery"]
    assert by_battery == (["cancel", "start_mission"] if at_return == "cancel" else ["start_mission"])
    assert port.reports[0] == ("battery", "Battery 9 %: the task ends and the robot goes home to charge"
                               if at_return == "cancel" else "Battery 9 %: the task finishes, then the robot goes "
                                                             "home to charge")


def test_the_monitor_stops_the_robot_where_it_is_at_the_critical_limit(agent_spec: AgentSpec,
                                                                       link: RecordingLink) -> None:
    port = RecordingPort(current_pose=Pose2D(2.6, 2.6, 0.0))
    rig = Rig(agent_spec, port, link, StraightLineNavigation(port, speed_mps=1.0))
    idle(rig)
    rig.command("set_auto")
    rig.command("goal", goal=Pose2D(4.6, 2.6, 0.0))
    rig.run(0.5)
    port.battery_status = BatteryStatus(4.0, 23.0, warn_percent=20.0, return_percent=10.0, critical_percent=5.0)
    rig.run(2.0)
    assert rig.agent.state == "IDLE.MANUAL" and rig.agent.task_reports[-1]["outcome"] == "cancelled"
    assert 2.9 < port.current_pose.x_m < 3.3, "stopped where it was"  # type: ignore[union-attr]
    assert port.reports == [("battery", "Battery critical: 4 %, stopped where it is; charge it now")]


def test_kitchen_check_runs_with_navigation(agent_spec: AgentSpec, link: RecordingLink) -> None:
    from atemr.trees.missions import load_mission

    port = RecordingPort(current_pose=Pose2D(2.6, 2.6, 0.0), dt_s=0.1)
    rig = Rig(agent_spec, port, link, StraightLineNavigation(port, speed_mps=1.0))
    idle(rig)
    rig.command("set_auto")
    mission = load_mission(AGENT_YAML.parent / "missions" / "kitchen-check.yaml")
    assert rig.command("start_mission", mission=mission).dest == "EXEC"  # type: ignore[attr-defined]
    rig.run(30.0)
    report = rig.agent.task_reports[-1]
    assert report["outcome"] == "reached", report
    assert [s["status"] for s in report["steps"]] == ["reached"] * 6
    assert port.images == ["images/kitchen-0.jpg", "images/dining-1.jpg"]
    home = report["steps"][-1]
    assert home["kind"] == "return_home" and home["position_error_m"] == 0.0 and home["heading_error_rad"] == 0.0


def test_the_live_snapshot_has_every_node_of_a_big_tree(rig: Rig) -> None:
    """No node limit (Groot2's free tier stops at 20): a 150-step mission is in the snapshot whole, each node
    with its status and tick count, and it stays JSON-able."""
    idle(rig)
    rig.command("set_auto")
    steps = "".join(f"    - {{name: pause {i}, wait: {{duration_s: 0.1}}}}\n" for i in range(150))
    mission = parse_mission(load_yaml("big.yaml", text=f"mission:\n  name: big\n  steps:\n{steps}"), "big.yaml")
    rig.command("start_mission", mission=mission)
    rig.run(1.05)
    snap = json.loads(json.dumps(rig.agent.snapshot()))

    def walk(node: dict) -> list[dict]:
        return [node, *(n for child in node.get("children", []) for n in walk(child))]

    nodes = walk(snap["tree"])
    pauses = [n for n in nodes if n["name"].startswith("pause ")]
    assert len(pauses) == 150 and len(nodes) > 150
    assert all({"status", "ticks", "type"} <= set(n) for n in nodes)
    done = [n for n in pauses if n["status"] == "SUCCESS"]
    assert 5 <= len(done) < 150 and all(n["ticks"] >= 1 for n in done)
    assert [n["ticks"] for n in pauses[-10:]] == [0] * 10, "not run yet"


class BrokenMapService(RecordingPort):
    """A robot whose map service fails to stop (a session already gone, a disk gone)."""

    def end_mapping(self, save_as: str | None) -> None:
        raise HardwareError("the map service is gone")


def test_leaving_exec_is_never_blocked_by_a_map_that_cannot_be_stopped(agent_spec: AgentSpec, link: RecordingLink,
                                                                       caplog: pytest.LogCaptureFixture) -> None:
    port = BrokenMapService(mapping_available=True)
    rig = idle(Rig(agent_spec, port, link))
    rig.command("set_auto")
    text = "mission:\n  name: remap\n  steps:\n    - start_mapping: {}\n    - wait: {duration_s: 30}\n"
    start_mission(rig, text)
    rig.run(1.0)
    assert rig.agent.state == "EXEC" and rig.agent.context.mapping_active
    assert rig.command("cancel").dest == "IDLE.AUTO"  # type: ignore[attr-defined]
    assert not rig.agent.context.mapping_active
    assert any("could not stop mapping on leaving EXEC" in r.getMessage() for r in caplog.records)


def test_a_timed_out_step_with_retries_says_it_timed_out(rig: Rig) -> None:
    idle(rig)
    rig.command("set_auto")
    text = "mission:\n  name: slow\n  steps:\n    - wait: {duration_s: 5}\n      timeout_s: 1\n      retries: 1\n"
    start_mission(rig, text)
    rig.run(2.5)
    report = rig.agent.task_reports[-1]
    assert report["outcome"] == "failed" and report["steps"][0]["reason"] == "timed out after 1 s"
    assert "timed out after 1 s" in report["reason"]
