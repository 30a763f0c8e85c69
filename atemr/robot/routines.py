"""Routines on the robot: `RoutineRunner` starts each scheduled mission when its time comes, if the robot may.

A routine starts only when the robot is in AUTO and idle (``IDLE.AUTO``), localized, charged above the
battery's return limit, its autonomy level lets
the agent start a mission by itself (the ``start_mission`` transition's ``autonomy``), and the mission file is
valid with every place it names on the active map. Otherwise the run is *skipped* and says why ("09:00
check-on-resident skipped: robot in MANUAL"). A run is a robot event (kind ``routine``), so it is in the
recording (MCAP), the dashboard's events and its alerts; and a line of ``routines-history.jsonl`` with its
outcome (skipped, missed, reached, failed, cancelled, refused), so the Routines page lists the last runs after
a restart too.

The calendar (`Calendar`) is the robot's injected clock read as a date: the wall clock on the robot, and in
simulation ``sim.start_time`` plus the simulated seconds, so a simulated day is repeatable. The routines file
is re-read when it changes (a refused file keeps the routines in force, and says why). The scheduling itself
is `atemr.skills.routines.RoutinePlanner`, pure.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import Any

from atemr.clock import Clock
from atemr.domain.places import Places
from atemr.domain.routines import Routine, RoutineBook, local_hhmm, local_stamp
from atemr.errors import ConfigError, brief
from atemr.fsm.agent import Agent
from atemr.fsm.autonomy import rank
from atemr.io.routine_store import HISTORY_KEPT, RoutineStore
from atemr.skills.routines import DueRun, RoutinePlanner
from atemr.trees.missions import Mission, load_mission

#: How often the runner looks at the calendar.
RATE_HZ = 1.0


def parse_start_time(text: str) -> float | None:
    """``sim.start_time`` (ISO 8601 with its offset) as epoch seconds; None when empty; `ConfigError` else."""
    if not text:
        return None
    try:
        moment = datetime.fromisoformat(text.strip())
    except ValueError:
        raise ConfigError(f"expected an ISO 8601 date and time such as 2026-03-29T08:55+02:00, got {brief(text)}",
                          path="sim.start_time") from None
    if moment.tzinfo is None:
        raise ConfigError(f"give the offset of {brief(text)} (e.g. +02:00 or Z): a time without one is ambiguous",
                          path="sim.start_time")
    return moment.timestamp()


class Calendar:
    """The date and time (epoch seconds) the routines go by: the wall clock (``start`` None), or ``start`` plus the
    robot clock's seconds since the calendar was made (a simulation). `set` is the clock being set (the network
    time arriving on a robot without a real-time clock; a test passing the hours in which nothing happens)."""

    def __init__(self, clock: Clock, start: float | None = None) -> None:
        self.clock = clock
        self._offset = None if start is None else start - clock.now()

    def now(self) -> float:
        return time.time() if self._offset is None else self._offset + self.clock.now()

    def set(self, epoch: float) -> None:
        """The calendar says ``epoch`` now (and goes on from there with the robot's clock)."""
        self._offset = epoch - self.clock.now()


class RoutineRunner:
    """The scheduler component that runs the routines (see the module docstring)."""

    name = "routines"

    def __init__(self, store: RoutineStore, agent: Agent, missions_dir: Path, *, calendar: Calendar,
                 places: Callable[[], Places], localized: Callable[[], bool | None],
                 event: Callable[[str, str], None], battery: Callable[[], str | None] = lambda: None) -> None:
        self.store = store
        self.agent = agent
        self.missions_dir = missions_dir
        self.calendar = calendar
        self.places = places
        self.localized = localized
        self.event = event
        #: Why the battery forbids a new task now (None: it does not).
        self.battery = battery
        self.error: str | None = None
        #: Held while the routines in force change or are used (the dashboard's thread reloads after a save).
        self._lock = threading.RLock()
        self._stamp = store.stamp()
        self.book = self._load()
        self.planner = RoutinePlanner(self.book, calendar.now())
        self.history: deque[dict[str, Any]] = deque(store.history(), maxlen=HISTORY_KEPT)
        #: The run started and not finished yet: its record, the agent command's id and the last report before it.
        self.running: dict[str, Any] | None = None
        self._command: int | None = None
        self._before: object = None
        self._mission_name: str | None = None

    # -- the routines file -------------------------------------------------------------------------------
    def _load(self) -> RoutineBook:
        try:
            book = self.store.load()
        except ConfigError as exc:
            self.error = str(exc)
            self.event("routine", f"routines file refused, the routines in force stay: {exc}")
            return getattr(self, "book", RoutineBook())
        self.error = None
        return book

    def reload(self) -> None:
        """Re-read the file (after the page saved it, or when it changed on disk); any thread."""
        with self._lock:
            self._stamp = self.store.stamp()
            self.book = self._load()
            self.planner.book = self.book

    # -- each tick ------------------------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        if self.store.stamp() != self._stamp:
            self.reload()
        with self._lock:
            self._follow(now)
            for due in self.planner.due(self.calendar.now()):
                self._take(due, now)

    def _record(self, due: DueRun, outcome: str, reason: str | None, now: float) -> dict[str, Any]:
        tz = self.book.tz
        return {"routine": due.routine.name, "mission": due.routine.mission, "scheduled": due.at,
                "time": local_hhmm(due.at, tz), "stamp": local_stamp(due.at, tz), "outcome": outcome,
                "reason": reason, "robot_s": round(now, 3)}

    def _finish(self, record: dict[str, Any], text: str) -> None:
        self.history.append(record)
        self.store.append_run(record)
        self.event("routine", text)

    def _take(self, due: DueRun, now: float) -> None:
        label = f"{local_hhmm(due.at, self.book.tz)} {due.routine.name}"
        if due.missed:
            seen = local_hhmm(self.calendar.now(), self.book.tz)
            why = f"not started on time (seen at {seen}: the robot was off or its clock was set)"
            self._finish(self._record(due, "missed", why, now), f"{label} missed: {why}")
            return
        mission_or_why = self._startable(due.routine)
        if isinstance(mission_or_why, str):
            self._finish(self._record(due, "skipped", mission_or_why, now), f"{label} skipped: {mission_or_why}")
            return
        self._before = self.agent.task_reports[-1] if self.agent.task_reports else None
        self._mission_name = mission_or_why.name
        self._command = self.agent.submit("start_mission", origin=f"routine {due.routine.name}", mission=mission_or_why)
        self.running = self._record(due, "running", None, now)
        self.event("routine", f"{label} started: mission {due.routine.mission}")

    def _startable(self, routine: Routine) -> Mission | str:
        """The routine's mission when the robot may start it now, else why not."""
        if self.running is not None:
            return f"robot busy with routine {self.running['routine']}"
        state = self.agent.state
        if state == "IDLE.MANUAL":
            return "robot in MANUAL"
        if state != "IDLE.AUTO":
            return f"robot busy ({state})" if state.split(".")[0] in ("EXEC", "MAPPING") else f"robot in {state}"
        if self.localized() is False:
            return "robot not localized"
        low = self.battery()
        if low is not None:
            return low
        needed = next((t.autonomy for t in self.agent.spec.transitions
                       if t.trigger == "start_mission" and ("IDLE.AUTO" in t.sources or "*" in t.sources)), None)
        if needed is not None and rank(needed) > rank(self.agent.gate.level):
            return f"autonomy level {self.agent.gate.level}: starting a mission needs level {needed} or the operator"
        path = self.missions_dir / f"{routine.mission}.yaml"
        if not path.is_file():
            return f"no mission named {routine.mission}"
        try:
            mission = load_mission(path)
            mission.check_places(self.places(), "the active map")
        except ConfigError as exc:
            return f"mission {routine.mission} is not valid: {exc.reason}"
        return mission

    def _follow(self, now: float) -> None:
        """The running routine's mission: refused by the agent, or finished (its report's outcome)."""
        run = self.running
        if run is None or self._command is None:
            return
        result = self.agent.result(self._command)
        label = f"{run['time']} {run['routine']}"
        if result is not None and not result.accepted and result.decision != "requested":
            self.running = None
            self._finish({**run, "outcome": "refused", "reason": result.reason, "robot_s": round(now, 3)},
                         f"{label} refused: {result.reason}")
            return
        reports = self.agent.task_reports
        report = reports[-1] if reports else None
        if report is None or report is self._before or report.get("mission") != self._mission_name:
            return
        self.running = None
        outcome = str(report.get("outcome"))
        reason = report.get("reason")
        self._finish({**run, "outcome": outcome, "reason": reason, "robot_s": round(now, 3)},
                     f"{label} {outcome}" + (f": {reason}" if reason else ""))

    # -- what the Routines page shows -----------------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        """Each routine with its schedule in words and its next run, the last runs (newest first), the time zone,
        the calendar now, the file's error if it was refused."""
        with self._lock:
            return self._snapshot()

    def _snapshot(self) -> dict[str, Any]:
        now = self.calendar.now()
        tz = self.book.tz
        routines = []
        for r in self.book.routines:
            nxt = self.planner.next_run(r, now)
            routines.append({**r.to_json(), "schedule": r.schedule.describe(), "enabled": r.enabled,
                             "next": None if nxt is None else local_stamp(nxt, tz)})
        return {"timezone": self.book.timezone, "now": local_stamp(now, tz), "routines": routines,
                "running": self.running, "history": list(reversed(self.history))[:50], "error": self.error}


__all__ = ["RATE_HZ", "Calendar", "RoutineRunner", "parse_start_time"]
