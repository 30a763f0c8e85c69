"""Routine schedules and the planner (issue 27): pure calendar arithmetic on epoch seconds, a simulated day,
daylight-saving changes on a given time zone, and every schedule error named."""

from __future__ import annotations

from datetime import datetime
from zoneinfo import ZoneInfo

import pytest

from atemr.domain.routines import Routine, RoutineBook, local_hhmm, local_stamp
from atemr.errors import ConfigError
from atemr.skills.routines import RoutinePlanner

BERLIN = ZoneInfo("Europe/Berlin")


def at(text: str, tz: ZoneInfo = BERLIN) -> float:
    return datetime.fromisoformat(text).replace(tzinfo=tz).timestamp()


def book(*items: dict, timezone: str = "Europe/Berlin") -> RoutineBook:
    return RoutineBook.from_document({"timezone": timezone, "routines": list(items)})


CARE = book(
    {"name": "check-on-resident", "mission": "kitchen-check", "at": "09:00", "days": ["mon", "tue", "wed", "thu",
                                                                                      "fri"]},
    {"name": "evening", "mission": "round-of-the-rooms", "at": "21:00"},
    {"name": "night patrol", "mission": "living-room-patrol", "every_min": 30, "from": "22:00", "to": "23:00"},
)


def test_a_simulated_day_asked_every_minute_gives_each_run_once_at_its_time() -> None:
    planner = RoutinePlanner(CARE, at("2026-06-01 00:00"))  # a Monday
    seen = []
    t = at("2026-06-01 00:00")
    while t < at("2026-06-02 00:00"):
        t += 60.0
        seen += [(d.routine.name, local_hhmm(d.at, BERLIN), d.missed) for d in planner.due(t)]
    night = [("night patrol", t, False) for t in ("22:00", "22:30", "23:00")]
    assert seen == [("check-on-resident", "09:00", False), ("evening", "21:00", False), *night]
    saturday = at("2026-06-06 08:00")
    assert local_stamp(planner.next_run(CARE.routines[0], saturday) or 0, BERLIN) == "2026-06-08 09:00 CEST"


def test_a_run_seen_too_late_is_missed_not_started_and_nothing_runs_twice() -> None:
    planner = RoutinePlanner(CARE, at("2026-06-01 08:00"))
    assert [(d.routine.name, d.missed) for d in planner.due(at("2026-06-01 11:00"))] == [("check-on-resident", True)]
    assert planner.due(at("2026-06-01 08:30")) == []  # the calendar set back: the morning does not run again
    assert planner.due(at("2026-06-01 09:01")) == []
    assert [d.missed for d in planner.due(at("2026-06-01 21:01"))] == [False]  # within the grace: started


@pytest.mark.parametrize(("day", "expected"), [
    ("2026-03-29", ["2026-03-29 09:00 CEST"]),  # spring forward in Berlin: a 23-hour day
    ("2026-10-25", ["2026-10-25 09:00 CET"]),  # fall back: a 25-hour day
])
def test_a_routine_keeps_its_local_time_across_a_daylight_saving_change(day: str, expected: list[str]) -> None:
    daily = book({"name": "morning", "mission": "m", "at": "09:00"})
    start, end = at(f"{day} 00:00"), at(f"{day} 23:59")
    assert [local_stamp(t, BERLIN) for t in daily.routines[0].schedule.runs_between(start, end, BERLIN)] == expected
    before = daily.routines[0].schedule.runs_between(at(f"{day} 00:00") - 86400, at(f"{day} 00:00"), BERLIN)[0]
    hours = (daily.routines[0].schedule.runs_between(start, end, BERLIN)[0] - before) / 3600
    assert hours == (23.0 if day.endswith("03-29") else 25.0)


def test_times_the_change_skips_or_repeats_run_once() -> None:
    night = book({"name": "night", "mission": "m", "every_min": 30, "from": "01:30", "to": "03:30"})
    spring = night.routines[0].schedule.runs_between(at("2026-03-29 00:00"), at("2026-03-29 06:00"), BERLIN)
    # 02:00 and 02:30 do not exist that night: they run when the clocks say 03:00 and 03:30, once each
    assert [local_stamp(t, BERLIN)[11:] for t in spring] == ["01:30 CET", "03:00 CEST", "03:30 CEST"]
    autumn = night.routines[0].schedule.runs_between(at("2026-10-25 00:00"), at("2026-10-25 06:00"), BERLIN)
    assert [local_stamp(t, BERLIN)[11:] for t in autumn] == ["01:30 CEST", "02:00 CEST", "02:30 CEST",
                                                              "03:00 CET", "03:30 CET"]


def test_a_routine_round_trips_through_its_document() -> None:
    again = RoutineBook.from_document(CARE.to_document())
    assert again == CARE
    assert [r.schedule.describe() for r in CARE.routines] == [
        "at 09:00, mon-fri", "daily at 21:00", "daily every 30 min 22:00-23:00"]
    unquoted = book({"name": "x", "mission": "m", "at": 540})  # YAML 1.1 reads 09:00 as 540
    assert unquoted.routines[0].to_json()["at"] == "09:00"


@pytest.mark.parametrize(("item", "where", "words"), [
    ({"name": "x", "mission": "m", "at": "25:00"}, "routines[0].at", "HH:MM"),
    ({"name": "x", "mission": "m"}, "routines[0]", "either 'at'"),
    ({"name": "x", "mission": "m", "at": "09:00", "every_min": 10}, "routines[0]", "not both"),
    ({"name": "x", "mission": "m", "every_min": 2, "from": "09:00", "to": "10:00"}, "routines[0].every_min", "from 5"),
    ({"name": "x", "mission": "m", "every_min": 10, "from": "22:00", "to": "02:00"}, "routines[0].to", "midnight"),
    ({"name": "x", "mission": "m", "every_min": 10, "from": "09:00"}, "routines[0]", "needs 'to'"),
    ({"name": "x", "mission": "m", "at": "09:00", "days": ["monday"]}, "routines[0].days", "mon, tue"),
    ({"name": "x", "mission": "../etc", "at": "09:00"}, "routines[0].mission", "mission file"),
    ({"name": "x", "mission": "m", "at": "09:00", "when": 1}, "routines[0].when", "unknown key"),
    ({"name": "", "mission": "m", "at": "09:00"}, "routines[0].name", "name is 1-64"),
])
def test_schedule_errors_name_the_item_and_key(item: dict, where: str, words: str) -> None:
    with pytest.raises(ConfigError) as info:
        book(item)
    assert info.value.path == where and words in info.value.reason


def test_bad_time_zones_and_duplicates_are_refused() -> None:
    with pytest.raises(ConfigError, match="unknown time zone 'Mars/Olympus'"):
        book(timezone="Mars/Olympus")
    with pytest.raises(ConfigError, match="IANA"):
        book(timezone="../../etc/passwd")
    with pytest.raises(ConfigError, match="two routines are named 'a'"):
        book({"name": "a", "mission": "m", "at": "09:00"}, {"name": "a", "mission": "m", "at": "10:00"})
    with pytest.raises(ConfigError, match="no routine named 'b'"):
        CARE.without("b")
    assert CARE.with_routine(Routine("evening", "m", CARE.routines[0].schedule)).get("evening").mission == "m"
