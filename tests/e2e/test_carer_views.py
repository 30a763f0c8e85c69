"""The dashboard as a carer meets it (issue 25), in Debian's chromium at a laptop, a portrait tablet and a phone:
camera, joystick and STOP on one screen, driving by touch, a goal set through GO HERE until "Arrived.", honest
connection state, and alerts in plain words. Screenshots go to test-output/e2e/."""

from __future__ import annotations

import time
from typing import Any

import pytest

from atemr.ui.state import state_problems

pytestmark = pytest.mark.e2e

SIZES = {  # name: (width, height, touch and device scale 2)
    "laptop": (1440, 900, False),
    "tablet": (820, 1180, True),
    "phone": (390, 844, True),
}
#: Smallest tap target, in CSS pixels (WCAG 2.5.5, Apple's and Google's guidance).
MIN_TARGET_PX = 44


def wait_for(page: Any, js: str, timeout: float = 10_000) -> None:
    """Poll ``js`` until true (the page's CSP forbids eval, so no wait_for_function on strings)."""
    deadline = time.monotonic() + timeout / 1000
    while time.monotonic() < deadline:
        if page.evaluate(f"() => {{ try {{ return !!({js}); }} catch (e) {{ return false; }} }}"):
            return
        page.wait_for_timeout(50)
    raise AssertionError(f"still false after {timeout / 1000:.0f} s: {js}")


@pytest.fixture
def sized(browser: Any, request: pytest.FixtureRequest) -> Any:
    """A page at one of `SIZES`, failing on any console error or uncaught exception."""
    width, height, touch = SIZES[request.param]
    context = browser.new_context(viewport={"width": width, "height": height}, has_touch=touch, is_mobile=touch,
                                  device_scale_factor=2 if touch else 1)
    page = context.new_page()
    page.set_default_timeout(10_000)
    problems: list[str] = []
    page.on("console", lambda m: problems.append(f"{m.text} ({m.location.get('url')})") if m.type == "error" else None)
    page.on("pageerror", lambda e: problems.append(f"uncaught: {e}"))
    page.size_name = request.param  # type: ignore[attr-defined]
    yield page
    context.close()
    assert not problems, f"console errors or uncaught exceptions at {request.param}: {problems}"


def inside(page: Any, selector: str) -> dict[str, float]:
    box = page.locator(selector).bounding_box()
    view = page.viewport_size
    assert box is not None, f"{selector} is not shown"
    assert box["x"] >= 0 and box["y"] >= 0, (selector, box)
    assert box["x"] + box["width"] <= view["width"] + 0.5, (selector, box, view)
    assert box["y"] + box["height"] <= view["height"] + 0.5, (selector, box, view)
    return box


def touch_drag(page: Any, points: list[tuple[float, float]], step_ms: int = 60) -> None:
    """A finger on the screen: down at the first point, through the others, up (Chromium's own touch input)."""
    cdp = page.context.new_cdp_session(page)
    first = {"x": points[0][0], "y": points[0][1]}
    cdp.send("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": [first]})
    for x, y in points[1:]:
        page.wait_for_timeout(step_ms)
        cdp.send("Input.dispatchTouchEvent", {"type": "touchMove", "touchPoints": [{"x": x, "y": y}]})
    page.wait_for_timeout(step_ms)
    cdp.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})


def tap(page: Any, selector: str) -> None:
    if SIZES[page.size_name][2]:  # a touch screen
        page.tap(selector)
    else:
        page.click(selector)


@pytest.mark.parametrize("sized", list(SIZES), indirect=True)
def test_drive_by_video_and_send_a_goal_on_every_screen(ready_site, sized, shots, helpers):
    page, robot = sized, ready_site.robot
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE' && ATEMR.map?.image != null")
    assert state_problems(robot.state()) == []
    page.evaluate("window.scrollTo(0, 0)")
    # camera, joystick and STOP on one screen together, with the command feedback beside them
    for selector in (".camera", "#joystick", "#stop", "#command-result"):
        inside(page, selector)
    # every control a finger uses (on the laptop the status bar's indicators and the text buttons are a mouse's)
    mouse_only = "e.classList.contains('ind') || e.classList.contains('link')" if page.size_name == "laptop" \
        else "false"
    small = page.evaluate(f"""[...document.querySelectorAll('button, .tabs a, select')]
        .filter((e) => e.offsetParent !== null && !e.closest('dialog') && !({mouse_only}))
        .map((e) => [e.id || e.textContent.trim(), e.getBoundingClientRect()])
        .filter(([, r]) => r.height < {MIN_TARGET_PX} || r.width < {MIN_TARGET_PX})
        .map(([name, r]) => `${{name}} ${{Math.round(r.width)}}x${{Math.round(r.height)}}`)""")
    assert not small, f"tap targets under {MIN_TARGET_PX} px at {page.size_name}: {small}"
    # the screenshot shows the picture the carer sees, not the black frame before the stream's first image
    wait_for(page, "document.getElementById('camera').naturalWidth >= 640", timeout=20_000)
    page.screenshot(path=str(shots / f"carer-{page.size_name}-control.png"))

    # drive forward with the joystick: by touch on the tablet and the phone, by mouse on the laptop
    pad = page.locator("#joystick").bounding_box()
    cx, cy = pad["x"] + pad["width"] / 2, pad["y"] + pad["height"] / 2
    x0, before = robot.pose.x_m, robot.count("joystick")
    if page.size_name == "laptop":
        page.mouse.move(cx, cy)
        page.mouse.down()
        page.mouse.move(cx, cy - pad["height"] * 0.45, steps=4)
        page.wait_for_timeout(900)
        page.mouse.up()
    else:
        touch_drag(page, [(cx, cy)] + [(cx, cy - pad["height"] * 0.45)] * 15)
    wait_for(page, "ATEMR.state.wheel_speeds.left_radps === 0")
    assert robot.count("joystick") - before >= 5 and robot.pose.x_m > x0 + 0.05

    # GO HERE: tap a free spot on the map, confirm; progress, then "Arrived."
    tap(page, "#go-here")
    assert "Tap where the robot should go" in page.inner_text("#map-hint")
    gx, gy = robot.pose.x_m + 0.8, robot.pose.y_m
    page.locator("#map").scroll_into_view_if_needed()
    sx, sy = page.evaluate(f"[...ATEMR.map.toScreen({gx}, {gy})]")
    box = page.locator("#map").bounding_box()
    ratio = page.evaluate("ATEMR.map.canvas.width") / box["width"]
    px, py = box["x"] + sx / ratio, box["y"] + sy / ratio
    if page.size_name == "laptop":
        page.mouse.click(px, py)
    else:
        touch_drag(page, [(px, py)])
    page.wait_for_selector("#goal-confirm:not([hidden])")
    assert robot.goal is None  # nothing is sent before CONFIRM
    # CONFIRM is in sight where the map was tapped, not above it under the status bar (it was on the phone)
    inside(page, "#goal-confirm")
    assert page.evaluate("""(() => { const r = document.getElementById('goal-go').getBoundingClientRect();
        return document.elementFromPoint(r.x + r.width / 2, r.y + r.height / 2)?.id; })()""") == "goal-go"
    if page.size_name != "laptop":  # fixed at the bottom, where the alerts' toasts come: above them
        assert page.evaluate("+getComputedStyle(document.getElementById('goal-confirm')).zIndex > "
                             "+getComputedStyle(document.getElementById('alerts')).zIndex")
    page.screenshot(path=str(shots / f"carer-{page.size_name}-goal-confirm.png"))
    tap(page, "#goal-go")
    wait_for(page, "document.getElementById('goal-progress').textContent.startsWith('On the way: ')")
    page.screenshot(path=str(shots / f"carer-{page.size_name}-goal.png"))
    wait_for(page, "document.getElementById('goal-progress').textContent === 'Arrived.'", timeout=15_000)
    assert "Goal reached." in page.inner_text("#alerts")
    assert page.evaluate("fetch('/favicon.ico').then((r) => r.status)") == 200


@pytest.mark.parametrize("sized", list(SIZES), indirect=True)
def test_the_other_pages_read_well_on_every_screen(ready_site, sized, shots, helpers):
    """Every page at every size: nothing scrolls sideways, and (the `sized` page's own check) no console error."""
    page = sized
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    view = page.viewport_size["width"]
    for name in ("mapping", "settings", "media", "agent", "auth/register"):
        page.goto(f"{ready_site.url}/{name}")
        page.wait_for_load_state("load")
        page.wait_for_timeout(300)  # the page's scripts run and its first state arrives
        width = page.evaluate("document.scrollingElement.scrollWidth")
        assert width <= view, f"/{name} scrolls sideways at {page.size_name}: {width} px wide"
        page.screenshot(path=str(shots / f"carer-{page.size_name}-{name}.png"), full_page=True)


@pytest.mark.parametrize("sized", ["laptop"], indirect=True)
def test_a_silent_robot_shows_a_stale_banner_and_turns_driving_off_until_it_is_back(ready_site, sized, helpers):
    page = sized
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE' && ATEMR.live")
    # opening the page (the socket still connecting, no state yet) is not the robot going offline
    assert page.is_hidden("#connection") and "offline" not in page.inner_text("#alert-items")
    ready_site.pause()  # the robot process ends; the dashboard stays up
    stopped = time.monotonic()
    page.wait_for_selector("#connection.stale:not([hidden])", timeout=2_000)
    assert time.monotonic() - stopped < 2.0
    wait_for(page, "document.getElementById('connection').textContent.includes('last state came')")
    assert "driving is off" in page.inner_text("#connection")
    assert page.is_disabled("#go-here") and page.is_disabled("#mode-toggle")
    assert page.get_attribute("#joystick", "aria-disabled") == "true"
    assert page.evaluate("document.body.classList.contains('stale')")
    before = ready_site.robot.count("joystick")
    page.focus("#joystick")
    page.keyboard.down("w")
    page.wait_for_timeout(400)
    page.keyboard.up("w")
    assert ready_site.robot.count("joystick") - before <= 1  # at most the stop, never a drive command
    # the alert waits a second more than the banner (a slow moment is not "offline")
    wait_for(page, "document.getElementById('alerts').textContent.includes('The robot is offline')")
    ready_site.resume()  # a robot comes up again
    page.wait_for_selector("#connection.back", timeout=3_000)
    assert "Connected again" in page.inner_text("#connection")
    assert not page.is_disabled("#go-here") and not page.is_disabled("#mode-toggle")
    assert "The robot is offline" not in page.inner_text("#alerts")


ALERTS = [  # what the robot does → what the carer reads
    ("stop_cause", "floor_sensors", "Stopped: the floor sensors that watch for stairs have gone quiet"),
    ("stop_cause", "obstacle", "Stopped: something is too close. Drive away from it"),
    ("stop_cause", "cliff", "Stopped: a drop (stairs, a step) is under the robot's edge"),
    ("stop_cause", "heartbeat", "Stopped: the robot's two computers lost contact"),
    ("stop_cause", "motor", "Stopped: a motor reports a fault"),
    ("stop_cause", "bus", "Stopped: the motors' connection (CAN bus) failed"),
    ("event", {"kind": "localization lost", "text": "scan agrees with the map for 31%"},
     "The robot is no longer sure where it is"),
    ("event", {"kind": "localization relocalized", "text": "back"}, "The robot knows where it is again."),
    ("event", {"kind": "localization ambiguous", "text": "global localization: 2 places agree"},
     "Places on the map look alike to the robot"),
    ("event", {"kind": "localization ambiguous", "text": "global localization: 2 places agree; turning in place to "
               "tell them apart"}, "It is turning in place to look around"),  # after FIND POSITION
    ("event", {"kind": "localization map_changed", "text": "map flat selected: not localized until a pose is set"},
     "Another map is in use: the robot does not know where it is on it."),
    ("event", {"kind": "goal", "text": "Goal failed: no path to the goal."}, "Goal failed: no path to the goal."),
    ("event", {"kind": "mission", "text": "Mission 'patrol' finished."}, "Mission 'patrol' finished."),
    ("event", {"kind": "unconfirmed", "text": "The robot did not drive to a goal: nobody confirmed it in time. It "
               "stays where it is."}, "The robot did not drive to a goal: nobody confirmed it in time."),
]


@pytest.mark.parametrize("sized", ["laptop"], indirect=True)
def test_each_alert_is_said_in_plain_words(ready_site, sized, helpers):
    page, robot = sized, ready_site.robot
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE' && ATEMR.live")
    for what, value, text in ALERTS:
        with robot.lock:
            if what == "stop_cause":
                robot.stop_cause = value
            else:
                robot.events.append({"t": robot.clock.now(), **value, "unix_s": time.time()})
        wait_for(page, f"document.getElementById('alert-items').textContent.includes({text!r})")
        if what == "stop_cause":
            wait_for(page, f"document.getElementById('emergency').dataset.cause === {value!r}")
            assert page.inner_text("#emergency").startswith("Stopped: ") and "_" not in page.inner_text("#emergency")
            with robot.lock:
                robot.stop_cause = None
            wait_for(page, "document.getElementById('alert-items').textContent.includes('The robot may move again.')")
            page.evaluate("document.getElementById('alert-items').innerHTML = ''")
    # the localization line while FIND POSITION's ambiguous answer turns the robot, then once it no longer does
    ambiguous = {"confidence": 0.49, "limit": 0.7, "localized": False, "state": "ambiguous", "looking_around": True,
                 "candidates": [{"x_m": 1.0, "y_m": 1.0, "yaw_rad": 0.0, "agreement": 0.99},
                                {"x_m": 4.0, "y_m": 2.0, "yaw_rad": 3.1, "agreement": 0.99}]}
    for looking, words in ((True, "turning in place to tell them apart"), (False, "drive a little to tell them apart")):
        with robot.lock:
            robot.localization = {**ambiguous, "looking_around": looking}
        wait_for(page, f"document.getElementById('localization-detail').textContent.includes({words!r})")
    with robot.lock:
        robot.localization = None
    # a refusal of the carer's own command, in the words the robot gave
    page.evaluate("ATEMR.command('goal', {x_m: 1, y_m: 1, yaw_rad: 0})")
    wait_for(page, "document.getElementById('alert-items').textContent.includes('Go here: switch to AUTO first')")
    tap(page, "#alerts-open")
    assert page.is_visible("#alert-list") and page.locator("#alert-items li").count() >= 3
    assert "IDLE." not in page.inner_text("#alert-items")  # the technical names stay on the Agent page
