"""`RobotControl`: the commands of the control channel (`atemr.io.control_socket`) on the running robot.

``atemr mission run FILE`` without ``--headless`` connects here. The commands:

- ``{"cmd": "status"}`` → ``{"ok": true, "status": {...}}``: the agent's state, mode, task and its progress,
  the last finished task, the valid triggers, the pose, and the mission run from this channel, if any.
- ``{"cmd": "start", "mission": {"text": YAML, "file": NAME} | "goals": [{x_m, y_m, yaw_rad}, ...],
  "timeout_s": 600, "follow": true}``: the mission document is validated again here (a client's check is
  not trusted); an invalid one, or a robot that is busy (Exec, Mapping, shutting down, another mission from
  here), is refused and nothing starts. Then, as an operator would: wait for IDLE, switch to AUTO, start
  the mission through the agent's inbox (`Agent.submit`, as the dashboard does) — `atemr.fsm.mission_run`.
  The answers follow on the same connection: ``started``, then ``state`` (each agent state change),
  ``phase`` (the run's: ``confirming`` while the start waits for the operator's confirmation on the
  dashboard, when the robot's autonomy level is below the mission's), ``step`` (each step status change,
  with its report), and last ``result``: the same JSON as a headless
  ``atemr mission run --json``. The connection that started a mission (with ``follow``, the default) owns
  it: if it goes away before the end (the client was killed), the mission is cancelled — nobody could stop
  it with Ctrl-C any more. With ``"follow": false`` the answer is ``started`` alone and the mission runs on.
- ``{"cmd": "follow"}``: the same answers for the mission running from here, from its start.
- ``{"cmd": "cancel", "reason": "..."}``: cancel the mission started here, or the agent's current task
  (a goal or mission from the dashboard).

The socket threads never touch the agent: every action is queued for this component, which runs it on the
robot's thread (as the dashboard gateway's pump does) and advances the mission after each agent tick.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import asdict
from typing import Any

from atemr.domain.status import top_level
from atemr.errors import ControlError, brief
from atemr.fsm.agent import Agent
from atemr.fsm.mission_run import MissionRun
from atemr.io.control_socket import ControlConnection, ControlServer, control_socket_path
from atemr.io.sim.simulation import Simulation
from atemr.msgs import Pose2D
from atemr.robot.core import Robot
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.trees.missions import Mission, mission_from_goals, parse_mission
from atemr.yamlsafe import load_yaml

log = logging.getLogger(__name__)

#: Real seconds a socket thread waits for the robot's thread to take its action.
ANSWER_TIMEOUT_S = 10.0
#: Real seconds between two checks that a follower is still connected.
FOLLOW_POLL_S = 0.5
#: A mission's longest allowed run, robot seconds (one week).
MAX_TIMEOUT_S = 7 * 86_400.0
MAX_GOALS = 1000
#: States in which a new mission is refused at once (waiting would not help).
BUSY = {"EXEC": "running a task (cancel it first: atemr mission cancel, or the dashboard)",
        "MAPPING": "mapping (save or discard the map on the dashboard first)",
        "SHUTDOWN": "shutting down"}


class _Session:
    """A mission started from the control channel: its `MissionRun` and the answers followers read."""

    def __init__(self, run: MissionRun, owner: int, extras: dict[str, Any]) -> None:
        self.run = run
        self.owner = owner
        self.extras = extras
        self.events: list[dict[str, Any]] = []
        self.finished = False
        self._cond = threading.Condition()
        self._state: str | None = None
        self._phase = run.phase
        self._steps: dict[int, str] = {}
        mission = run.mission
        self.emit({"event": "started", "mission": mission.name, "file": mission.file,
                   "steps": [s.name for s in mission.steps], "timeout_s": run.timeout_s})

    def emit(self, event: dict[str, Any]) -> None:
        event = {"ok": True, "t": self.run.agent.context.now, **event}
        with self._cond:
            self.events.append(event)
            self._cond.notify_all()

    def poll(self) -> None:
        """After an agent tick: advance the run and publish what changed (robot thread)."""
        done = self.run.poll()
        self._publish(self.run.result["steps"] if done else (self.run.agent.task_progress() or {}).get("steps"))
        if done:
            self._end()

    def abandon(self, reason: str) -> None:
        """The robot stops: end with what is known."""
        if not self.finished:
            self.run.abandon(reason)
            self._publish(self.run.result["steps"])
            self._end()

    def _publish(self, steps: list[dict[str, Any]] | None) -> None:
        agent = self.run.agent
        if agent.state != self._state:
            self._state = agent.state
            self.emit({"event": "state", "state": agent.state})
        if self.run.phase != self._phase:
            self._phase = self.run.phase
            self.emit({"event": "phase", "phase": self._phase, "autonomy": agent.gate.level})
        if self.run.phase not in ("running", "cancelling", "done"):
            return
        for step in steps or []:
            if self._steps.get(step["index"], "pending") != step["status"]:
                self._steps[step["index"]] = step["status"]
                self.emit({"event": "step", "step": step})

    def _end(self) -> None:
        self.run.result.update(self.extras)
        self.finished = True
        self.emit({"event": "result", "result": self.run.result})

    def wait(self, seen: int, timeout_s: float) -> list[dict[str, Any]]:
        """The events after the first ``seen`` (waits up to ``timeout_s`` for one; socket threads)."""
        with self._cond:
            self._cond.wait_for(lambda: len(self.events) > seen, timeout_s)
            return self.events[seen:]

    def summary(self) -> dict[str, Any]:
        return {"mission": self.run.mission.name, "phase": self.run.phase, "started_s": self.run.started_s,
                "finished": self.finished, "outcome": self.run.result["outcome"] if self.finished else None}


class RobotControl:
    """The control channel's scheduler component (``control``): serves the socket while the robot runs."""

    name = "control"

    def __init__(self, robot: Robot, agent: Agent, *, localization: LocalizationPipeline | None = None,
                 sim: Simulation | None = None, answer_timeout_s: float = ANSWER_TIMEOUT_S) -> None:
        """``agent`` is the robot's agent, passed as itself so the channel needs no wired parts (a bare agent
        in tests has none). ``localization`` gives ``status`` the robot's pose; ``sim`` says it is simulated
        (world and seed go into every result). Both are the robot's parts; a bare agent has neither."""
        self.robot = robot
        self.agent = agent
        self.localization = localization
        self.sim = sim
        self.answer_timeout_s = answer_timeout_s
        self.server = ControlServer(control_socket_path(robot.config), {
            "status": self._cmd_status, "start": self._cmd_start, "follow": self._cmd_follow,
            "cancel": self._cmd_cancel,
        })
        self.session: _Session | None = None
        self.last: _Session | None = None
        self._actions: queue.SimpleQueue[tuple[Callable[[float], Any], Future[Any]]] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._closed = False
        self._extras = {"world": robot.config.sim.world if sim is not None else None,
                        "seed": robot.config.sim.seed if sim is not None else None}

    # -- scheduler component (robot thread) ----------------------------------------------------------
    def start(self) -> None:
        self.server.start()

    def tick(self, now: float) -> None:
        while True:
            try:
                action, future = self._actions.get_nowait()
            except queue.Empty:
                break
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(action(now))
            except Exception as exc:
                future.set_exception(exc)
        if self.session is not None:
            self.session.poll()
            if self.session.finished:
                self.last, self.session = self.session, None

    def shutdown(self) -> None:
        """End the mission (the robot stops under it), refuse what is queued, close the socket."""
        with self._lock:
            self._closed = True
        while True:
            try:
                _, future = self._actions.get_nowait()
            except queue.Empty:
                break
            future.set_exception(ControlError("the robot is stopping"))
        if self.session is not None:
            self.session.abandon("the robot stopped before the mission ended")
            self.last, self.session = self.session, None
        self.server.stop()

    def _call(self, action: Callable[[float], Any]) -> Any:
        """Run ``action(now)`` on the robot's thread and return its result (socket threads)."""
        future: Future[Any] = Future()
        with self._lock:
            if self._closed:
                raise ControlError("the robot is stopping")
            self._actions.put((action, future))
        try:
            return future.result(self.answer_timeout_s)
        except FutureTimeout:
            future.cancel()
            raise ControlError(f"the robot did not answer within {self.answer_timeout_s:g} s "
                               f"(is its control loop running?)") from None

    # -- commands (socket threads) -------------------------------------------------------------------
    def _cmd_status(self, request: dict[str, Any], conn: ControlConnection) -> None:
        conn.send({"ok": True, "status": self._call(self._status)})

    def _cmd_start(self, request: dict[str, Any], conn: ControlConnection) -> None:
        mission = mission_of(request)
        timeout_s = number_of(request, "timeout_s", 600.0, MAX_TIMEOUT_S)
        follow = request.get("follow", True)
        if not isinstance(follow, bool):
            raise ControlError(f"'follow' must be true or false, got {brief(follow)}")
        session: _Session = self._call(lambda now: self._begin(mission, timeout_s, conn.number))
        if follow:
            self._follow(session, conn, owner=True)
        else:
            conn.send(session.events[0])

    def _cmd_follow(self, request: dict[str, Any], conn: ControlConnection) -> None:
        session = self._call(lambda now: self.session)
        if session is None:
            raise ControlError("no mission started from the control channel is running")
        self._follow(session, conn, owner=False)

    def _cmd_cancel(self, request: dict[str, Any], conn: ControlConnection) -> None:
        reason = request.get("reason", "cancelled by the operator (atemr mission cancel)")
        if not isinstance(reason, str) or not reason.strip() or len(reason) > 200:
            raise ControlError("'reason' must be a non-empty string of at most 200 characters")
        conn.send({"ok": True, **self._call(lambda now: self._cancel(reason))})

    def _follow(self, session: _Session, conn: ControlConnection, *, owner: bool) -> None:
        seen = 0
        while True:
            # Read `stopping` before the events: the robot's shutdown publishes the mission's result before it
            # stops the server, so a follower that sees the server stopping still sends that result.
            leaving = conn.gone() or self.server.stopping
            events = session.wait(seen, 0.0 if leaving else FOLLOW_POLL_S)
            for event in events:
                if not conn.send(event):
                    break
            seen += len(events)
            if events and events[-1]["event"] == "result":
                return
            if leaving:
                if owner and not session.finished:
                    self._queue_cancel(session, "the client that started the mission disconnected")
                return

    def _queue_cancel(self, session: _Session, reason: str) -> None:
        future: Future[Any] = Future()
        with self._lock:
            if not self._closed:
                self._actions.put((lambda now: session.run.cancel(reason), future))

    # -- actions (robot thread) ----------------------------------------------------------------------
    def _begin(self, mission: Mission, timeout_s: float, owner: int) -> _Session:
        if self.session is not None:
            raise ControlError(f"a mission started from the control channel is already running: "
                               f"'{self.session.run.mission.name}' (atemr mission cancel stops it)")
        state = self.agent.state
        busy = BUSY.get(top_level(state))
        if busy is not None:
            raise ControlError(f"the robot is busy: the agent is in {state}, {busy}")
        run = MissionRun(self.agent, mission, timeout_s=timeout_s, origin="control socket")
        self.session = _Session(run, owner, self._extras)
        self.robot.event("mission", f"'{mission.name}' started from the control channel")
        return self.session

    def _cancel(self, reason: str) -> dict[str, Any]:
        if self.session is not None:
            self.session.run.cancel(reason)
            return {"cancelled": self.session.run.mission.name}
        state = self.agent.state
        if top_level(state) != "EXEC":
            raise ControlError(f"nothing to cancel: the agent is in {state}, no task is running")
        task = self.agent.task_progress()
        self.agent.submit("cancel", origin="control socket")
        return {"cancelled": task["mission"] if task else "the current task"}

    def _status(self, now: float) -> dict[str, Any]:
        snapshot = self.agent.snapshot(transitions=10)
        pose: Pose2D | None = None if self.localization is None else self.localization.map_pose()
        return {
            "t": now,
            "simulation": self.sim is not None,
            **{k: snapshot[k] for k in ("state", "mode", "task", "task_progress", "last_task", "error",
                                        "valid_triggers", "transitions")},
            "pose": asdict(pose) if pose is not None else None,
            "localization": None if self.localization is None else self.localization.status.as_dict(),
            "control": self.session.summary() if self.session is not None else None,
            "last_control": self.last.summary() if self.last is not None else None,
        }


def mission_of(request: dict[str, Any]) -> Mission:
    """The mission a ``start`` request carries, validated here (`ControlError`/`ConfigError` if not)."""
    if ("mission" in request) == ("goals" in request):
        raise ControlError("'start' needs either 'mission' {\"text\": YAML, \"file\": NAME} or 'goals' (not both)")
    if "mission" in request:
        document = request["mission"]
        if not isinstance(document, dict) or not isinstance(document.get("text"), str):
            raise ControlError("'mission' must be {\"text\": the mission YAML, \"file\": its name}")
        name = document.get("file", "<mission>")
        if not isinstance(name, str) or not name or len(name) > 4096:
            raise ControlError("'mission.file' must be a non-empty string (the name errors are reported under)")
        return parse_mission(load_yaml(name, text=document["text"]), name)
    goals = request["goals"]
    if not isinstance(goals, list) or not 0 < len(goals) <= MAX_GOALS:
        raise ControlError(f"'goals' must be a list of 1 to {MAX_GOALS} poses {{x_m, y_m, yaw_rad}}")
    poses = []
    for i, goal in enumerate(goals):
        if not isinstance(goal, dict) or set(goal) != {"x_m", "y_m", "yaw_rad"}:
            raise ControlError(f"goals[{i}] must be {{\"x_m\", \"y_m\", \"yaw_rad\"}}, got {brief(goal)}")
        values = [goal["x_m"], goal["y_m"], goal["yaw_rad"]]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            raise ControlError(f"goals[{i}] coordinates must be numbers, got {brief(goal)}")
        poses.append(Pose2D(*(float(v) for v in values)))
    return mission_from_goals(poses)


def number_of(request: dict[str, Any], key: str, default: float, maximum: float) -> float:
    value = request.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or not 0 < value <= maximum:
        raise ControlError(f"'{key}' must be a number of seconds in (0, {maximum:g}], got {brief(value)}")
    return float(value)


__all__ = ["RobotControl", "mission_of"]
