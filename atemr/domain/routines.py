"""Care routines: a mission with a schedule ("check on the resident at 9:00 on weekdays", "a patrol every 30
minutes from 21:00 to 23:00"), and the calendar arithmetic that says when each one runs.

A `Schedule` is either a time of day (``at: "09:00"``) or a period within a window (``every_min: 30``,
``from: "21:00"``, ``to: "23:00"``), on some weekdays (``days: [mon, tue, ...]``, every day by default).
Times are local to the routines' time zone (`zoneinfo`), so a routine at 09:00 runs at 09:00 on both sides
of a daylight-saving change: the day is 23 or 25 hours long, not the routine shifted. A local time that does
not exist that day (02:30 when the clocks go forward) runs when the clocks say 03:30 (the offset before the
change, Python's ``fold=0``); one that happens twice (02:30 when they go back) runs once, the first time.

Everything here is pure: times are seconds since the epoch, handed in by the caller (the robot's injected
clock), never read here. `RoutineBook.from_document` checks a whole routines file and names the item and
key at fault; `RoutineBook.to_document` writes it back.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from datetime import date, datetime, time, timedelta
from typing import Any
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

from atemr.errors import ConfigError, brief

DAYS = ("mon", "tue", "wed", "thu", "fri", "sat", "sun")
EVERY_DAY: tuple[int, ...] = tuple(range(7))
_HHMM = re.compile(r"^([01]?\d|2[0-3]):([0-5]\d)$")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9 _.-]{0,63}$")
#: Shortest period of a repeating routine (a mission every minute would never let the robot rest).
MIN_EVERY_MIN = 5
MAX_ROUTINES = 100
_KEYS = ("name", "mission", "at", "every_min", "from", "to", "days", "enabled")


def _clock_time(value: Any, where: str) -> time:
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 24 * 60:
        value = f"{value // 60:02d}:{value % 60:02d}"  # YAML reads an unquoted 09:00 as 540 (sexagesimal)
    if not isinstance(value, str) or not _HHMM.match(value.strip()):
        raise ConfigError(f"expected a time of day HH:MM (24-hour), got {brief(value)}", path=where)
    hours, minutes = value.strip().split(":")
    return time(int(hours), int(minutes))


def hhmm(t: time) -> str:
    return f"{t.hour:02d}:{t.minute:02d}"


def zone(name: Any, where: str = "timezone") -> ZoneInfo:
    """The IANA time zone ``name`` (``Europe/Berlin``), else `ConfigError`."""
    if not isinstance(name, str) or not name or ".." in name or name.startswith("/"):
        raise ConfigError(f"expected an IANA time zone such as Europe/Berlin, got {brief(name)}", path=where)
    try:
        return ZoneInfo(name)
    except (ZoneInfoNotFoundError, ValueError):
        raise ConfigError(f"unknown time zone {brief(name)} (an IANA name such as Europe/Berlin)",
                          path=where) from None


@dataclass(frozen=True)
class Schedule:
    """When a routine runs: ``at`` a time of day, or ``every_min`` minutes from ``start`` to ``end``
    (inclusive), on ``days`` (0 is Monday)."""

    at: time | None = None
    every_min: int | None = None
    start: time | None = None
    end: time | None = None
    days: tuple[int, ...] = EVERY_DAY

    def times(self) -> list[time]:
        """The local times of one day this schedule runs at."""
        if self.at is not None:
            return [self.at]
        assert self.every_min is not None and self.start is not None and self.end is not None
        first = self.start.hour * 60 + self.start.minute
        last = self.end.hour * 60 + self.end.minute
        return [time(m // 60, m % 60) for m in range(first, last + 1, self.every_min)]

    def describe(self) -> str:
        """In words, for the page: "daily at 09:00", "every 30 min 21:00-23:00, mon-fri"."""
        when = f"at {hhmm(self.at)}" if self.at is not None else \
            f"every {self.every_min} min {hhmm(self.start or time())}-{hhmm(self.end or time())}"
        if self.days == EVERY_DAY:
            return f"daily {when}"
        if self.days == (0, 1, 2, 3, 4):
            return f"{when}, mon-fri"
        return f"{when}, {' '.join(DAYS[d] for d in self.days)}"

    def runs_between(self, after: float, until: float, tz: ZoneInfo) -> list[float]:
        """The runs (epoch seconds) with ``after < t <= until``, in order."""
        if not (math.isfinite(after) and math.isfinite(until)) or until <= after:
            return []
        first = datetime.fromtimestamp(after, tz).date() - timedelta(days=1)
        last = datetime.fromtimestamp(until, tz).date() + timedelta(days=1)
        out: list[float] = []
        day = first
        while day <= last:
            out += [t for t in self._on(day, tz) if after < t <= until]
            day += timedelta(days=1)
        return sorted(set(out))

    def next_run(self, after: float, tz: ZoneInfo) -> float | None:
        """The first run after ``after`` (None: a schedule without days never runs)."""
        day = datetime.fromtimestamp(after, tz).date()
        for _ in range(9):
            later = [t for t in self._on(day, tz) if t > after]
            if later:
                return min(later)
            day += timedelta(days=1)
        return None

    def _on(self, day: date, tz: ZoneInfo) -> list[float]:
        if day.weekday() not in self.days:
            return []
        return [datetime.combine(day, t, tzinfo=tz).timestamp() for t in self.times()]


@dataclass(frozen=True)
class Routine:
    """A named mission run on a schedule."""

    name: str
    mission: str
    schedule: Schedule
    enabled: bool = True

    def to_json(self) -> dict[str, Any]:
        s = self.schedule
        out: dict[str, Any] = {"name": self.name, "mission": self.mission}
        if s.at is not None:
            out["at"] = hhmm(s.at)
        else:
            out.update({"every_min": s.every_min, "from": hhmm(s.start or time()), "to": hhmm(s.end or time())})
        if s.days != EVERY_DAY:
            out["days"] = [DAYS[d] for d in s.days]
        if not self.enabled:
            out["enabled"] = False
        return out

    @classmethod
    def from_json(cls, item: Any, where: str) -> Routine:  # noqa: PLR0912  each key checked, each its own error
        if not isinstance(item, dict):
            raise ConfigError(f"a routine is a mapping {{name, mission, at | every_min+from+to, days}}, got "
                              f"{brief(item)}", path=where)
        for key in item:
            if key not in _KEYS:
                raise ConfigError(f"unknown key {brief(key)}; a routine has {', '.join(_KEYS)}", path=f"{where}.{key}")
        name = item.get("name")
        if not isinstance(name, str) or not _NAME.match(name):
            raise ConfigError(f"a routine's name is 1-64 letters, digits, spaces, '_', '.', '-', got {brief(name)}",
                              path=f"{where}.name")
        mission = item.get("mission")
        if not isinstance(mission, str) or not re.match(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$", mission):
            raise ConfigError(f"'mission' names a mission file of trees/missions (its stem), got {brief(mission)}",
                              path=f"{where}.mission")
        if ("at" in item) == ("every_min" in item):
            raise ConfigError("a routine runs either 'at' a time of day or 'every_min' minutes (with 'from' and "
                              "'to'), not both and not neither", path=where)
        if "at" in item:
            extra = [k for k in ("from", "to") if k in item]
            if extra:
                raise ConfigError(f"'{extra[0]}' goes with 'every_min', not with 'at'", path=f"{where}.{extra[0]}")
            schedule = Schedule(at=_clock_time(item["at"], f"{where}.at"))
        else:
            every = item["every_min"]
            if isinstance(every, bool) or not isinstance(every, int) or not MIN_EVERY_MIN <= every <= 24 * 60:
                raise ConfigError(f"'every_min' is a whole number of minutes from {MIN_EVERY_MIN} to 1440, got "
                                  f"{brief(every)}", path=f"{where}.every_min")
            for key in ("from", "to"):
                if key not in item:
                    raise ConfigError(f"'every_min' needs '{key}' (HH:MM)", path=where)
            start, end = _clock_time(item["from"], f"{where}.from"), _clock_time(item["to"], f"{where}.to")
            if end <= start:
                raise ConfigError(f"'to' ({hhmm(end)}) must be after 'from' ({hhmm(start)}); a window across "
                                  "midnight is two routines", path=f"{where}.to")
            schedule = Schedule(every_min=every, start=start, end=end)
        days = item.get("days", list(DAYS))
        if not isinstance(days, list) or not days or not all(isinstance(d, str) and d.lower() in DAYS for d in days):
            raise ConfigError(f"'days' is a non-empty list of {', '.join(DAYS)}, got {brief(days)}",
                              path=f"{where}.days")
        schedule = Schedule(schedule.at, schedule.every_min, schedule.start, schedule.end,
                            tuple(sorted({DAYS.index(d.lower()) for d in days})))
        enabled = item.get("enabled", True)
        if not isinstance(enabled, bool):
            raise ConfigError(f"'enabled' is true or false, got {brief(enabled)}", path=f"{where}.enabled")
        return cls(name, mission, schedule, enabled)


@dataclass(frozen=True)
class RoutineBook:
    """Every routine of the robot and the time zone their times are in."""

    timezone: str = "UTC"
    routines: tuple[Routine, ...] = field(default=())

    @property
    def tz(self) -> ZoneInfo:
        return zone(self.timezone)

    def get(self, name: str) -> Routine | None:
        return next((r for r in self.routines if r.name == name), None)

    def with_routine(self, routine: Routine) -> RoutineBook:
        """``routine`` added, or replacing the one of its name (in its place)."""
        if self.get(routine.name) is None:
            if len(self.routines) >= MAX_ROUTINES:
                raise ConfigError(f"at most {MAX_ROUTINES} routines", path="routines")
            return RoutineBook(self.timezone, (*self.routines, routine))
        return RoutineBook(self.timezone, tuple(routine if r.name == routine.name else r for r in self.routines))

    def without(self, name: str) -> RoutineBook:
        if self.get(name) is None:
            raise ConfigError(f"no routine named {brief(name)}; routines: "
                              f"{', '.join(r.name for r in self.routines) or 'none'}", path="routines")
        return RoutineBook(self.timezone, tuple(r for r in self.routines if r.name != name))

    def to_document(self) -> dict[str, Any]:
        return {"timezone": self.timezone, "routines": [r.to_json() for r in self.routines]}

    @classmethod
    def from_document(cls, doc: Any) -> RoutineBook:
        """A loaded routines file (``{timezone, routines: [...]}``); `ConfigError` naming what is wrong."""
        if doc is None:
            return cls()
        if not isinstance(doc, dict) or set(doc) - {"timezone", "routines"}:
            raise ConfigError("a routines file has the keys 'timezone' and 'routines'", path="(top)")
        timezone = doc.get("timezone", "UTC")
        zone(timezone)
        items = doc.get("routines") or []
        if not isinstance(items, list) or len(items) > MAX_ROUTINES:
            raise ConfigError(f"'routines' is a list of at most {MAX_ROUTINES} routines", path="routines")
        routines = [Routine.from_json(item, f"routines[{i}]") for i, item in enumerate(items)]
        names = [r.name for r in routines]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ConfigError(f"two routines are named {twice[0]!r}", path="routines")
        return cls(timezone, tuple(routines))


def local_hhmm(epoch: float, tz: ZoneInfo) -> str:
    """``09:00``: how a person reads the time of a run."""
    return datetime.fromtimestamp(epoch, tz).strftime("%H:%M")


def local_stamp(epoch: float, tz: ZoneInfo) -> str:
    """``2026-03-29 09:00 CEST``: a run's date and time with its zone's abbreviation."""
    return datetime.fromtimestamp(epoch, tz).strftime("%Y-%m-%d %H:%M %Z")


__all__ = ["DAYS", "MIN_EVERY_MIN", "Routine", "RoutineBook", "Schedule", "hhmm", "local_hhmm", "local_stamp",
           "zone"]
