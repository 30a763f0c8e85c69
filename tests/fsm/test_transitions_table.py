"""One row per transition of trees/agent.yaml: source, trigger, guard inputs, destination, 0x153 state code.

The rows are written by hand; `test_every_yaml_transition_has_a_row` compares them with the document, so a
transition added to the YAML without a row here (or a row for a transition that was removed) fails.
"""

from __future__ import annotations

from typing import Any

import pytest

from atemr.domain.status import StateCode, state_code
from atemr.fsm.autonomy import LEVELS as AUTONOMY_LEVELS
from atemr.fsm.autonomy import AutonomyGate
from atemr.fsm.machine import Lifecycle
from atemr.fsm.spec import AgentSpec
from atemr.io.can import PrimaryStatus
from atemr.registry import Registry
from atemr.trees.context import AgentContext
from atemr.trees.fakes import RecordingPort

# (source as written, trigger, dest as written, guard inputs, expected leaf state, expected 0x153 code)
ROWS: list[tuple[str, str, str, dict[str, bool], str, StateCode]] = [
    ("STARTUP", "startup_ok", "IDLE", {}, "IDLE.MANUAL", StateCode.IDLE),
    ("STARTUP", "critical_failure", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("IDLE.MANUAL", "set_auto", "IDLE.AUTO", {"level1_ok": True}, "IDLE.AUTO", StateCode.IDLE),
    ("IDLE.AUTO", "set_manual", "IDLE.MANUAL", {}, "IDLE.MANUAL", StateCode.IDLE),
    ("IDLE.AUTO", "goal", "EXEC", {"goal_valid": True}, "EXEC", StateCode.EXEC),
    ("IDLE.AUTO", "goal", "ERROR", {"goal_valid": False}, "ERROR", StateCode.ERROR),
    ("IDLE.MANUAL", "goal", "ERROR", {"auto_mode": False}, "ERROR", StateCode.ERROR),
    ("IDLE.AUTO", "start_mission", "EXEC", {"mission_runnable": True}, "EXEC", StateCode.EXEC),
    ("IDLE.MANUAL", "begin_mapping", "MAPPING", {}, "MAPPING", StateCode.MAPPING),
    ("EXEC", "reached", "IDLE.AUTO", {}, "IDLE.AUTO", StateCode.IDLE),
    ("EXEC", "failed", "ERROR", {}, "ERROR", StateCode.ERROR),
    ("EXEC", "cancel", "IDLE.AUTO", {}, "IDLE.AUTO", StateCode.IDLE),
    ("MAPPING", "save_map", "IDLE", {"map_name_valid": True}, "IDLE.MANUAL", StateCode.IDLE),
    ("MAPPING", "discard_map", "IDLE", {}, "IDLE.MANUAL", StateCode.IDLE),
    ("IDLE", "fault", "ERROR", {}, "ERROR", StateCode.ERROR),
    ("EXEC", "fault", "ERROR", {}, "ERROR", StateCode.ERROR),
    ("MAPPING", "fault", "ERROR", {}, "ERROR", StateCode.ERROR),
    ("ERROR", "recover", "IDLE.AUTO", {"task_failed": True, "level1_ok": True}, "IDLE.AUTO", StateCode.IDLE),
    ("ERROR", "recover", "IDLE", {"task_failed": False}, "IDLE.MANUAL", StateCode.IDLE),
    ("ERROR", "recover", "IDLE", {"level1_ok": False}, "IDLE.MANUAL", StateCode.IDLE),
    ("ERROR", "escalate", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("IDLE", "shutdown", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("EXEC", "shutdown", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("MAPPING", "shutdown", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("ERROR", "shutdown", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("IDLE", "restart", "SHUTDOWN.RESTART", {}, "SHUTDOWN.RESTART", StateCode.SHUTDOWN),
    ("ERROR", "restart", "SHUTDOWN.RESTART", {}, "SHUTDOWN.RESTART", StateCode.SHUTDOWN),
    ("SHUTDOWN.RESTART", "restarted", "STARTUP", {}, "STARTUP", StateCode.STARTUP),
    ("STARTUP", "power_off", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("IDLE", "power_off", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("EXEC", "power_off", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("MAPPING", "power_off", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("ERROR", "power_off", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
    ("SHUTDOWN.RESTART", "power_off", "SHUTDOWN.POWEROFF", {}, "SHUTDOWN.POWEROFF", StateCode.SHUTDOWN),
]


#: The rows whose transition carries an autonomy level (every other row has none), and that level.
LEVELS: dict[tuple[str, str, str], str] = {
    ("IDLE.AUTO", "goal", "EXEC"): "high",
    ("IDLE.AUTO", "start_mission", "EXEC"): "high",
    ("IDLE.MANUAL", "begin_mapping", "MAPPING"): "low",
}


def controlled(spec: AgentSpec, inputs: dict[str, bool], source: str, gate: AutonomyGate | None = None
               ) -> tuple[Lifecycle, list[str]]:
    """A lifecycle in ``source`` whose guards answer from ``inputs`` and whose callbacks only record."""
    guards: Registry[Any] = Registry("test-guards")
    callbacks: Registry[Any] = Registry("test-callbacks")
    called: list[str] = []
    names = {g for t in spec.transitions for g in (*t.conditions, *t.unless)}
    for name in names:
        guards.add(name, lambda g, n=name: None if inputs.get(n, True) else f"{n} is false in this row")
    for name in {c for t in spec.transitions for c in (*t.before, *t.after)} | {
            c for s in spec.states.values() for c in (*s.on_enter, *s.on_exit)}:
        callbacks.add(name, lambda g, n=name: called.append(n))
    context = AgentContext(port=RecordingPort())
    return Lifecycle(spec, context, guard_registry=guards, callback_registry=callbacks,
                     initial=spec.leaf_of(source), gate=gate), called


def test_every_yaml_transition_has_a_row(agent_spec: AgentSpec) -> None:
    in_yaml = {(s, t.trigger, t.dest) for t in agent_spec.transitions for s in t.sources}
    in_table = {(row[0], row[1], row[2]) for row in ROWS}
    assert in_yaml - in_table == set(), "transitions in the YAML without a row in this table"
    assert in_table - in_yaml == set(), "rows in this table for transitions the YAML does not have"


@pytest.mark.parametrize(("source", "trigger", "dest", "inputs", "expected", "code"), ROWS,
                         ids=[f"{r[0]}-{r[1]}-{r[2]}" for r in ROWS])
def test_transition(agent_spec: AgentSpec, source: str, trigger: str, dest: str, inputs: dict[str, bool],
                    expected: str, code: StateCode) -> None:
    machine, called = controlled(agent_spec, inputs, source)
    record = machine.fire(trigger, reason="table row")
    assert record.accepted, record.reason
    assert (record.source, record.dest, machine.state) == (agent_spec.leaf_of(source), expected, expected)
    assert state_code(machine.state) == code
    frame = PrimaryStatus(state=state_code(machine.state)).encode()
    assert frame.arbitration_id == 0x153 and frame.data[2] == int(code)
    spec = next(t for t in agent_spec.transitions if t.trigger == trigger and source in t.sources and t.dest == dest)
    left, entered = agent_spec.ancestors(record.source), agent_spec.ancestors(expected)
    exits = [c for s in left if s not in entered for c in agent_spec.states[s].on_exit]
    enters = [c for s in reversed(entered) if s not in left for c in agent_spec.states[s].on_enter]
    assert called == [*spec.before, *exits, *enters, *spec.after]


def test_every_autonomy_level_has_its_row(agent_spec: AgentSpec) -> None:
    in_yaml = {(s, t.trigger, t.dest): t.autonomy for t in agent_spec.transitions for s in t.sources if t.autonomy}
    assert in_yaml == LEVELS


@pytest.mark.parametrize("level", AUTONOMY_LEVELS)
@pytest.mark.parametrize(("source", "trigger", "dest", "inputs", "expected", "code"), ROWS,
                         ids=[f"{r[0]}-{r[1]}-{r[2]}" for r in ROWS])
def test_transition_at_each_autonomy_level(agent_spec: AgentSpec, level: str, source: str, trigger: str, dest: str,
                                           inputs: dict[str, bool], expected: str, code: StateCode) -> None:
    """Below its level a row's transition waits for the operator (the machine stays); otherwise it is taken."""
    gate = AutonomyGate(level)
    machine, called = controlled(agent_spec, inputs, source, gate)
    record = machine.fire(trigger, reason="table row")
    needed = LEVELS.get((source, trigger, dest))
    if needed is not None and AUTONOMY_LEVELS.index(needed) > AUTONOMY_LEVELS.index(level):  # type: ignore[arg-type]
        assert (record.accepted, record.decision, machine.state) == (False, "requested", agent_spec.leaf_of(source))
        assert gate.pending is not None and gate.pending.dest == expected and called == []
    else:
        assert record.accepted and machine.state == expected and record.decision == ""
        assert gate.pending is None


GUARDED = [r for r in ROWS if any(r[3].values())]


@pytest.mark.parametrize(("source", "trigger", "dest", "inputs", "expected", "code"), GUARDED,
                         ids=[f"{r[0]}-{r[1]}" for r in GUARDED])
def test_a_failing_condition_blocks_the_transition(agent_spec: AgentSpec, source: str, trigger: str, dest: str,
                                                   inputs: dict[str, bool], expected: str, code: StateCode) -> None:
    flipped = {name: not value for name, value in inputs.items()}
    machine, _ = controlled(agent_spec, flipped, source)
    record = machine.fire(trigger)
    assert record.dest != expected
    if not record.accepted:
        assert "is false in this row" in record.reason
        assert machine.state == agent_spec.leaf_of(source)


def test_every_trigger_not_valid_in_a_state_is_refused_with_a_reason(agent_spec: AgentSpec) -> None:
    triggers = {t.trigger for t in agent_spec.transitions}
    for state in agent_spec.leaves():
        machine, _ = controlled(agent_spec, {}, state)
        for trigger in sorted(triggers - set(agent_spec.triggers_from(state))):
            record = machine.fire(trigger)
            assert not record.accepted and machine.state == state
            assert f"'{trigger}' is not valid in state {state}" in record.reason


def test_guard_reasons_reach_the_record(agent_spec: AgentSpec) -> None:
    machine, _ = controlled(agent_spec, {"level1_ok": False}, "IDLE.MANUAL")
    record = machine.fire("set_auto")
    assert not record.accepted and record.reason == "level1_ok is false in this row"
    assert machine.trace[-1] is record
