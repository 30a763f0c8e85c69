"""Places and routines in Debian's chromium against the whole simulated robot (issue 27): a place added by
tapping the map (a drag gives its heading) is stored with the map, and the "Go to" list sends the robot
there; a routine created on the Routines page is stored in the data directory and listed with its next run."""

from __future__ import annotations

import math
import re

import pytest

from atemr.io.map_store import MapStore
from atemr.io.routine_store import RoutineStore

from .test_dashboard import screen_point, wait_for

pytestmark = pytest.mark.e2e


def test_add_a_place_by_tapping_the_map_and_send_the_robot_there(robot_site, page, shots, helpers):
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE' && ATEMR.map?.image != null")
    wait_for(page, "document.querySelectorAll('#place-list li').length === 6")  # the studio's rooms and home
    names = page.eval_on_selector_all("#place-list li", "els => els.map(e => e.dataset.place)")
    assert names == ["home", "living room", "kitchen", "bedroom", "bathroom", "balcony door"]
    wait_for(page, "Object.values(ATEMR.state.level2).every((ok) => ok)")  # AUTO needs every level-1 OK

    start = robot_site.sim.pose
    px, py = start.x_m + 1.0, start.y_m + 0.6  # free floor of the living room, beside the start
    page.click("#place-add")
    page.locator("#map").scroll_into_view_if_needed()  # the panel may be below the map on this screen
    x, y = screen_point(page, px, py)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x, y - 40, steps=4)  # dragged up the screen: facing +y (north)
    page.mouse.up()
    assert page.is_visible("#place-form")
    page.fill("#place-name", "Mum's armchair")
    page.click("#place-save")
    wait_for(page, "document.querySelector('#place-list li[data-place=\"Mum\\'s armchair\"]') !== null")
    stored = MapStore(robot_site.data_dir).places("studio")["mum's armchair"]
    assert math.hypot(stored.pose.x_m - px, stored.pose.y_m - py) < 0.1 and abs(stored.pose.yaw_rad - math.pi / 2) < 0.2
    page.screenshot(path=str(shots / "places-added.png"), full_page=True)

    # a second place with the same name is refused with the reason, and nothing changes
    page.click("#place-add")
    page.locator("#map").scroll_into_view_if_needed()
    x, y = screen_point(page, px - 0.5, py)
    page.mouse.click(x, y)
    page.fill("#place-name", "MUM'S ARMCHAIR")
    page.click("#place-save")
    wait_for(page, "document.getElementById('place-status').textContent.includes('exists already')")
    page.click("#place-cancel")
    assert len(MapStore(robot_site.data_dir).places("studio")) == 7

    # "Go to": the robot switches to AUTO and drives to the place by itself
    page.click("#place-list li[data-place=\"Mum's armchair\"] .place-go")
    wait_for(page, "document.getElementById('mode-toggle').textContent === 'AUTO'")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'EXEC'")
    goal = page.evaluate("ATEMR.state.goal")
    assert abs(goal["x_m"] - stored.pose.x_m) < 0.01 and abs(goal["y_m"] - stored.pose.y_m) < 0.01
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'", timeout=30000)
    truth = robot_site.sim.pose
    assert math.hypot(truth.x_m - px, truth.y_m - py) < 0.3, truth
    page.screenshot(path=str(shots / "places-arrived.png"), full_page=True)

    # renamed and deleted from the list
    page.click("#place-list li[data-place=\"Mum's armchair\"] .place-rename")
    page.fill("#place-name", "armchair")
    page.click("#place-save")
    wait_for(page, "document.querySelector('#place-list li[data-place=\"armchair\"]') !== null")
    page.click("#place-list li[data-place=\"armchair\"] .place-delete")
    page.click("#place-list li[data-place=\"armchair\"] .place-delete")  # the second tap confirms
    wait_for(page, "document.querySelectorAll('#place-list li').length === 6")
    assert "armchair" not in MapStore(robot_site.data_dir).places("studio")


def test_create_a_routine_on_the_routines_page(robot_site, page, shots, helpers):
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))  # logged in: the Control page, with its status bar
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    page.click("nav.tabs a:has-text('Routines')")
    page.wait_for_url(re.compile(r"/routines$"))
    assert "No routines yet." in page.inner_text("#routine-list")
    page.fill("#routines-timezone", "Europe/Berlin")
    page.click("#timezone-form button[type=submit]")
    page.wait_for_selector("p.flash:has-text('Routines time zone Europe/Berlin.')")  # the page came back
    page.fill("#routine-name", "check-on-resident")
    page.select_option("#routine-mission", "round-of-the-rooms")
    page.fill("#routine-at", "09:00")
    page.uncheck("#routine-days input[value=sat]")
    page.uncheck("#routine-days input[value=sun]")
    page.click("#routine-save")
    wait_for(page, "document.querySelector('#routine-list tr[data-routine=\"check-on-resident\"]') !== null")
    row = page.inner_text("#routine-list tr[data-routine=\"check-on-resident\"]")
    assert "round-of-the-rooms" in row and "at 09:00, mon-fri" in row and re.search(r"\d{4}-\d\d-\d\d 09:00 CES?T", row)
    book = RoutineStore(robot_site.data_dir).load()
    assert book.timezone == "Europe/Berlin" and book.routines[0].to_json() == {
        "name": "check-on-resident", "mission": "round-of-the-rooms", "at": "09:00",
        "days": ["mon", "tue", "wed", "thu", "fri"]}
    # a mistake is refused beside the form, what was typed kept, nothing stored
    page.fill("#routine-name", "night patrol")
    page.check("#routine-kind-every")
    page.fill("#routine-every", "30")
    page.fill("#routine-from", "23:00")
    page.fill("#routine-to", "01:00")
    page.click("#routine-save")
    assert "across midnight" in page.inner_text("#routine-error")
    assert page.input_value("#routine-name") == "night patrol"
    assert len(RoutineStore(robot_site.data_dir).load().routines) == 1
    # CHANGE puts the routine in the form; saving replaces it (no second routine, no name to retype)
    page.goto(f"{robot_site.url}/routines")
    page.click("#routine-list tr[data-routine=\"check-on-resident\"] a.routine-change")
    assert page.inner_text("#routine-form-title") == "Change the routine 'check-on-resident'"
    assert page.input_value("#routine-name") == "check-on-resident" and page.input_value("#routine-at") == "09:00"
    page.fill("#routine-at", "10:30")
    page.click("#routine-save")
    page.wait_for_selector("p.flash:has-text('Routine check-on-resident saved.')")
    assert [r.to_json()["at"] for r in RoutineStore(robot_site.data_dir).load().routines] == ["10:30"]
    # the open page follows the robot: a routine added elsewhere (the robot's file, another carer) appears in the
    # list without a reload, and the form keeps what is being typed
    page.fill("#routine-name", "half typed")
    assert robot_site.gateway.save_routine({"name": "evening", "mission": "look-around", "at": "20:00"}).ok
    wait_for(page, "document.querySelector('#routine-list tr[data-routine=\"evening\"]') !== null")
    assert page.input_value("#routine-name") == "half typed"
    page.screenshot(path=str(shots / "routines.png"), full_page=True)
    page.set_viewport_size({"width": 390, "height": 844})  # a carer's phone: nothing scrolls sideways
    page.goto(f"{robot_site.url}/routines")
    page.screenshot(path=str(shots / "routines-phone.png"), full_page=True)
    wide = page.evaluate("""() => [...document.querySelectorAll('main *')].filter((e) =>
        e.getBoundingClientRect().right > 391).map((e) => `${e.tagName}#${e.id}.${e.className}`).slice(0, 8)""")
    assert page.evaluate("document.scrollingElement.scrollWidth") <= 390, wide
