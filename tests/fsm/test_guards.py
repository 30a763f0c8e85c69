"""The guards' answers and reasons, every registered guard and callback covered, and random trigger
sequences that never break the machine."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.domain.status import ComponentHealth
from atemr.fsm.guards import GuardInput, callbacks, guards
from atemr.fsm.machine import Lifecycle
from atemr.fsm.spec import AgentSpec
from atemr.msgs import Pose2D
from atemr.trees.behaviours import behaviours
from atemr.trees.context import AgentContext
from atemr.trees.fakes import RecordingLink, RecordingPort, StraightLineNavigation
from atemr.trees.missions import parse_mission
from atemr.yamlsafe import load_yaml

TESTED_GUARDS = {"goal_valid", "auto_mode", "mission_runnable", "level1_ok", "map_name_valid", "task_failed"}
TESTED_CALLBACKS = {"begin_mapping", "save_map", "discard_map", "abandon_mapping", "stop_motors", "set_goal_task",
                    "set_mission_task", "clear_task", "record_error", "clear_error", "remember_task_failed"}


def test_every_registered_guard_and_callback_is_tested_here() -> None:
    assert set(guards) == TESTED_GUARDS
    assert set(callbacks) == TESTED_CALLBACKS


def test_task_failed_holds_from_a_failed_task_until_the_error_is_cleared() -> None:
    g = GuardInput(AgentContext(port=RecordingPort()), {})
    assert guards.get("task_failed")(g) == "the error was not a failed goal or mission in AUTO"
    callbacks.get("remember_task_failed")(g)
    assert guards.get("task_failed")(g) is None
    callbacks.get("clear_error")(g)
    assert guards.get("task_failed")(g) is not None and g.context.error is None


def check(guard: str, port: RecordingPort | None = None, link: RecordingLink | None = None, /,
          navigation: StraightLineNavigation | None = None, **kwargs: object) -> str | None:
    context = AgentContext(port=port or RecordingPort(), link=link or RecordingLink(), navigation=navigation)
    return guards.get(guard)(GuardInput(context, kwargs))


def test_goal_valid_without_navigation_says_so() -> None:
    assert check("goal_valid", goal=Pose2D(1, 1, 0)) == "navigation is not available on this robot"


def test_goal_valid_without_the_go_to_pose_behaviour_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(behaviours._items, "GoToPose")
    port = RecordingPort()
    answer = check("goal_valid", port, navigation=StraightLineNavigation(port), goal=Pose2D(1, 1, 0))
    assert answer == "navigation is not available in this build (no 'GoToPose' behaviour)"


@pytest.mark.parametrize(("goal", "refuse", "reason"), [
    ({"x": 1}, None, "a goal must be a Pose2D, got dict"),
    (Pose2D(math.nan, 0, 0), None, "goal has a non-finite coordinate"),
    (Pose2D(1, 1, math.inf), None, "goal has a non-finite coordinate"),
    (Pose2D(1, 1, 0), "goal (1.00, 1.00, 0.00 rad) is outside the map", "is outside the map"),
    (Pose2D(1, 1, 0), "the robot is not localized", "not localized"),
])
def test_goal_valid_reasons(goal: object, refuse: str | None, reason: str) -> None:
    port = RecordingPort()
    answer = check("goal_valid", port, navigation=StraightLineNavigation(port, refuse=refuse), goal=goal)
    assert answer is not None and reason in answer


def test_goal_valid_passes_when_navigation_accepts() -> None:
    port = RecordingPort()
    assert check("goal_valid", port, navigation=StraightLineNavigation(port), goal=Pose2D(1, 1, 0)) is None


def test_auto_mode_names_the_mode() -> None:
    port = RecordingPort()
    assert "AUTO mode only (the robot is in MANUAL)" in str(check("auto_mode", port))
    context = AgentContext(port=port, mode="AUTO")
    assert guards.get("auto_mode")(GuardInput(context, {})) is None


def test_level1_and_map_name_and_mission() -> None:
    assert check("level1_ok") is None
    port = RecordingPort()
    port.components["imu"] = ComponentHealth(False, "silent")
    assert check("level1_ok", port, RecordingLink(heartbeat=False)) == \
        "level-1 status not OK (heartbeat lost; unhealthy: imu)"
    assert check("map_name_valid", name="kitchen-2") is None
    for bad in ("", ".hidden", "a/b", "x" * 65, 7):
        assert check("map_name_valid", name=bad) is not None
    wait = parse_mission(load_yaml("w", text="mission:\n  name: w\n  steps: [{wait: {duration_s: 1}}]\n"), "w")
    assert check("mission_runnable", mission=wait) is None
    assert "needs a validated Mission" in str(check("mission_runnable", mission="trees/missions/x.yaml"))
    go = parse_mission(load_yaml("g", text="mission:\n  name: g\n  steps: [{wait: {duration_s: 1}}, "
                                           "{go_to: {x_m: 1, y_m: 1}}]\n"), "g")
    assert check("mission_runnable", mission=go) == \
        "mission 'g' drives to poses (steps 1) and navigation is not available on this robot"
    port = RecordingPort()
    assert check("mission_runnable", port, navigation=StraightLineNavigation(port), mission=go) is None


def test_auto_and_missions_need_the_confidence_above_its_limit(agent_spec: AgentSpec) -> None:
    """Issue 21: "localized" is the confidence number at or above its limit, and the guards say so with it."""
    lost = RecordingPort(is_localized=False)
    answer = check("level1_ok", lost)
    assert answer == ("level-1 status not OK (not localized (confidence 0%, needs 70%; lost): set the robot's "
                      "position on the map (SET POSITION) or press FIND POSITION)")
    wait = parse_mission(load_yaml("w", text="mission:\n  name: w\n  steps: [{wait: {duration_s: 1}}]\n"), "w")
    assert "mission 'w' refused: not localized" in str(check("mission_runnable", lost, mission=wait))
    assert check("level1_ok", RecordingPort(is_localized=True)) is None
    assert check("level1_ok", RecordingPort(is_localized=None)) is None  # a robot that cannot localize at all
    # the machine answers the same at once, without firing (the dashboard's MANUAL/AUTO toggle)
    context = AgentContext(port=lost, link=RecordingLink())
    machine = Lifecycle(agent_spec, context, initial="IDLE.MANUAL")
    assert "not localized" in str(machine.refusal("set_auto")) and machine.state == "IDLE.MANUAL"
    assert "'reached' is not valid in state IDLE.MANUAL" in str(machine.refusal("reached"))
    lost.is_localized = True
    assert machine.refusal("set_auto") is None and machine.state == "IDLE.MANUAL" and lost.modes == []


def test_callbacks_act_through_the_port() -> None:
    port = RecordingPort(mapping_available=True)
    context = AgentContext(port=port)

    def run(callback: str, /, **kw: object) -> None:
        callbacks.get(callback)(GuardInput(context, kw, ["why"]))

    run("begin_mapping")
    assert port.mapping and context.mapping_active
    run("save_map", name="flat")
    run("abandon_mapping")
    assert port.maps == ["flat"], "nothing to abandon after a save"
    run("begin_mapping")
    run("abandon_mapping")
    run("discard_map")
    assert port.maps == ["flat", None, None]
    run("stop_motors")
    assert port.stops == 1
    run("set_goal_task", goal=Pose2D(1, 2, 0))
    assert context.task.name == "goal" and context.task.steps[0].behaviours == ("GoToPose",)
    run("clear_task")
    assert context.task is None
    run("record_error", goal=Pose2D(1, 2, 0))
    assert type(context.error).__name__ == "NavigationError" and str(context.error) == "why"
    run("clear_error")
    assert context.error is None
    wait = parse_mission(load_yaml("w", text="mission:\n  name: w\n  steps: [{wait: {duration_s: 1}}]\n"), "w")
    run("set_mission_task", mission=wait)
    assert context.task is wait


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(
    ["startup_ok", "critical_failure", "set_auto", "set_manual", "goal", "start_mission", "begin_mapping",
     "reached", "failed", "cancel", "save_map", "discard_map", "fault", "recover", "escalate", "shutdown",
     "restart", "restarted", "power_off", "bogus"]), st.booleans()), max_size=30))
def test_random_triggers_never_break_the_machine(agent_spec: AgentSpec, steps: list[tuple[str, bool]]) -> None:
    port = RecordingPort(mapping_available=True, is_localized=True)
    machine = Lifecycle(agent_spec, AgentContext(port=port, link=RecordingLink(),
                                                 navigation=StraightLineNavigation(port)))
    wait = parse_mission(load_yaml("w", text="mission:\n  name: w\n  steps: [{wait: {duration_s: 1}}]\n"), "w")
    for trigger, good in steps:
        before = machine.state
        kwargs = {"goal": Pose2D(1, 1, 0) if good else Pose2D(math.nan, 0, 0), "mission": wait,
                  "name": "flat" if good else "../x"}
        record = machine.fire(trigger, **kwargs)
        assert machine.state in agent_spec.leaves()
        if not record.accepted:
            assert machine.state == before and record.reason
        else:
            assert record.dest == machine.state
