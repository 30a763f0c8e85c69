"""The dashboard's routine commands on the whole simulated robot (issue 27): a routine is checked whole before
it is stored in the data directory's routines file, a refused one stores nothing, and the runner uses the
stored file at its next tick."""

from __future__ import annotations

from atemr.io.routine_store import RoutineStore

from .test_gateway import booted, run  # noqa: F401  (booted is a fixture)


def test_routines_are_added_checked_changed_and_deleted(booted):  # noqa: F811
    robot, gateway = booted
    store = RoutineStore(robot.config.data_dir)
    assert gateway.routines()["routines"] == []
    assert gateway.set_routines_timezone("Europe/Berlin").ok
    morning = {"name": "check-on-resident", "mission": "look-around", "at": "09:00", "days": ["mon", "fri"]}
    assert gateway.save_routine(morning).ok
    refused = {
        "time": gateway.save_routine({**morning, "name": "x", "at": "9h"}),
        "mission": gateway.save_routine({**morning, "name": "x", "mission": "tea"}),
        "twice": gateway.save_routine(morning),
        "zone": gateway.set_routines_timezone("Mars/Olympus"),
        "unknown": gateway.delete_routine("nap"),
    }
    assert not any(r.ok for r in refused.values())
    assert "HH:MM" in refused["time"].reason
    assert "no mission named 'tea'" in refused["mission"].reason and "look-around" in refused["mission"].reason
    assert "exists already" in refused["twice"].reason
    assert "unknown time zone" in refused["zone"].reason
    assert "no routine named 'nap'" in refused["unknown"].reason
    assert [r.name for r in store.load().routines] == ["check-on-resident"]  # nothing of the refusals stored

    assert gateway.save_routine({**morning, "name": "morning", "at": "08:30"}, previous="check-on-resident").ok
    run(robot, 1.5)  # the runner reads the changed file at its next tick
    shown = gateway.routines()
    assert shown["timezone"] == "Europe/Berlin"
    assert [(r["name"], r["schedule"]) for r in shown["routines"]] == [("morning", "at 08:30, mon fri")]
    assert shown["routines"][0]["next"].endswith(("CET", "CEST"))
    assert gateway.delete_routine("morning").ok
    run(robot, 1.5)
    assert gateway.routines()["routines"] == [] and store.load().timezone == "Europe/Berlin"
