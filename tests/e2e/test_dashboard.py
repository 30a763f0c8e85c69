"""The dashboard in Debian's chromium: first start, login, users, settings, driving, AUTO goal, mapping,
media, and a screenshot of every page (test-output/e2e/)."""

from __future__ import annotations

import io
import math
import os
import re
import time
from pathlib import Path
from typing import Any

import av
import pytest
from PIL import Image

from atemr.ui.sockets import sessions_of
from atemr.ui.state import state_problems

pytestmark = pytest.mark.e2e


def wait_for(page, js: str, timeout: float = 8000) -> None:
    """Poll ``js`` until true. (``page.wait_for_function`` evaluates strings with eval, which the
    dashboard's Content-Security-Policy forbids; ``page.evaluate`` goes through the DevTools protocol.)"""
    step_ms = 50
    for _ in range(int(timeout / step_ms)):
        if page.evaluate(js):
            return
        page.wait_for_timeout(step_ms)
    raise AssertionError(f"still false after {timeout / 1000:.0f} s: {js}")


def watch_texts(page, element_id: str) -> None:
    """Record every text the element ``element_id`` shows from now on, even one replaced before a poll could see
    it (`watched_texts` reads them)."""
    page.evaluate(f"""(() => {{
        const el = document.getElementById('{element_id}');
        const seen = ((window.watched ||= {{}})['{element_id}'] = []);
        new MutationObserver(() => seen.push(el.textContent)).observe(el, {{childList: true}});
    }})()""")


def watched_texts(page, element_id: str) -> list[str]:
    return page.evaluate(f"window.watched['{element_id}']")


def test_first_start_sets_the_admin_password_then_login_remembers_the_user(site, page, shots, helpers):
    page.goto(site.url)
    assert page.url.endswith("/auth/first-start")
    assert not page.is_visible("#alerts-open")  # no socket, no alerts: the button showed here, dead
    page.screenshot(path=str(shots / "first-start.png"), full_page=True)
    page.fill("#admin-password", helpers.ADMIN_PW)
    page.fill("#admin-confirm", helpers.ADMIN_PW)
    page.click("#set-admin-password")
    page.wait_for_url(re.compile(r"/control$"))
    assert page.inner_text("#username") == "admin"
    assert not site.users.needs_root_password()
    page.click("#logout")
    page.wait_for_url(re.compile(r"/auth/login"))
    assert not page.is_visible("#alerts-open")
    page.screenshot(path=str(shots / "login.png"), full_page=True)
    page.fill("#username-input", "admin")
    page.fill("#password-input", "wrong-password")
    page.click("#login-button")
    assert "Wrong username or password" in page.inner_text("main")
    page.fill("#password-input", helpers.ADMIN_PW)
    page.check("#remember")
    page.click("#login-button")
    page.wait_for_url(re.compile(r"/control$"))
    page.click("#logout")
    page.wait_for_url(re.compile(r"/auth/login"))
    assert page.input_value("#username-input") == "admin"


def screen_point(page, x_m: float, y_m: float) -> tuple[float, float]:
    """Where the map-frame point (x, y) is on the page (through the map view's own transform)."""
    sx, sy, cw, ch = page.evaluate(f"[...ATEMR.map.toScreen({x_m}, {y_m}), ATEMR.map.canvas.width, "
                                   "ATEMR.map.canvas.height]")
    box = page.locator("#map").bounding_box()
    return box["x"] + sx * box["width"] / cw, box["y"] + sy * box["height"] / ch


#: The Control page shows the MJPEG stream and its first frame (at least 640 wide) has arrived.
CAMERA_STREAMING = ("document.getElementById('camera').src.includes('/api/camera.mjpeg') "
                    "&& document.getElementById('camera').naturalWidth >= 640")
#: How long to wait for the first frame (a wait, not a speed check): the robot renders it in real time beside
#: the browser, and a loaded 2-core machine took longer than the default 8 s.
CAMERA_WAIT_MS = 20_000


def wait_for_camera(page) -> None:
    """Wait for `CAMERA_STREAMING`; a failure says which transport the page uses and what the image shows (the
    page falls back to Socket.IO frames when the MJPEG image errors, and then the stream never comes)."""
    try:
        wait_for(page, CAMERA_STREAMING, timeout=CAMERA_WAIT_MS)
    except AssertionError as exc:
        seen = page.evaluate("(() => { const c = document.getElementById('camera'); "
                             "return `transport=${c.dataset.transport} "
                             "src=${(c.getAttribute('src') || '').slice(0, 40)} "
                             "width=${c.naturalWidth} hidden=${c.hidden}`; })()")
        raise AssertionError(f"{exc} ({seen})") from None


def test_control_page_shows_the_robot_and_the_keyboard_drives_it(robot_site, page, shots, helpers):
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'")
    wait_for_camera(page)
    wait_for(page, "ATEMR.map?.image != null && ATEMR.state.pose !== null && ATEMR.state.scan.length > 100")
    assert page.evaluate("ATEMR.state.active_map") == "studio"
    assert page.evaluate("ATEMR.state.level2.lidar && ATEMR.state.level2.webserver && ATEMR.state.level1.heartbeat")
    # the status bar in a carer's words, the engineer's names on hover
    bar = page.evaluate("""() => Object.fromEntries(["sock", "agent-state", "emergency", "autonomy-level", "battery"]
        .map((id) => [id, [document.getElementById(id).textContent, document.getElementById(id).title]]))""")
    assert bar["sock"][0] == "Connected" and "WebSocket ONLINE" in bar["sock"][1], bar
    assert bar["agent-state"][0] == "Ready" and "agent state IDLE" in bar["agent-state"][1], bar
    assert bar["emergency"][0] == "No emergency" and bar["autonomy-level"][0] == "Autonomy full", bar
    assert "never waits for you" in bar["autonomy-level"][1], bar
    assert re.fullmatch(r"Battery \d+ %", bar["battery"][0]) and " V)" in bar["battery"][1], bar
    assert page.inner_text("#state-agent") == "Ready" and "IDLE" in page.get_attribute("#state-agent", "title")
    assert page.inner_text("#level1 [data-name=auto]") == "MODE MANUAL"
    assert "knows where it is" in page.get_attribute("#level1 [data-name=localization]", "title")
    # each event at the time of day it happened (this page's clock), its robot time on hover
    first = page.locator("#events li").first
    assert re.match(r"\d\d:\d\d:\d\d", first.inner_text()), first.inner_text()
    recent = [time.localtime(time.time() - ago) for ago in range(0, 181, 30)]  # 24 h or 12 h, as the locale says
    at = first.inner_text()
    assert at[:5] in {time.strftime(f, t) for t in recent for f in ("%H:%M", "%I:%M")}, at
    assert "robot time" in first.get_attribute("title")
    x0 = page.evaluate("ATEMR.state.pose.x_m")
    truth0 = robot_site.sim.pose
    page.focus("#joystick")
    page.keyboard.down("ArrowUp")
    wait_for(page, f"ATEMR.state.pose.x_m > {x0} + 0.2 && ATEMR.map.state.pose.x_m > {x0} + 0.2")
    page.keyboard.up("ArrowUp")
    wait_for(page, "Math.abs(ATEMR.state.wheel_speeds.left_radps) < 0.05")  # released: the robot stops
    assert robot_site.sim.pose.x_m > truth0.x_m + 0.2  # the simulated robot really moved
    yaw0 = page.evaluate("ATEMR.state.pose.yaw_rad")
    page.keyboard.down("a")
    wait_for(page, f"ATEMR.state.pose.yaw_rad > {yaw0} + 0.2")
    page.keyboard.up("a")
    wait_for(page, "ATEMR.state.system !== null && ATEMR.state.system.cpu_percent >= 0")
    page.screenshot(path=str(shots / "control.png"), full_page=True)


def test_the_joystick_pad_resends_while_held_and_stops_on_release(ready_site, page, shots, helpers):
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    wait_for(page, "document.querySelectorAll('#level1 .led.ok').length === 4")
    # the keyboard resends while a key is held and sends an explicit stop on release
    page.focus("#joystick")
    page.keyboard.down("ArrowUp")
    wait_for(page, "ATEMR.state.wheel_speeds.left_radps > 0")
    page.wait_for_timeout(400)
    page.keyboard.up("ArrowUp")
    forward = [c for c in ready_site.robot.calls if c[0] == "joystick" and c[1][0].linear_mps > 0]
    assert len(forward) >= 3  # resent while held
    wait_for(page, "ATEMR.state.wheel_speeds.left_radps === 0")
    last = [c for c in ready_site.robot.calls if c[0] == "joystick"][-1]
    assert last[1][0].is_zero  # released: an explicit stop
    wait_for(page, "document.querySelectorAll('#sysgraph').length === 1 && ATEMR.state.system.cpu_percent === 20")

    # the same with the mouse (pointer events also carry touch): drag the knob forward and hold
    before = ready_site.robot.count("joystick")
    pad = page.locator("#joystick").bounding_box()
    cx, cy = pad["x"] + pad["width"] / 2, pad["y"] + pad["height"] / 2
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx, cy - pad["height"] / 2, steps=3)
    wait_for(page, "ATEMR.state.wheel_speeds.left_radps > 0")
    page.wait_for_timeout(700)  # held longer than the robot's 0.5 s timeout: the page keeps resending
    x1 = ready_site.robot.pose.x_m
    page.wait_for_timeout(300)
    assert ready_site.robot.pose.x_m > x1 + 0.05
    page.mouse.up()
    wait_for(page, "ATEMR.state.wheel_speeds.left_radps === 0")
    assert ready_site.robot.count("joystick") - before >= 6
    # STOP in MANUAL: a zero joystick command, and the line under it says so (it replaces, e.g., FIND POSITION's
    # "turning in place to look around", which STOP ends)
    page.evaluate("document.getElementById('command-result').textContent = 'Find position: turning'")
    stops = ready_site.robot.count("joystick")
    page.click("#stop")
    wait_for(page, "document.getElementById('command-result').textContent === 'Stop: done'")
    assert ready_site.robot.count("joystick") > stops

    streams = ready_site.server.app.extensions["atemr.camera_streams"]
    assert streams.open == 1  # CAM-ON: the page watches the MJPEG stream
    page.click("#cam-toggle")
    wait_for(page, "document.getElementById('cam-toggle').textContent === 'CAM-OFF'")
    assert page.locator("#camera").is_hidden()
    for _ in range(200):  # the browser dropped the stream; the server notices at its next part (<= 1 s)
        if streams.open == 0:
            break
        page.wait_for_timeout(50)
    assert streams.open == 0


def test_auto_mode_and_a_goal_by_click_and_drag_reached_by_the_robot(robot_site, page, shots, helpers):
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE' && ATEMR.map?.image != null")
    # AUTO is refused until every level-1 status is OK (the IR sensors come up after the secondary core boots)
    wait_for(page, "Object.values(ATEMR.state.level2).every((ok) => ok)")
    page.click("#go-here")  # GO HERE: the next press on the map is the goal, a drag its heading
    assert "Tap where the robot should go" in page.inner_text("#map-hint")
    start = robot_site.sim.pose
    gx, gy = start.x_m + 1.0, start.y_m + 0.5
    x, y = screen_point(page, gx, gy)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 40, y, steps=4)  # dragged to the right: heading along +x
    page.mouse.up()
    assert page.is_visible("#goal-confirm") and robot_site.agent_state == "IDLE.MANUAL"  # nothing sent yet
    page.click("#goal-go")  # CONFIRM: switches to AUTO, then sends the goal
    wait_for(page, "document.getElementById('mode-toggle').textContent === 'AUTO'")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'EXEC'")
    wait_for(page, "document.getElementById('goal-progress').textContent.startsWith('On the way: ')")
    wait_for(page, "ATEMR.state.goal !== null && ATEMR.state.global_path.length > 2")
    # the goal's acknowledgement says it was taken, never "done" beside "On the way"
    assert page.inner_text("#command-result") == "Go here: accepted"
    goal = page.evaluate("ATEMR.state.goal")
    assert abs(goal["x_m"] - gx) < 0.1 and abs(goal["y_m"] - gy) < 0.1 and abs(goal["yaw_rad"]) < 0.3
    page.screenshot(path=str(shots / "control-auto-goal.png"), full_page=True)
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'", timeout=20000)
    wait_for(page, "document.getElementById('goal-progress').textContent === 'Arrived.'")
    assert "Goal reached." in page.inner_text("#alerts")
    # the acknowledgement no longer says "accepted" once the goal has its outcome
    assert page.inner_text("#command-result") == "Go here: Goal reached."
    assert robot_site.sim.pose.distance_to(start) > 0.8  # it drove there
    assert math.hypot(robot_site.sim.pose.x_m - gx, robot_site.sim.pose.y_m - gy) < 0.3


def test_mapping_begin_end_and_save_on_the_robot(robot_site, page, shots, helpers):
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{robot_site.url}/mapping")
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'")
    version = page.evaluate("ATEMR.state.map_version")
    page.click("#mapping-toggle")
    wait_for(page, "document.getElementById('mapping-toggle').textContent === 'END MAP'")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'MAPPING'")
    page.focus("#joystick")
    page.keyboard.down("a")  # turn on the spot: the lidar sweeps the room (a redraw every 5 scans)
    wait_for(page, f"ATEMR.state.map_version > {version} + 7 && ATEMR.map.meta.version > {version} + 7",
             timeout=15000)
    page.keyboard.up("a")
    page.screenshot(path=str(shots / "mapping.png"), full_page=True)
    page.click("#mapping-toggle")
    page.wait_for_selector("#save-dialog[open]")
    page.screenshot(path=str(shots / "mapping-save-dialog.png"))
    page.fill("#save-name", "kitchen")
    page.click("#save-map")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'")
    wait_for(page, "document.getElementById('map-select').value === 'kitchen'")
    assert (robot_site.data_dir / "maps" / "kitchen.yaml").is_file()
    assert robot_site.robot.parts.maps.active_name == "kitchen"
    page.select_option("#map-select", "studio")
    wait_for(page, "document.getElementById('command-result').textContent === 'Map: done'")
    wait_for(page, "ATEMR.state.active_map === 'studio'")


def test_change_a_speed_limit_on_the_robot(robot_site, page, shots, helpers):
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{robot_site.url}/settings")
    assert page.input_value("#linear-limit") == "1.6"
    page.fill("#linear-limit", "0.8")
    page.click("#limits-update")
    page.wait_for_selector("text=Speed limits: done")
    assert page.input_value("#linear-limit") == "0.8"
    assert robot_site.robot.parts.pipeline.limits.max_linear_mps == 0.8
    assert robot_site.robot.parts.settings.load()["motion"]["max_linear_mps"] == 0.8  # persisted
    page.screenshot(path=str(shots / "settings.png"), full_page=True)


def test_turning_awareness_on_warns_that_the_robot_may_move_by_itself(ready_site, page, helpers):
    assert state_problems(ready_site.robot.state()) == []  # the test robot keeps to the pages' contract
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{ready_site.url}/settings")
    asked: list[str] = []

    def answer(dialog: Any) -> None:
        asked.append(dialog.message)
        dialog.dismiss() if len(asked) == 1 else dialog.accept()

    page.on("dialog", answer)
    page.check("#awareness")
    page.click("#awareness-form button[type=submit]")
    page.wait_for_timeout(300)
    assert ready_site.robot.count("set_awareness") == 0  # dismissed: nothing sent
    assert len(asked) == 1 and "moves by itself" in asked[0]
    page.click("#awareness-form button[type=submit]")
    page.wait_for_selector("text=Awareness on: done")
    assert ready_site.robot.count("set_awareness") == 1 and len(asked) == 2


def test_a_user_sees_the_safety_settings_read_only(ready_site, page, helpers):
    ready_site.users.create("carer", "carer-pass-1", "user")
    helpers.login(page, ready_site.url, "carer", "carer-pass-1")
    page.goto(f"{ready_site.url}/settings")
    for control in ("#linear-limit", "#awareness", "#wifi-form input[name=ssid]", "#limits-update"):
        assert page.is_disabled(control), control
    assert page.locator("text=needs the admin role").count() == 3
    page.goto(f"{ready_site.url}/control")
    assert page.is_disabled("#sim-press-5s")


def test_new_user_waits_for_an_admin_to_grant_access(ready_site, browser, page, shots, helpers):
    page.goto(f"{ready_site.url}/auth/login")
    page.click("#create-user")
    page.fill("input[name=username]", "nurse")
    page.fill("input[name=password]", "nurse-pass-1")
    page.fill("input[name=confirm]", "nurse-pass-1")
    page.screenshot(path=str(shots / "create-user.png"), full_page=True)
    page.click("button[type=submit]")
    page.wait_for_selector("text=An administrator must grant access")
    helpers.login(page, ready_site.url, "nurse", "nurse-pass-1")
    page.wait_for_selector("#no-access")
    page.screenshot(path=str(shots / "no-access.png"), full_page=True)

    admin = browser.new_context().new_page()
    helpers.login(admin, ready_site.url, "admin", helpers.ADMIN_PW)
    admin.goto(f"{ready_site.url}/settings")
    row = admin.locator('tr[data-user="nurse"]')
    row.locator("select[name=role]").select_option("user")
    row.locator("button.set-role").click()
    admin.wait_for_selector("text=nurse is now user")
    assert 'tr[data-user="admin"] button.remove-user' not in admin.content()
    assert admin.locator('tr[data-user="admin"] select').count() == 0  # root admin cannot be demoted
    admin.screenshot(path=str(shots / "settings-manage-users.png"), full_page=True)

    helpers.login(page, ready_site.url, "nurse", "nurse-pass-1")
    page.wait_for_url(re.compile(r"/control$"))
    assert page.inner_text("#username") == "nurse"

    admin.on("dialog", lambda d: d.accept())
    admin.locator('tr[data-user="nurse"] button.remove-user').click()
    admin.wait_for_selector("text=User nurse removed")
    assert ready_site.users.get("nurse") is None
    admin.context.close()


def test_simulation_panel_kidnaps_the_robot_and_shows_the_secondary_screen(robot_site, page, shots, helpers):
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE' && ATEMR.map?.image != null")
    wait_for(page, "document.getElementById('secondary-screen').naturalWidth === 256")
    start = robot_site.sim.pose
    target = next((start.x_m + dx, start.y_m) for dx in (0.6, -0.6, 1.0, -1.0)
                  if robot_site.sim.clearance_at(start.x_m + dx, start.y_m).clearance_m > 0)
    page.click("#sim-kidnap")
    x, y = screen_point(page, *target)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x, y - 40, steps=3)  # dragged up: heading along +y
    page.mouse.up()
    wait_for(page, "document.getElementById('command-result').textContent === 'Kidnap: done'")
    for _ in range(40):  # applied at the next physics tick, on the robot's thread
        pose = robot_site.sim.pose
        if pose != start:
            break
        page.wait_for_timeout(50)
    assert math.hypot(pose.x_m - target[0], pose.y_m - target[1]) < 0.1
    assert abs(pose.yaw_rad - math.pi / 2) < 0.3
    page.screenshot(path=str(shots / "control-kidnap.png"), full_page=True)
    # Localization was not told: FIND POSITION has the robot find itself, and the map shows it where it now is.
    watch_texts(page, "command-result")
    page.click("#localize-global")
    wait_for(page, f"ATEMR.state.pose !== null && Math.hypot(ATEMR.state.pose.x_m - {pose.x_m}, "
                   f"ATEMR.state.pose.y_m - {pose.y_m}) < 0.15", timeout=20_000)
    # "Find position: searching" until the search's outcome, which then takes its place
    wait_for(page, "document.getElementById('command-result').textContent"
                   ".startsWith('Find position: The robot knows where it is')")
    acks = watched_texts(page, "command-result")
    assert acks[0] == "Find position: searching" and acks[-1].startswith("Find position: The robot knows"), acks


def test_media_captured_and_recorded_then_played_previewed_downloaded_and_deleted(robot_site, page, shots, helpers):
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    wait_for_camera(page)
    images = robot_site.data_dir / "media" / "images"
    for _ in range(2):
        page.click("#capture")
        wait_for(page, "document.getElementById('command-result').textContent === 'Capture: done'")
        page.evaluate("document.getElementById('command-result').textContent = ''")
    files = sorted(images.glob("*.jpg"))
    assert len(files) == 2
    page.click("#record")
    wait_for(page, "ATEMR.state.recording === true")
    # which way it went, not "Recording: done"
    wait_for(page, "document.getElementById('command-result').textContent === 'Recording: started'")
    page.wait_for_timeout(1500)
    page.click("#record")
    wait_for(page, "ATEMR.state.recording === false")
    wait_for(page, "document.getElementById('command-result').textContent === 'Recording: stopped, in Media'")
    videos = list((robot_site.data_dir / "media" / "videos").iterdir())
    assert [v.suffix for v in videos] == [".mp4"], videos
    for i in range(10):  # older images: the page shows ten, MORE the rest
        older = images / f"older-{i}.jpg"
        Image.new("RGB", (640, 480), (20 * i, 90, 90)).save(older, format="JPEG")
        os.utime(older, (1000 + i, 1000 + i))
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(f"{robot_site.url}/media")
    # the video the recorder wrote plays in Chromium's own <video>: metadata and a first frame decoded
    video = f'#videos li[data-name="{videos[0].name}"] video'
    page.evaluate(f"(() => {{ const v = document.querySelector('{video}'); v.preload = 'auto'; v.load(); }})()")
    wait_for(page, f"document.querySelector('{video}').readyState >= 2", timeout=15_000)
    duration, width, error = page.evaluate(f"(() => {{ const v = document.querySelector('{video}'); "
                                           "return [v.duration, v.videoWidth, v.error && v.error.message]; })()")
    assert error is None and duration > 0 and width == 640
    with av.open(str(videos[0])) as container:  # as long as the robot's clock says it recorded (a loaded
        assert abs(duration - container.duration / 1e6) < 0.2  # machine runs the robot slower than real time)
    # thumbnails made by the server (images load as they come into view): the images' and the video's poster
    loaded = "(i => i.complete && i.naturalWidth === 320)"
    wait_for(page, f"[...document.querySelectorAll('#images img')].slice(0, 2).every({loaded})")
    poster = page.evaluate(f"document.querySelector('{video}').poster")
    assert page.request.get(poster).headers["content-type"] == "image/jpeg"
    page.click("#images button.more")
    wait_for(page, "document.querySelectorAll('#images li[data-name]').length === 12 "
                   "&& document.querySelector('#images button.more') === null")
    page.locator('#images li[data-name="older-0.jpg"] img').scroll_into_view_if_needed()
    wait_for(page, f"{loaded}(document.querySelector('#images li[data-name=\"older-0.jpg\"] img'))")
    assert page.get_attribute('#images li[data-name="older-0.jpg"] form', "data-confirm") == \
        "Delete older-0.jpg? This cannot be undone."
    page.screenshot(path=str(shots / "media.png"), full_page=True)
    first = files[0].name
    with page.expect_download() as info:
        page.click(f'li[data-name="{first}"] a.download')
    download = info.value
    assert download.suggested_filename == first
    data = Path(download.path()).read_bytes()
    assert data == files[0].read_bytes()
    with Image.open(io.BytesIO(data)) as image:
        assert image.size == (640, 480)
    # deleting one asks first: dismissed, nothing goes; accepted, it goes
    questions: list[str] = []

    def answer(dialog: Any, accept: bool) -> None:
        questions.append(dialog.message)
        if accept:
            dialog.accept()
        else:
            dialog.dismiss()

    page.once("dialog", lambda d: answer(d, False))
    page.click(f'li[data-name="{first}"] button.delete-one')
    page.wait_for_timeout(300)
    assert questions == [f"Delete {first}? This cannot be undone."] and files[0].exists()
    page.once("dialog", lambda d: answer(d, True))
    page.click(f'li[data-name="{first}"] button.delete-one')
    page.wait_for_selector(f"text=Deleted {first}")
    assert not files[0].exists() and files[1].exists()
    assert not errors, errors


def test_phone_sized_screen(ready_site, browser, shots, helpers):
    context = browser.new_context(viewport={"width": 390, "height": 844}, is_mobile=True, has_touch=True)
    page = context.new_page()
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= 400  # one column, no sideways scrolling
    joystick = page.locator("#joystick").bounding_box()
    assert joystick["width"] >= 120
    page.screenshot(path=str(shots / "control-phone.png"), full_page=True)
    context.close()


def test_agent_view_draws_the_lifecycle_and_tree(ready_site, page, shots, helpers):
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{ready_site.url}/agent")
    wait_for(page, "document.querySelector('#machine .mstate.active') !== null")
    active = page.eval_on_selector_all("#machine .mstate.active", "(chips) => chips.map((c) => c.textContent)")
    chips = page.eval_on_selector_all("#machine .mstate", "(chips) => chips.map((c) => c.textContent)")
    assert active[-1] == "IDLE.MANUAL" and len(chips) == len(set(chips)), chips  # each state named once
    wait_for(page, "document.querySelectorAll('#agent-tree li.node').length === 3")
    assert "all checks passed" in page.inner_text("#agent-transitions")
    # subscribing to the view is no command of the carer's: no "Agent view: done", no "not connected" toast
    page.wait_for_timeout(500)
    assert "Agent view" not in page.inner_text("#command-result") + page.inner_text("#alert-items")
    page.screenshot(path=str(shots / "agent.png"), full_page=True)


def test_several_robots_on_one_dashboard_are_told_apart(ready_site, page, shots, helpers):
    """A second robot publishing into this dashboard (as through ui.message_queue) brings up the robot
    selector; showing it displays its state and refuses commands, which belong to this dashboard's robot."""
    import threading

    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'")
    assert page.locator("#robot").is_hidden()  # one robot: the view is as it always was
    socketio = ready_site.server.app.extensions["socketio"]
    stop = threading.Event()

    def publish() -> None:  # another robot's state, at 10 Hz
        while not stop.wait(0.1):
            socketio.emit("state", {"robot": "BRAVO", "agent_state": "EXEC", "mode": "AUTO", "emergency": True},
                          to="operators")

    publisher = threading.Thread(target=publish, daemon=True)
    publisher.start()
    try:
        wait_for(page, "!document.getElementById('robot').hidden "
                       "&& document.getElementById('robot').options.length === 2")
        assert page.evaluate("ATEMR.robot") == "KAY"  # this dashboard's own robot stays shown
        assert page.get_attribute("#agent-state", "data-state") == "IDLE"
        page.select_option("#robot", "BRAVO")
        wait_for(page, "document.getElementById('agent-state').dataset.state === 'EXEC'")
        page.click("#capture")
        wait_for(page, "document.getElementById('command-result').textContent.includes('BRAVO is only watched here')")
        assert ready_site.robot.count("capture_image") == 0
        page.screenshot(path=str(shots / "control-two-robots.png"), full_page=True)
        page.select_option("#robot", "KAY")
        wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'")
        page.click("#capture")
        wait_for(page, "document.getElementById('command-result').textContent === 'Capture: done'")
    finally:
        stop.set()
        publisher.join(timeout=5)
    wait_for(page, "document.getElementById('robot').hidden")  # BRAVO went silent: it leaves the selector


def test_a_gated_transition_is_confirmed_from_the_page(robot_site, page, shots, helpers):
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{robot_site.url}/agent")
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    wait_for(page, "document.getElementById('autonomy-level').dataset.level === 'full'")
    page.click("#agent-reload")  # the explicit reload: the file is the running version
    wait_for(page, "document.getElementById('reload-status').dataset.status === 'unchanged'")
    page.screenshot(path=str(shots / "agent-studio.png"), full_page=True)
    page.select_option("#autonomy-select", "off")
    page.click("#autonomy-set")
    wait_for(page, "document.getElementById('autonomy-level').dataset.level === 'off'")
    assert "begin_mapping → MAPPING (low)" in page.inner_text("#autonomy-gated")
    page.goto(f"{robot_site.url}/mapping")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'")
    page.click("#mapping-toggle")
    wait_for(page, "!document.getElementById('autonomy-request').hidden")
    assert page.inner_text("#autonomy-what") == "may it start mapping?"
    assert "begin_mapping: IDLE.MANUAL → MAPPING" in page.get_attribute("#autonomy-what", "title")
    assert robot_site.agent_state == "IDLE.MANUAL", "it waits for the operator"
    wait_for(page, "ATEMR.state.events.some((e) => e.kind === 'autonomy' && e.text.includes('waits for the operator'))")
    page.screenshot(path=str(shots / "autonomy-request.png"), full_page=True)
    page.click("#autonomy-confirm")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'MAPPING'")
    wait_for(page, "document.getElementById('autonomy-request').hidden")
    confirmed = [r for r in robot_site.robot.components["agent"].trace if r.decision == "confirmed"]
    assert [(r.trigger, r.dest, r.decided_by) for r in confirmed] == [("begin_mapping", "MAPPING", "admin")]


def test_the_agent_page_shows_a_reload_error_with_its_position_and_the_diff(ready_site, page, helpers):
    snapshot = ready_site.robot.agent_snapshot

    def with_reload() -> dict:
        out = dict(snapshot())
        out["reloads"] = [{
            "kind": "agent", "file": "/robot/trees/agent.yaml", "t": 12.0, "status": "invalid",
            "origin": "file watcher",
            "reason": "not reloaded, the running version stays: agent.yaml:131:35: unknown node type 'Hault'",
            "diff": "--- agent.yaml (running)\n+++ agent.yaml (edited)\n@@ -131 +131 @@\n-            - {type: Halt}\n"
                    "+            - {type: Hault}\n",
            "error": {"message": "unknown node type 'Hault' (did you mean 'Halt'?)", "line": 131, "column": 35,
                      "path": "states[5].children[1].tree.children[3].type", "text": "..."},
            "applied_t": None,
        }]
        return out

    ready_site.robot.agent_snapshot = with_reload
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{ready_site.url}/agent")
    wait_for(page, "document.getElementById('reload-status').dataset.status === 'invalid'")
    assert page.inner_text("#reload-error") == "line 131, column 35: unknown node type 'Hault' (did you mean 'Halt'?)"
    assert page.inner_text("#reload-diff .del").rstrip() == "-            - {type: Halt}"
    assert page.inner_text("#reload-diff .add").rstrip() == "+            - {type: Hault}"
    assert "agent agent.yaml: invalid" in page.inner_text("#reload-status")


def test_a_map_switch_shows_not_localized_and_auto_waits_for_a_pose(robot_site, page, shots, helpers):
    """Issue 21: selecting another map drops the pose and the page says so; AUTO is refused with the reason
    (not accepted and undone) until the operator sets the pose on the map."""
    store = robot_site.robot.parts.map_store
    store.save("flat-copy", store.load("studio"))
    robot_site.gateway.maps_changed()
    helpers.login(page, robot_site.url, "admin", helpers.ADMIN_PW)
    page.goto(f"{robot_site.url}/mapping")
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE' "
                   "&& ATEMR.state.localization.localized")
    assert page.inner_text("#localization").startswith("LOCALIZED")
    wait_for(page, "Object.values(ATEMR.state.level2).every((ok) => ok)")  # every level-1 state but the pose OK
    page.select_option("#map-select", "flat-copy")
    wait_for(page, "ATEMR.state.active_map === 'flat-copy'")
    wait_for(page, "document.getElementById('localization').textContent.startsWith('NOT LOCALIZED')")
    assert page.inner_text("#localization-detail").startswith("position not known yet; needs 70%")  # not uninitialized
    assert "SET POSITION or FIND POSITION" in page.inner_text("#localization-detail")
    # the Events list in the carer's words, the robot's own on hover
    wait_for(page, "[...document.querySelectorAll('#events li')].some((li) => li.textContent.includes("
                   "'Another map is in use') && li.title.includes('not localized until a pose is set'))")
    wait_for(page, "document.getElementById('alert-items').textContent.includes('Another map is in use')")
    page.click("#mode-toggle")
    wait_for(page, "document.getElementById('command-result').textContent.startsWith("
                   "'Mode: Cannot switch to AUTO: the robot is not sure where it is')")
    assert "FIND POSITION" in page.inner_text("#command-result")
    page.screenshot(path=str(shots / "mapping-map-switched-not-localized.png"), full_page=True)
    assert robot_site.agent_state == "IDLE.MANUAL" and page.inner_text("#mode-toggle") == "MANUAL"

    page.goto(f"{robot_site.url}/control")  # the operator sets the pose where the robot stands
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE' && ATEMR.map?.image != null")
    truth = robot_site.sim.pose
    # GO HERE now: the switch to AUTO it needs is refused, and the answer is the goal's, not "Mode: ..."
    page.click("#go-here")
    page.mouse.click(*screen_point(page, truth.x_m, truth.y_m))
    page.click("#goal-go")
    wait_for(page, "document.getElementById('command-result').textContent.startsWith("
                   "'Go here: Cannot switch to AUTO: the robot is not sure where it is')")
    page.click("#goal-cancel")
    page.click("#set-position")  # the next tap on the map is where the robot is, a drag the way it faces
    x, y = screen_point(page, truth.x_m, truth.y_m)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 40 * math.cos(truth.yaw_rad), y - 40 * math.sin(truth.yaw_rad), steps=4)
    page.mouse.up()
    wait_for(page, "document.getElementById('command-result').textContent === 'Set position: done'")
    wait_for(page, "document.getElementById('localization').textContent.startsWith('LOCALIZED')", timeout=10000)
    page.click("#mode-toggle")
    wait_for(page, "document.getElementById('mode-toggle').textContent === 'AUTO'")
    assert robot_site.agent_state == "IDLE.AUTO"


def test_a_dashboard_that_went_away_reads_offline_not_error(ready_site, page, helpers):
    """The robot's process ended (the server with it): the status bar says Offline and keeps trying, not
    Refused, which means the robot refused this page (logged out, no access)."""
    helpers.login(page, ready_site.url, "admin", helpers.ADMIN_PW)
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE'")
    watch_texts(page, "sock")
    ready_site.stop()
    assert len(sessions_of(ready_site.server.app)) == 0  # every connection closed, its session forgotten
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'OFFLINE'")
    page.wait_for_timeout(2500)  # a retry or two against the closed port
    shown = watched_texts(page, "sock")
    assert "Refused" not in shown and page.inner_text("#sock") == "Offline", shown
