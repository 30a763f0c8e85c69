"""Which routine runs are due: `RoutinePlanner` keeps the calendar time it last looked at and, asked again
with the calendar time now (from the robot's injected clock, never read here), returns every run scheduled
in between, in order.

A run whose time passed more than ``grace_s`` before it was seen is *missed*, not run late: a robot that was
off at 09:00, or whose calendar jumped (a Raspberry Pi without a real-time clock gets the date from the
network after it boots), does not drive off at 11:00 to catch up on the morning; the run is reported as
missed instead. A calendar that goes back (the clock was set back) runs nothing twice.
"""

from __future__ import annotations

from dataclasses import dataclass

from atemr.domain.routines import Routine, RoutineBook

#: How late a run may still start after its time (the planner is asked about once a second).
GRACE_S = 120.0


@dataclass(frozen=True)
class DueRun:
    """One scheduled run of ``routine`` at ``at`` (epoch seconds); ``missed`` when seen too late to start."""

    routine: Routine
    at: float
    missed: bool = False


class RoutinePlanner:
    """See the module docstring. ``now`` is the calendar (epoch seconds) when the planner starts: runs before
    it are not due."""

    def __init__(self, book: RoutineBook, now: float, *, grace_s: float = GRACE_S) -> None:
        self.book = book
        self.grace_s = grace_s
        self.checked = now

    def due(self, now: float) -> list[DueRun]:
        """The runs scheduled after the last call and at or before ``now``, earliest first."""
        if now <= self.checked:  # the same moment, or a calendar set back: what ran does not run again
            return []
        tz = self.book.tz
        runs = [DueRun(r, t, now - t > self.grace_s) for r in self.book.routines if r.enabled
                for t in r.schedule.runs_between(self.checked, now, tz)]
        self.checked = now
        return sorted(runs, key=lambda d: (d.at, d.routine.name))

    def next_run(self, routine: Routine, now: float) -> float | None:
        """When ``routine`` runs next after ``now`` (None when it is disabled)."""
        return routine.schedule.next_run(max(now, self.checked), self.book.tz) if routine.enabled else None


__all__ = ["GRACE_S", "DueRun", "RoutinePlanner"]
