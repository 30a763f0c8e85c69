"""The Routines page (issue 27): admins only; it lists each routine's schedule and next run and the last runs
with their outcome; its forms reach the robot as routines of the routines file, and a refusal is shown beside
the form with what was typed kept."""

from __future__ import annotations

import re


def test_a_user_has_no_routines_page(alice):
    answer = alice.get("/routines")
    html = answer.get_data(as_text=True)
    # told what the page is for and where to go, not that the account has no access at all
    assert answer.status_code == 403 and "This page is for administrators" in html and "/control" in html
    assert "no access to the robot yet" not in html
    assert "Routines</a>" not in alice.get("/control").get_data(as_text=True)


def test_a_routine_is_changed_from_its_own_button(admin, gateway, ui):
    """CHANGE puts the routine in the form (name, mission, time, days, enabled); saving replaces it."""
    page = admin.get("/routines").get_data(as_text=True)
    assert 'href="/routines?edit=check-on-resident#routine-form"' in page and "Add a routine" in page
    gateway.routine_data["routines"][0].update({"days": ["mon", "wed"], "enabled": False})
    html = admin.get("/routines?edit=check-on-resident").get_data(as_text=True)
    assert "Change the routine 'check-on-resident'" in html and "SAVE CHANGES" in html
    assert re.search(r'name="previous" id="routine-previous" value="check-on-resident"', html)
    assert re.search(r'id="routine-at" value="09:00"', html)
    assert re.search(r'value="mon"\s+checked', html) and not re.search(r'value="tue"\s+checked', html)
    assert not re.search(r'id="routine-enabled"\s+checked', html)
    gone = admin.get("/routines?edit=nobody")
    assert gone.status_code == 404 and "no routine named &#39;nobody&#39; to change" in gone.get_data(as_text=True)


def test_deleting_a_routine_asks_first(admin):
    html = admin.get("/routines").get_data(as_text=True)
    assert "data-confirm=\"Delete the routine 'check-on-resident'? It will not run again.\"" in html


def test_a_refused_time_zone_is_said_beside_its_own_form_and_leaves_the_routine_form_alone(admin, gateway, ui):
    gateway.refuse["set_routines_timezone"] = "routines time zone 'Berlin': unknown time zone"
    html = ui.post(admin, "/routines/timezone", {"timezone": "Berlin"}).get_data(as_text=True)
    assert 'id="timezone-error"' in html and 'id="routine-error"' not in html
    assert re.search(r'id="routines-timezone" required\s+value="Berlin"', html)  # what was typed, to mend
    # the routine form keeps its defaults: every day and "enabled" ticked (a time-zone error unticked them all)
    assert all(re.search(rf'value="{d}"\s+checked', html) for d in ("mon", "tue", "wed", "thu", "fri", "sat", "sun"))
    assert re.search(r'id="routine-enabled"\s+checked', html)


def test_an_admin_sees_each_routine_its_next_run_and_the_last_runs(admin):
    page = admin.get("/routines")
    assert page.status_code == 200
    html = page.get_data(as_text=True)
    assert "Routines</a>" in html
    assert 'data-routine="check-on-resident"' in html and "2026-06-03 09:00 CEST" in html
    assert "robot in MANUAL" in html and "outcome-skipped" in html


def test_a_routine_from_the_form_reaches_the_robot(admin, gateway, ui):
    form = {"name": "night patrol", "mission": "patrol", "kind": "every", "every_min": "30", "from": "21:00",
            "to": "23:00", "days": ["mon", "tue", "wed", "thu", "fri"], "enabled": "on"}
    answer = ui.post(admin, "/routines/save", form, follow_redirects=True)
    assert answer.status_code == 200 and "Routine night patrol saved." in answer.get_data(as_text=True)
    assert gateway.calls == [("save_routine", ({"name": "night patrol", "mission": "patrol", "every_min": 30,
                                                 "from": "21:00", "to": "23:00",
                                                 "days": ["mon", "tue", "wed", "thu", "fri"]}, None))]
    ui.post(admin, "/routines/save", {"name": "m", "mission": "patrol", "kind": "at", "at": "07:30",
                                      "days": ["mon", "tue", "wed", "thu", "fri", "sat", "sun"],
                                      "previous": "check-on-resident"})
    assert gateway.calls[-1] == ("save_routine", ({"name": "m", "mission": "patrol", "at": "07:30", "enabled": False},
                                                  "check-on-resident"))
    ui.post(admin, "/routines/delete", {"name": "m"})
    ui.post(admin, "/routines/timezone", {"timezone": "Europe/Lisbon"})
    assert gateway.names()[-2:] == ["delete_routine", "set_routines_timezone"]


def test_a_refused_routine_is_shown_beside_the_form_with_what_was_typed(admin, gateway, ui):
    gateway.refuse["save_routine"] = "routine 'x': expected a time of day HH:MM (24-hour), got '25:00'"
    answer = ui.post(admin, "/routines/save", {"name": "x", "mission": "patrol", "kind": "at", "at": "25:00",
                                               "days": ["sat"], "enabled": "on"})
    html = answer.get_data(as_text=True)
    assert answer.status_code == 400 and 'id="routine-error"' in html and "got &#39;25:00&#39;" in html
    assert 'value="x"' in html
    assert re.search(r'value="sat"\s+checked', html) and not re.search(r'value="mon"\s+checked', html)


def test_a_user_cannot_change_routines(alice, gateway, ui):
    answer = ui.post(alice, "/routines/save", {"name": "x", "mission": "patrol", "kind": "at", "at": "09:00"})
    assert answer.status_code == 403 and gateway.calls == []
