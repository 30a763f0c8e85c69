"""Run one mission on an agent to its end and report it: what ``atemr mission run`` does once the robot is
wired (the robot, simulated or real, is whatever scheduler the agent is ticked by).

`MissionRun` drives the agent the way an operator would: wait for start-up to reach IDLE, switch to AUTO,
start the mission, and follow it until Exec ends (or ``timeout_s`` of robot time passes, which cancels it).
It never blocks: `MissionRun.poll` looks at the agent after a tick and takes the next step, so the same run
works in a headless simulation (`run_mission` steps the scheduler itself) and on a running robot (the
control channel polls it from a scheduler component, `atemr.robot.control`).

The JSON result names the outcome, each step (status, times, final pose, position and heading error), the
agent's state trace during the run and, when the mission could not start or was stopped, the reason.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict
from typing import Any

from atemr.domain.status import top_level
from atemr.fsm.agent import Agent
from atemr.trees.missions import Mission

#: Robot seconds to wait for the agent's answer to a command (it answers at its next tick).
ANSWER_S = 5.0
#: Robot seconds between two requests for AUTO while the sensors are still coming up.
AUTO_RETRY_S = 0.5
#: `MissionRun._answer`'s word for "the start waits for the operator's confirmation".
CONFIRMING = "waits for the operator's confirmation"


class MissionRun:
    """One mission on ``agent``, advanced by `poll` after each agent tick; ``result`` once `done`."""

    def __init__(self, agent: Agent, mission: Mission, *, timeout_s: float = 600.0, startup_timeout_s: float = 30.0,
                 origin: str = "mission run") -> None:
        self.agent = agent
        self.mission = mission
        self.timeout_s = timeout_s
        self.origin = origin
        self.started_s = agent.context.now
        self.result: dict[str, Any] = {"mission": mission.name, "file": mission.file, "outcome": "not started",
                                       "reason": None, "steps": [], "started_s": self.started_s}
        #: startup → auto → start → (confirming) → running → cancelling → done; ``confirming`` while the
        #: mission's start waits for the operator (the robot's autonomy level is below the transition's).
        self.phase = "startup"
        self._startup_deadline = self.started_s + startup_timeout_s
        self._deadline = self._startup_deadline
        self._last_report = agent.task_reports[-1] if agent.task_reports else None
        self._pending: tuple[int, str, float] | None = None
        self._retry_at = self.started_s
        self._stop_reason: str | None = None
        self._timed_out = False
        self._asked_s = self.started_s

    @property
    def done(self) -> bool:
        return self.phase == "done"

    def cancel(self, reason: str) -> None:
        """Stop the mission (cancel it on the agent if it already runs); ``reason`` goes into the result."""
        if self.done or self._stop_reason is not None:
            return
        self._stop_reason = reason
        if self.phase in ("startup", "auto", "start") and self._pending is None:
            self._finish(outcome="cancelled")
        elif self.phase == "confirming":
            self._withdraw()
        elif self.phase == "running":
            self._submit("cancel")
            self.phase = "cancelling"
        # a pending command (set_auto, start_mission) is answered first; `poll` then stops the run

    def abandon(self, reason: str) -> None:
        """End the run now, without waiting for the agent (the robot is stopping); idempotent."""
        if self.done:
            return
        running = self.phase in ("running", "cancelling")
        progress = self.agent.task_progress() if running else None
        if progress is not None and self._new_report() is None:
            self.result.update(progress)
        self._finish(reason=reason, outcome=None if self._new_report() is not None else
                     "interrupted" if running else "not started")

    def poll(self) -> bool:  # noqa: PLR0912  one branch per run phase; a method per phase would be the fix
        """Look at the agent and take the next step of the run; True once the run is over."""
        agent = self.agent
        for _ in range(4):  # a few phases may pass in one poll (IDLE already reached, AUTO already on)
            if self.done:
                return True
            phase = self.phase
            if phase == "startup" and top_level(agent.state) != "IDLE" and (
                    agent.halted or agent.context.now >= self._startup_deadline):
                self._finish(reason=f"the agent did not reach IDLE within "
                                    f"{self._startup_deadline - self.started_s:g} s (state {agent.state})")
            elif agent.halted:
                self._finish(reason=f"the agent halted (state {agent.state})")
            elif self._pending is not None:
                answer = self._answer()
                if answer is None:
                    return False
                self._answered(*answer)
            elif phase == "startup":
                if top_level(agent.state) != "IDLE":
                    return False
                self.phase = "auto"
            elif phase == "auto":
                if agent.state == "IDLE.AUTO":
                    self.phase = "start"
                elif agent.context.now >= self._retry_at:
                    self._submit("set_auto")
                else:
                    return False
            elif phase == "start":
                self._submit("start_mission", mission=self.mission)
            elif phase == "running":
                if self._new_report() is not None:
                    self._finish()
                elif agent.context.now >= self._deadline:
                    self._timed_out = True
                    self._stop_reason = f"mission timed out after {self.timeout_s:g} s and was cancelled"
                    self._submit("cancel")
                    self.phase = "cancelling"
                else:
                    return False
            elif phase == "confirming":
                request = agent.gate.pending
                if request is not None and request.trigger == "start_mission":
                    return False
                self._confirmed()
            elif phase == "cancelling":
                return False  # waits for the cancel's answer (handled above)
        return self.done

    # -- internals ---------------------------------------------------------------------------------
    def _submit(self, trigger: str, **kwargs: Any) -> None:
        command_id = self.agent.submit(trigger, origin=self.origin, **kwargs)
        self._pending = (command_id, trigger, self.agent.context.now + ANSWER_S)

    def _answer(self) -> tuple[str, str | None] | None:
        """(trigger, None when accepted else why) once the pending command is answered or overdue."""
        assert self._pending is not None
        command_id, trigger, deadline = self._pending
        result = self.agent.result(command_id)
        if result is None:
            if self.agent.context.now < deadline:
                return None
            self._pending = None
            return trigger, f"no answer to '{trigger}' before the time limit"
        self._pending = None
        if result.decision == "requested":
            return trigger, CONFIRMING
        if result.accepted and result.dest is not None and top_level(result.dest) != "ERROR":
            return trigger, None
        return trigger, result.reason or f"'{trigger}' led to {result.dest}"

    def _answered(self, trigger: str, why: str | None) -> None:
        now = self.agent.context.now
        if trigger == "cancel":
            self._finish()
        elif self._stop_reason is not None:  # cancelled while set_auto or start_mission was on its way
            if trigger == "start_mission" and why == CONFIRMING:
                self.phase, self._asked_s = "confirming", now
                self._withdraw()
            elif trigger == "start_mission" and why is None:
                self._submit("cancel")
                self.phase = "cancelling"
            else:
                self._finish(outcome="cancelled")
        elif trigger == "set_auto":
            # AUTO is refused until every level-1 status is OK (sensors still coming up): ask again, as an
            # operator would, until the start-up time is over.
            if why is not None and (now >= self._startup_deadline or top_level(self.agent.state) != "IDLE"):
                self._finish(reason=why)
            else:
                self._retry_at = now + (AUTO_RETRY_S if why is not None else 0.0)
        elif trigger == "start_mission":
            if why == CONFIRMING:
                self.phase = "confirming"
                self._asked_s = now
            elif why is not None:
                self._finish(reason=why)
            else:
                self.phase = "running"
                self._deadline = now + self.timeout_s

    def _withdraw(self) -> None:
        """Deny our own start still waiting for the operator (a cancel); `poll` then sees the denial."""
        request = self.agent.gate.pending
        if request is not None and request.trigger == "start_mission":
            self.agent.answer(request.id, False, by=self.origin)

    def _confirmed(self) -> None:
        """The operator has decided on the mission's start: running if it was taken, else why not."""
        records = [r for r in self.agent.trace if r.trigger == "start_mission" and r.t >= self._asked_s
                   and r.decision != "requested"]
        last = records[-1] if records else None
        if last is not None and last.accepted and last.dest is not None and top_level(last.dest) == "EXEC":
            self.phase = "running"
            self._deadline = self.agent.context.now + self.timeout_s
            if self._stop_reason is not None:
                self._submit("cancel")
                self.phase = "cancelling"
        elif self._stop_reason is not None:
            self._finish(outcome="cancelled")
        else:
            self._finish(reason=f"the operator did not confirm the mission: {last.reason if last else 'no answer'}")

    def _new_report(self) -> dict[str, Any] | None:
        reports = self.agent.task_reports
        last = reports[-1] if reports else None
        return last if last is not None and last is not self._last_report else None

    def _finish(self, *, reason: str | None = None, outcome: str | None = None) -> None:
        agent = self.agent
        result = self.result
        report = self._new_report()
        if report is not None:
            result.update(report)
        if outcome is not None:
            result["outcome"] = outcome
        if self._timed_out and report is not None:
            result["outcome"] = "timeout"
        result["reason"] = reason or self._stop_reason or result.get("reason")
        pose = agent.context.port.pose()
        result["final_pose"] = asdict(pose) if pose is not None else None
        result["state"] = agent.state
        result["trace"] = [r.as_dict() for r in agent.trace if r.accepted and r.t >= self.started_s]
        result["finished_s"] = agent.context.now
        self.phase = "done"


def run_mission(agent: Agent, step: Callable[[], float], mission: Mission, *, timeout_s: float = 600.0,
                startup_timeout_s: float = 30.0) -> dict[str, Any]:
    """Run ``mission`` on ``agent``; ``step`` advances the robot by one scheduler tick (``Scheduler.step``)."""
    run = MissionRun(agent, mission, timeout_s=timeout_s, startup_timeout_s=startup_timeout_s)
    while not run.poll():
        step()
    return run.result
