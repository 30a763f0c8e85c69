"""Run one mission on an agent to its end and report it: what ``atemr mission run`` does once the robot is
wired (the robot, simulated or real, is whatever scheduler the agent is ticked by).

`run_mission` drives the agent the way an operator would: wait for start-up to reach IDLE, switch to AUTO,
start the mission, and tick until Exec ends (or ``timeout_s`` of robot time passes, which cancels it).
The JSON result names the outcome, each step (status, times, final pose, position and heading error), the
agent's state trace and, when the mission could not start, the agent's reason.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict
from typing import Any

from atemr.fsm.agent import Agent
from atemr.fsm.codes import top_level
from atemr.trees.missions import Mission


def _until(agent: Agent, step: Callable[[], float], done: Callable[[], bool], deadline: float) -> bool:
    while not done():
        if agent.context.now >= deadline or agent.halted:
            return done()
        step()
    return True


def _wait(agent: Agent, step: Callable[[], float], seconds: float) -> None:
    until = agent.context.now + seconds
    while agent.context.now < until and not agent.halted:
        step()


def _command(agent: Agent, step: Callable[[], float], trigger: str, deadline: float, **kwargs: Any) -> str | None:
    """Submit and wait for the answer; None when accepted, else the reason."""
    command_id = agent.submit(trigger, origin="mission run", **kwargs)
    _until(agent, step, lambda: agent.result(command_id) is not None, deadline)
    result = agent.result(command_id)
    if result is None:
        return f"no answer to '{trigger}' before the time limit"
    return None if result.accepted and result.dest is not None and top_level(result.dest) != "ERROR" \
        else result.reason or f"'{trigger}' led to {result.dest}"


def run_mission(agent: Agent, step: Callable[[], float], mission: Mission, *, timeout_s: float = 600.0,
                startup_timeout_s: float = 30.0) -> dict[str, Any]:
    """Run ``mission`` on ``agent``; ``step`` advances the robot by one scheduler tick (``Scheduler.step``)."""
    start = agent.context.now
    result: dict[str, Any] = {"mission": mission.name, "file": mission.file, "outcome": "not started",
                              "reason": None, "steps": [], "started_s": start}
    reports = len(agent.task_reports)
    reason = None
    deadline = start + startup_timeout_s
    if not _until(agent, step, lambda: top_level(agent.state) == "IDLE", deadline):
        reason = f"the agent did not reach IDLE within {startup_timeout_s:g} s (state {agent.state})"
    while reason is None and agent.state != "IDLE.AUTO":
        # AUTO is refused until every level-1 status is OK (sensors still coming up): ask again, as an
        # operator would, until the start-up time is over.
        reason = _command(agent, step, "set_auto", agent.context.now + 5.0)
        if reason is not None and agent.context.now < deadline and top_level(agent.state) == "IDLE":
            _wait(agent, step, 0.5)
            reason = None
    if reason is None:
        reason = _command(agent, step, "start_mission", agent.context.now + 5.0, mission=mission)
    if reason is not None:
        result["reason"] = reason
    else:
        deadline = agent.context.now + timeout_s
        if not _until(agent, step, lambda: len(agent.task_reports) > reports, deadline):
            _command(agent, step, "cancel", agent.context.now + 5.0)
            result["reason"] = f"mission timed out after {timeout_s:g} s and was cancelled"
        if len(agent.task_reports) > reports:
            result.update(agent.task_reports[-1])
            if result["reason"] is not None:
                result["outcome"] = "timeout"
    pose = agent.context.port.pose()
    result["final_pose"] = asdict(pose) if pose is not None else None
    result["state"] = agent.state
    result["trace"] = [r.as_dict() for r in agent.trace if r.accepted]
    result["finished_s"] = agent.context.now
    return result
