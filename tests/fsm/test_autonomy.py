"""Operator autonomy levels: the document's levels are validated (precise errors, never on safety
transitions); a gated transition waits with the robot held still; confirm proceeds, deny and timeout take
the safe path; safety transitions never wait; every decision is in the trace and reaches the listeners."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from atemr.clock import SimClock
from atemr.errors import ConfigError
from atemr.fsm.agent import Agent
from atemr.fsm.autonomy import LEVELS, AutonomyGate, safety_reason
from atemr.fsm.machine import Lifecycle, TransitionRecord
from atemr.fsm.spec import AgentSpec, parse_agent
from atemr.msgs import Twist
from atemr.scheduler import Scheduler
from atemr.trees.context import AgentContext
from atemr.trees.fakes import RecordingLink, RecordingPort
from atemr.trees.missions import Mission, parse_mission
from atemr.yamlsafe import load_yaml

AGENT_YAML = Path(__file__).resolve().parents[2] / "trees" / "agent.yaml"
TEXT = AGENT_YAML.read_text()
START_MISSION = '''  - {trigger: start_mission, source: IDLE.AUTO, dest: EXEC, conditions: mission_runnable,
     after: set_mission_task, autonomy: high,'''


def parse(text: str) -> AgentSpec:
    return parse_agent(load_yaml("agent.yaml", text=text), "agent.yaml")


def position(text: str, needle: str) -> tuple[int, int]:
    index = text.index(needle)
    return text.count("\n", 0, index) + 1, index - (text.rfind("\n", 0, index) + 1) + 1


def wait_mission(seconds: float = 2.0) -> Mission:
    text = f"mission:\n  name: w\n  steps:\n    - wait: {{duration_s: {seconds}}}\n"
    return parse_mission(load_yaml("w.yaml", text=text), "w.yaml")


class Rig:
    """An agent at 10 Hz on a simulated clock, idle in AUTO, at robot autonomy ``level``."""

    def __init__(self, spec: AgentSpec, level: str = "low", timeout_s: float = 5.0) -> None:
        self.port, self.link = RecordingPort(), RecordingLink()
        self.clock = SimClock()
        self.link.time_source = self.clock.now
        self.agent = Agent(spec, self.port, self.link, autonomy=level, confirm_timeout_s=timeout_s)
        self.heard: list[TransitionRecord] = []
        self.agent.listeners.append(self.heard.append)
        self.scheduler = Scheduler(self.clock)
        self.scheduler.add(self.agent, 10.0)
        self.scheduler.start()
        self.scheduler.run(duration=0.3)
        self.command("set_auto")
        assert self.agent.state == "IDLE.AUTO"

    def command(self, trigger: str, **kwargs: object) -> None:
        self.agent.submit(trigger, **kwargs)
        self.scheduler.step()

    def ask(self) -> int:
        """Start a mission (gated at high) and return the pending request's id."""
        self.command("start_mission", mission=wait_mission())
        pending = self.agent.gate.pending
        assert pending is not None and self.agent.state == "IDLE.AUTO"
        return pending.id


@pytest.fixture
def rig(agent_spec: AgentSpec) -> Rig:
    return Rig(agent_spec)


# -- the document ----------------------------------------------------------------------------------------------
def test_the_shipped_document_gates_goals_missions_and_mapping(agent_spec: AgentSpec) -> None:
    levels = {(t.trigger, t.dest): t.autonomy for t in agent_spec.transitions if t.autonomy}
    assert levels == {("goal", "EXEC"): "high", ("start_mission", "EXEC"): "high", ("begin_mapping", "MAPPING"): "low"}


SAFETY = [t for t in parse(TEXT).transitions if safety_reason(t.trigger, t.dest) is not None]


def test_the_safety_transitions_are_the_expected_ones() -> None:
    names = {(t.trigger, t.dest) for t in SAFETY}
    assert {("critical_failure", "SHUTDOWN.POWEROFF"), ("goal", "ERROR"), ("failed", "ERROR"), ("cancel", "IDLE.AUTO"),
            ("fault", "ERROR"), ("escalate", "SHUTDOWN.POWEROFF"), ("shutdown", "SHUTDOWN.POWEROFF"),
            ("restart", "SHUTDOWN.RESTART"), ("power_off", "SHUTDOWN.POWEROFF")} == names


@pytest.mark.parametrize("index", [t.index for t in SAFETY], ids=[f"{t.trigger}-{t.dest}" for t in SAFETY])
def test_a_level_on_a_safety_transition_is_refused_where_it_is_written(index: int) -> None:
    lines = TEXT.splitlines(keepends=True)
    spec = parse(TEXT).transitions[index]
    row = spec.where.line
    assert row is not None
    edited = lines[row - 1].replace("{trigger:", "{autonomy: low, trigger:", 1)
    text = "".join(lines[: row - 1]) + edited + "".join(lines[row:])
    with pytest.raises(ConfigError) as info:
        parse(text)
    assert "is a safety transition" in str(info.value) and "never gated" in str(info.value)
    assert (info.value.line, info.value.column) == (row, edited.index("autonomy") + 1)


def test_an_unknown_level_is_refused_at_its_value() -> None:
    text = TEXT.replace("after: set_mission_task, autonomy: high,", "after: set_mission_task, autonomy: medium,")
    with pytest.raises(ConfigError) as info:
        parse(text)
    assert "'autonomy' must be one of off, low, high, full, got 'medium'" in str(info.value)
    assert (info.value.line, info.value.column) == position(text, "medium")
    assert info.value.path.endswith(".autonomy")


def test_on_deny_needs_a_level_and_an_ungated_way_out() -> None:
    no_level = TEXT.replace("{trigger: set_manual, source: IDLE.AUTO, dest: IDLE.MANUAL,",
                            "{trigger: set_manual, source: IDLE.AUTO, dest: IDLE.MANUAL, on_deny: set_auto,")
    with pytest.raises(ConfigError, match="'on_deny' needs an 'autonomy' level") as info:
        parse(no_level)
    assert (info.value.line, info.value.column) == position(no_level, "on_deny: set_auto")
    nowhere = TEXT.replace("autonomy: high,\n     description: \"a validated", "autonomy: high, on_deny: save_map,\n"
                           "     description: \"a validated")
    with pytest.raises(ConfigError, match=r"on_deny trigger 'save_map' has no transition out of IDLE\.AUTO"):
        parse(nowhere)
    gated = TEXT.replace("autonomy: high,\n     description: \"a validated", "autonomy: high, on_deny: goal,\n"
                         "     description: \"a validated")
    with pytest.raises(ConfigError, match="the safe path must never wait"):
        parse(gated)
    assert parse(TEXT.replace("autonomy: high,\n     description: \"a validated",
                              "autonomy: high, on_deny: set_manual,\n     description: \"a validated"))


def test_levels_and_the_gate() -> None:
    gate = AutonomyGate()
    assert gate.level == "full" and not any(gate.gates(level) for level in LEVELS)
    gate.set_level("low")
    assert [gate.gates(level) for level in LEVELS] == [False, False, True, True]
    with pytest.raises(ConfigError, match="unknown autonomy level 'max'"):
        gate.set_level("max")
    with pytest.raises(ConfigError, match="timeout must be positive"):
        AutonomyGate(timeout_s=0)


# -- the running agent -----------------------------------------------------------------------------------------
def test_at_the_default_level_nothing_waits(agent_spec: AgentSpec) -> None:
    rig = Rig(agent_spec, level="full")
    rig.command("start_mission", mission=wait_mission())
    assert rig.agent.state == "EXEC" and rig.agent.gate.pending is None
    assert not any(r.decision for r in rig.agent.trace)


def test_a_gated_transition_waits_with_the_robot_held_still(rig: Rig) -> None:
    rig.port.joystick_command = (Twist(0.4, 0.0), 0.0)
    request_id = rig.ask()
    asked = rig.agent.trace[-1]
    assert (asked.trigger, asked.accepted, asked.decision) == ("start_mission", False, "requested")
    assert "waits for the operator" in asked.reason and "needs autonomy high" in asked.reason
    assert rig.heard[-1] is asked
    snap = rig.agent.snapshot()["autonomy"]
    assert snap["pending"]["id"] == request_id and snap["pending"]["dest"] == "EXEC" and snap["level"] == "low"
    stops, commands = rig.port.stops, len(rig.port.commands)
    rig.scheduler.run(duration=1.0)
    assert rig.agent.state == "IDLE.AUTO"
    assert rig.port.stops - stops >= 10, "every tick while waiting commands zero"
    assert all(twist == Twist() for _, twist, _ in rig.port.commands[commands:])
    # another gated request cannot pile up behind it
    rig.command("start_mission", mission=wait_mission())
    assert rig.agent.gate.pending is not None and rig.agent.gate.pending.id == request_id
    assert "is waiting for the operator" in rig.agent.trace[-1].reason


def test_confirm_proceeds_and_is_recorded(rig: Rig) -> None:
    request_id = rig.ask()
    assert rig.agent.answer(request_id + 1, True, by="alice") is not None  # not the pending one
    assert rig.agent.answer(request_id, True, by="alice") is None
    rig.scheduler.step()
    assert rig.agent.state == "EXEC" and rig.agent.gate.pending is None
    taken = next(r for r in rig.agent.trace if r.decision == "confirmed")
    assert (taken.trigger, taken.accepted, taken.dest, taken.decided_by) == ("start_mission", True, "EXEC", "alice")
    assert "confirmed by alice" in taken.reason and taken in rig.heard
    assert rig.agent.context.task is not None and rig.agent.context.task.name == "w"
    rig.scheduler.run(duration=3.0)
    assert rig.agent.state == "IDLE.AUTO" and rig.agent.task_reports[-1]["outcome"] == "reached"


def test_deny_takes_the_safe_path_and_is_recorded(rig: Rig) -> None:
    request_id = rig.ask()
    assert rig.agent.answer(request_id, False, by="bob") is None
    rig.scheduler.step()
    assert rig.agent.state == "IDLE.AUTO" and rig.agent.gate.pending is None and rig.agent.context.task is None
    denied = rig.agent.trace[-1]
    assert (denied.decision, denied.decided_by, denied.accepted) == ("denied", "bob", False)
    assert "denied by bob" in denied.reason and "stays in IDLE.AUTO" in denied.reason
    assert rig.heard[-1] is denied
    assert rig.agent.answer(request_id, True, by="bob") == "no transition is waiting for confirmation"


def test_no_answer_times_out_on_robot_time_into_the_safe_default(rig: Rig) -> None:
    rig.ask()
    rig.scheduler.run(duration=4.8)
    assert rig.agent.gate.pending is not None, "not before the timeout"
    rig.scheduler.run(duration=0.4)
    assert rig.agent.gate.pending is None and rig.agent.state == "IDLE.AUTO"
    timed_out = rig.agent.trace[-1]
    assert (timed_out.decision, timed_out.decided_by) == ("timed_out", "timeout")
    assert "no answer within 5 s" in timed_out.reason and timed_out in rig.heard


def test_on_deny_fires_its_trigger(agent_spec: AgentSpec) -> None:
    spec = parse(TEXT.replace("autonomy: high,\n     description: \"a validated",
                              "autonomy: high, on_deny: set_manual,\n     description: \"a validated"))
    rig = Rig(spec)
    request_id = rig.ask()
    rig.agent.answer(request_id, False, by="carol")
    rig.scheduler.step()
    assert rig.agent.state == "IDLE.MANUAL"
    denied = next(r for r in rig.agent.trace if r.decision == "denied")
    assert "fires 'set_manual'" in denied.reason
    assert rig.agent.trace[-1].trigger == "set_manual" and rig.agent.trace[-1].origin == "autonomy:denied"


@pytest.mark.parametrize("trigger", ["shutdown", "power_off", "fault"])
def test_safety_transitions_never_wait_and_supersede_a_pending_request(agent_spec: AgentSpec, trigger: str) -> None:
    rig = Rig(agent_spec, level="off")
    rig.ask()
    if trigger == "power_off":
        rig.link.power_off = True
        rig.scheduler.run(duration=0.2)
    elif trigger == "fault":
        from atemr.domain.status import ComponentHealth

        rig.port.components["left_motor"] = ComponentHealth(False, "over-temperature")
        rig.scheduler.run(duration=0.2)
    else:
        rig.command(trigger)
    assert rig.agent.state in ("SHUTDOWN.POWEROFF", "ERROR")
    assert rig.agent.gate.pending is None
    taken = next(r for r in rig.agent.trace if r.trigger == trigger and r.accepted)
    assert taken.decision == ""
    superseded = next(r for r in rig.agent.trace if r.decision == "superseded")
    assert superseded.trigger == "start_mission" and "before the operator answered" in superseded.reason


def test_a_level_given_to_a_safety_transition_in_code_is_ignored(agent_spec: AgentSpec) -> None:
    transitions = tuple(dataclasses.replace(t, autonomy="full") if t.trigger == "cancel" else t
                        for t in agent_spec.transitions)
    spec = dataclasses.replace(agent_spec, transitions=transitions)
    machine = Lifecycle(spec, AgentContext(port=RecordingPort()), initial="EXEC", gate=AutonomyGate("off"))
    record = machine.fire("cancel")
    assert record.accepted and record.dest == "IDLE.AUTO" and machine.gate is not None
    assert machine.gate.pending is None


def test_the_export_shows_the_levels(agent_spec: AgentSpec) -> None:
    import json

    from atemr.fsm.export import drawing_of, to_ascii, to_json

    ascii_text = to_ascii(drawing_of(agent_spec))
    assert "IDLE.AUTO --start_mission [mission_runnable, autonomy high]--> EXEC" in ascii_text
    rows = json.loads(to_json(drawing_of(agent_spec)))["machine"]["transitions"]
    assert {(r["trigger"], r["autonomy"]) for r in rows if r["autonomy"]} == {
        ("goal", "high"), ("start_mission", "high"), ("begin_mapping", "low")}


def test_raising_the_level_lets_the_waiting_transition_go(rig: Rig) -> None:
    rig.ask()
    rig.agent.set_autonomy("high", by="alice")
    rig.scheduler.step()
    assert rig.agent.state == "EXEC"
    taken = next(r for r in rig.agent.trace if r.decision == "confirmed")
    assert taken.decided_by == "level high" and taken.dest == "EXEC"


def test_the_level_and_timeout_come_from_the_configuration(port: RecordingPort, link: RecordingLink) -> None:
    from atemr.config import load_config

    config = load_config(environ={"ATEMR_AGENT__AUTONOMY": "low"}, overrides={"agent.confirm_timeout_s": 2.5})
    agent = Agent.from_config(config, port, link)
    assert (agent.gate.level, agent.gate.timeout_s) == ("low", 2.5)
    with pytest.raises(ConfigError, match="autonomy"):
        load_config(environ={}, overrides={"agent.autonomy": "max"})


def test_a_recorder_keeps_every_decision_and_by_whom(rig: Rig) -> None:
    from atemr.fsm.recording import AgentRecorder
    from atemr.fsm.trace_timeline import TraceTimeline

    records: list[dict[str, object]] = []
    recorder = AgentRecorder(rig.agent, records.append)
    records.extend(recorder.preamble())
    recorder.attach()
    request_id = rig.ask()
    rig.agent.answer(request_id, False, by="bob")
    rig.scheduler.step()
    rig.ask()
    rig.scheduler.run(duration=5.2)
    decisions = [(r["decision"], r["decided_by"]) for r in records if r["k"] == "tr" and "decision" in r]
    assert decisions == [("requested", ""), ("denied", "bob"), ("requested", ""), ("timed_out", "timeout")]
    rows = TraceTimeline(records).transitions()
    assert [r.get("decision") for r in rows if r.get("decision")] == ["requested", "denied", "requested", "timed_out"]
    assert next(r for r in rows if r.get("decision") == "denied")["decided_by"] == "bob"
