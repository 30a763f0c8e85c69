"""Browser tests: Debian's chromium driven by Playwright against a real dashboard server on a free port.

Two kinds of site:

* `RobotSite` (``robot_site``/``ready_robot_site``): the whole simulated robot (`build_robot` +
  `add_dashboard`, the real `RobotGatewayImpl`) run by its scheduler in a background thread on
  `BootThenRealTime`: the robot boots unpaced (as fast as the CPU allows) and then runs paced at ``speed``.
  For behaviour that needs the robot: driving, AUTO goals, mapping, limits, captures.
* `Site` (``site``/``ready_site``): the dashboard against `KinematicGateway`, a test double that integrates
  joystick commands into a pose and records every command. For the dashboard's own mechanics (first
  start, users, the joystick resend rhythm, the phone layout, the agent view).

Tests skip with the reason when chromium or Playwright is missing; `./test` installs chromium when it can.
"""

from __future__ import annotations

import io
import math
import os
import shutil
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from PIL import Image, ImageDraw

from atemr.clock import RealTimeSimClock, SimClock, WallClock
from atemr.config import Config, UiConfig, load_config
from atemr.io.can.bus import unique_channel
from atemr.msgs import Pose2D, Twist
from atemr.scheduler import Scheduler
from atemr.ui.gateway import CommandResult, MapImage
from atemr.ui.server import PUSH_RATE_HZ, DashboardServer
from atemr.ui.state import RobotState

CHROMIUM = "/usr/bin/chromium"
ROOT = Path(__file__).resolve().parents[2]
OUTPUT = ROOT / "test-output" / "e2e"
ADMIN_PW = "e2e-admin-pass"
FAST_SCRYPT = "scrypt:1024:8:1"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def _png(img: Image.Image, fmt: str = "PNG") -> bytes:
    buf = io.BytesIO()
    img.save(buf, format=fmt)
    return buf.getvalue()


class KinematicGateway:
    """A robot stand-in for browser tests: unicycle kinematics from joystick/goal commands, no physics."""

    RES_M = 0.05

    def __init__(self, clock: RealTimeSimClock) -> None:
        self.clock = clock
        self.lock = threading.Lock()
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.pose = Pose2D(1.0, 1.0, 0.0)
        self.twist = Twist()
        self.twist_t = -1.0
        self.applied = Twist()
        self.mode = "MANUAL"
        self.agent = "IDLE"
        self.goal: Pose2D | None = None
        self.mapping = False
        self.limits = (0.5, 1.0)
        self.awareness = False
        self.stop_cause: str | None = None
        #: The state's localization when a test sets it (None: localized).
        self.localization: dict[str, Any] | None = None
        self.events: list[dict[str, Any]] = [{"t": 0.5, "kind": "info", "text": "agent started",
                                                   "unix_s": time.time()}]
        self.active_map = "room"
        self.maps = ["other", "room"]
        grid = Image.new("L", (120, 80), 254)
        ImageDraw.Draw(grid).rectangle([0, 0, 119, 79], outline=0, width=2)
        ImageDraw.Draw(grid).rectangle([60, 20, 70, 60], fill=0)
        self.map = MapImage(_png(grid), 120, 80, self.RES_M, Pose2D(0.0, 0.0, 0.0), 1)
        cam = Image.new("RGB", (640, 480), (40, 60, 90))
        ImageDraw.Draw(cam).text((20, 20), "ATEMR camera (test)", fill=(255, 255, 255))
        self.jpeg = _png(cam, "JPEG")

    # -- the robot's side: a scheduler component ---------------------------------------------------------
    name = "kinematic_robot"

    def tick(self, now: float) -> None:
        dt = 1.0 / PUSH_RATE_HZ
        with self.lock:
            twist = self.twist if now - self.twist_t <= 0.5 else Twist()  # the robot's 0.5 s joystick timeout
            self.applied = twist
            if self.mode == "AUTO" and self.goal is not None:
                dx, dy = self.goal.x_m - self.pose.x_m, self.goal.y_m - self.pose.y_m
                dist = math.hypot(dx, dy)
                if dist < 0.25:
                    self.goal, self.agent = None, "IDLE"
                    self.events.append({"t": round(now, 2), "kind": "goal", "text": "Goal reached.",
                                        "unix_s": time.time()})
                    twist = Twist()
                else:
                    step = min(dist, self.limits[0] * dt)
                    yaw = math.atan2(dy, dx)
                    self.pose = Pose2D(self.pose.x_m + step * math.cos(yaw), self.pose.y_m + step * math.sin(yaw), yaw)
                    return
            elif self.mode == "AUTO":
                twist = Twist()
            yaw = self.pose.yaw_rad + twist.angular_radps * dt
            self.pose = Pose2D(self.pose.x_m + twist.linear_mps * dt * math.cos(yaw),
                               self.pose.y_m + twist.linear_mps * dt * math.sin(yaw), yaw)

    # -- what the dashboard reads ------------------------------------------------------------------------
    def state(self) -> RobotState:
        with self.lock:
            p = self.pose
            scan = [[p.x_m + 1.5 * math.cos(a / 10), p.y_m + 1.5 * math.sin(a / 10)] for a in range(0, 63, 3)]
            goal = self.goal
            return {
                "robot": "KAY", "agent_state": self.agent, "mode": self.mode, "simulation": True,
                "active_map": self.active_map,
                "map_version": self.map.version, "pose": {"x_m": p.x_m, "y_m": p.y_m, "yaw_rad": p.yaw_rad},
                "localization": self.localization or {"confidence": 0.98, "limit": 0.7, "localized": True,
                                                      "state": "localized", "candidates": [],
                                                      "looking_around": False},
                "scan": scan, "depth_obstacles": [],
                "global_path": [[p.x_m, p.y_m], [goal.x_m, goal.y_m]] if goal else [],
                "local_path": [], "goal": goal and {"x_m": goal.x_m, "y_m": goal.y_m, "yaw_rad": goal.yaw_rad},
                "navigation": goal and {"distance_left_m": round(math.hypot(goal.x_m - p.x_m, goal.y_m - p.y_m), 2),
                                        "eta_s": round(math.hypot(goal.x_m - p.x_m, goal.y_m - p.y_m)
                                                       / self.limits[0], 1)},
                "stop_cause": self.stop_cause,
                "wheel_speeds": {"left_radps": self.applied.linear_mps / 0.1,
                                 "right_radps": self.applied.linear_mps / 0.1},
                "emergency": False,
                "level1": {"heartbeat": True, "hardware": True, "auto": self.mode == "AUTO", "connectivity": True,
                           "localization": True},
                "level2": {k: True for k in ("left_motor", "right_motor", "imu", "lidar", "camera", "webserver",
                                             "ir_front", "ir_rear")},
                "system": {"t": math.floor(self.clock.now()), "cpu_percent": 20.0, "memory_percent": 40.0,
                           "disk_percent": 60.0},
                "limits": {"linear_mps": self.limits[0], "angular_radps": self.limits[1]},
                "awareness": self.awareness, "wifi_ssid": "lab", "mapping": self.mapping, "recording": False,
                "mission": None, "missions": ["patrol", "visit_kitchen"], "maps": list(self.maps), "places": [],
                "battery": {"percent": 76.0, "voltage_v": 26.4, "level": "ok"},
                "events": [dict(e) for e in self.events[-20:]],
                "autonomy": {"level": "full", "levels": ["off", "low", "high", "full"], "timeout_s": 30.0,
                             "pending": None, "now": self.clock.now()},
            }

    def map_image(self) -> MapImage | None:
        return self.map

    def camera_jpeg(self) -> bytes | None:
        return self.jpeg

    def agent_snapshot(self) -> dict[str, Any] | None:
        with self.lock:
            running = "RUNNING"
            return {
                "state": f"{self.agent}.{self.mode}" if self.agent == "IDLE" else self.agent, "mode": self.mode,
                "valid_triggers": ["goal", "begin_mapping"], "task": None, "error": None,
                "tree": {"name": self.agent.title(), "type": "Sequence", "status": running, "children": [
                    {"name": "ReadSensors", "type": "Leaf", "status": "SUCCESS"},
                    {"name": "Drive", "type": "Leaf", "status": running, "feedback": f"mode {self.mode}"}]},
                "monitor": {"name": "Monitor", "type": "Parallel", "status": running, "children": [
                    {"name": "Heartbeat", "type": "Leaf", "status": "SUCCESS"}]},
                "transitions": [{"t": 0.5, "trigger": "started", "source": "STARTUP", "dest": "IDLE",
                                 "accepted": True, "reason": "all checks passed"}],
            }

    def secondary_screen_png(self) -> bytes | None:
        img = Image.new("1", (128, 64), 0)
        ImageDraw.Draw(img).text((4, 4), "OPS", fill=1)
        return _png(img)

    # -- commands ---------------------------------------------------------------------------------------
    def _record(self, name: str, *args: Any) -> None:
        with self.lock:
            self.calls.append((name, args))

    def count(self, name: str) -> int:
        with self.lock:
            return sum(1 for c in self.calls if c[0] == name)

    def joystick(self, twist: Twist) -> CommandResult:
        self._record("joystick", twist)
        with self.lock:
            if self.mode == "AUTO":
                return CommandResult.refused("joystick ignored in AUTO")
            self.twist, self.twist_t = twist, self.clock.now()
        return CommandResult.accepted()

    def set_mode(self, mode: str) -> CommandResult:
        self._record("set_mode", mode)
        with self.lock:
            self.mode = mode
        return CommandResult.accepted()

    def set_goal(self, goal: Pose2D) -> CommandResult:
        self._record("set_goal", goal)
        with self.lock:
            if self.mode != "AUTO":
                return CommandResult.refused("switch to AUTO first")
            self.goal, self.agent = goal, "EXEC"
        return CommandResult.accepted()

    def set_initial_pose(self, pose: Pose2D) -> CommandResult:
        self._record("set_initial_pose", pose)
        with self.lock:
            self.pose = pose
        return CommandResult.accepted()

    def localize_globally(self) -> CommandResult:
        self._record("localize_globally")
        return CommandResult.accepted()

    def set_limits(self, linear_mps: float, angular_radps: float) -> CommandResult:
        self._record("set_limits", linear_mps, angular_radps)
        with self.lock:
            self.limits = (linear_mps, angular_radps)
        return CommandResult.accepted()

    def begin_mapping(self) -> CommandResult:
        self._record("begin_mapping")
        with self.lock:
            self.mapping, self.agent = True, "MAPPING"
        return CommandResult.accepted()

    def end_mapping(self) -> CommandResult:
        self._record("end_mapping")
        with self.lock:
            self.mapping = False
        return CommandResult.accepted()

    def save_map(self, name: str) -> CommandResult:
        self._record("save_map", name)
        with self.lock:
            self.agent, self.active_map = "IDLE", name
            self.maps = sorted({*self.maps, name})
        return CommandResult.accepted()

    def discard_map(self) -> CommandResult:
        self._record("discard_map")
        with self.lock:
            self.agent = "IDLE"
        return CommandResult.accepted()

    def __getattr__(self, name: str) -> Any:
        """The remaining commands are recorded and accepted."""
        if name.startswith("_"):
            raise AttributeError(name)

        def command(*args: Any) -> CommandResult:
            self._record(name, *args)
            return CommandResult.accepted()

        return command

    def maps_changed(self) -> None:
        self._record("maps_changed")

    def files_in_use(self) -> tuple[Path, ...]:
        return ()


class Site:
    """A running dashboard + robot stand-in, and where screenshots go."""

    def __init__(self, data_dir: Path, clock: RealTimeSimClock) -> None:
        self.data_dir = data_dir
        self.robot = KinematicGateway(clock)
        # MJPEG: the pages' tests watch the stream (WebRTC drive video has its own, test_drive_video.py)
        config = Config(data_dir=data_dir, ui=UiConfig(port=0, drive_video="mjpeg"))
        self.server = DashboardServer(config, self.robot, clock=clock, hash_method=FAST_SCRYPT)
        self.scheduler = Scheduler(clock)
        self.scheduler.add(self.robot, PUSH_RATE_HZ)
        self.scheduler.add(self.server, PUSH_RATE_HZ)
        self.thread = threading.Thread(target=self.scheduler.run, name="e2e-scheduler", daemon=True)

    @property
    def url(self) -> str:
        return self.server.url

    @property
    def users(self) -> Any:
        return self.server.app.extensions["atemr.users"]

    def start(self) -> None:
        self.scheduler.start()
        self.thread.start()

    def stop(self) -> None:
        self.scheduler.stop()
        self.thread.join(timeout=5)
        self.scheduler.shutdown()

    def pause(self) -> None:
        """The robot stops sending its state (its process ended) while the dashboard stays up."""
        self.scheduler.stop()
        self.thread.join(timeout=5)

    def resume(self) -> None:
        """A robot comes up again and sends its state."""
        self.thread = threading.Thread(target=self.scheduler.run, name="e2e-scheduler", daemon=True)
        self.thread.start()


class BootThenRealTime(SimClock):
    """Simulated time that runs unpaced up to ``boot_s`` (the robot boots as fast as the CPU allows),
    then paced against the wall clock at ``speed`` simulated seconds per real second."""

    def __init__(self, boot_s: float, speed: float = 1.0) -> None:
        super().__init__(0.0)
        self.boot_s = boot_s
        self.speed = speed
        self._wall = WallClock()
        self._origin: tuple[float, float] | None = None  # (wall, simulated) when pacing began

    def sleep_until(self, t: float) -> None:
        if t <= self._t:
            return
        if t > self.boot_s:
            if self._origin is None:
                self._origin = (self._wall.now(), self._t)
            self._wall.sleep_until(self._origin[0] + (t - self._origin[1]) / self.speed)
        self._t = float(t)


#: Simulated seconds the robot needs to reach IDLE (the secondary core boots for 3 s).
BOOT_S = 4.0


class RobotSite:
    """The whole simulated robot with its dashboard, run in a background thread."""

    def __init__(self, data_dir: Path, speed: float = 1.0, overrides: dict[str, Any] | None = None) -> None:
        """``overrides``: configuration keys for this robot (``{"nav.timeout_s": 12.0}``) over the test defaults;
        the drive camera is MJPEG unless they say ``ui.drive_video`` (the pages' tests watch the stream)."""
        from atemr.robot import build_robot
        from atemr.robot.dashboard import add_dashboard

        self.data_dir = data_dir
        config = load_config(environ={}, overrides={
            "data_dir": str(data_dir), "can.channel": unique_channel("e2e"), "sim.seed": 5,
            "secondary.portal_serve": False, "ui.enabled": False, "ui.port": 0, "ui.drive_video": "mjpeg",
            **(overrides or {}),
        })
        self.clock = BootThenRealTime(BOOT_S, speed)
        self.robot = build_robot(config, realtime=True, clock=self.clock)
        self.server = add_dashboard(self.robot, hash_method=FAST_SCRYPT)
        self.gateway = self.robot.parts.gateway
        self.sim = self.robot.parts.sim
        self.thread = threading.Thread(target=self.robot.run, name="e2e-robot", daemon=True)

    @property
    def url(self) -> str:
        return self.server.url

    @property
    def users(self) -> Any:
        return self.server.app.extensions["atemr.users"]

    @property
    def agent_state(self) -> str:
        return str(self.robot.components["agent"].state)  # type: ignore[attr-defined]

    def start(self) -> None:
        self.robot.start()
        self.thread.start()

    def pause(self) -> None:
        """The robot's loop ends (as its process would) while its dashboard's web server stays up."""
        self.robot.stop()
        self.thread.join(timeout=10)

    def stop(self) -> None:
        self.pause()
        self.robot.shutdown()
        self.gateway.close()


def running(site: RobotSite) -> Iterator[RobotSite]:
    """``site`` with its admin password set, running for the test, stopped after it (a fixture's body)."""
    site.users.set_password("admin", ADMIN_PW)
    site.start()
    yield site
    site.stop()


@pytest.fixture
def robot_site(tmp_path: Path) -> Iterator[RobotSite]:
    yield from running(RobotSite(tmp_path / "data", speed=1.0))


@pytest.fixture
def webrtc_robot_site(tmp_path: Path) -> Iterator[RobotSite]:
    """The robot site sending its drive camera over WebRTC, its camera numbering its frames
    (``sim.camera_counter``); skips without aiortc (the webrtc extra)."""
    pytest.importorskip("aiortc", reason="aiortc (the webrtc extra) is not installed")
    yield from running(RobotSite(tmp_path / "data", overrides={"ui.drive_video": "webrtc", "sim.camera_counter": True}))


@pytest.fixture
def fast_robot_site(tmp_path: Path) -> Iterator[RobotSite]:
    """The robot site paced at 4× real time (a whole mission in a few seconds)."""
    yield from running(RobotSite(tmp_path / "data", speed=4.0))


def _skip_reason() -> str | None:
    if not Path(CHROMIUM).exists():
        return f"{CHROMIUM} is missing (./test installs Debian's chromium when run as root)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright (python) is not installed"
    return None


#: A fake camera (a test pattern) and microphone (a beep), granted without asking, and sound that plays
#: without a tap: for the call's tests, as a kiosk tablet is set up.
MEDIA_ARGS = ["--use-fake-device-for-media-stream", "--use-fake-ui-for-media-stream",
              "--autoplay-policy=no-user-gesture-required"]


@pytest.fixture(scope="session")
def playwright() -> Iterator[Any]:
    """One Playwright for the session: its sync API cannot run twice at once, so every browser comes from it."""
    reason = _skip_reason()
    if reason:
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        yield pw


def _launch(pw: Any, extra: list[str]) -> Any:
    args = CHROMIUM_ARGS if os.geteuid() == 0 else CHROMIUM_ARGS[1:]
    return pw.chromium.launch(executable_path=CHROMIUM, args=[*args, *extra], headless=True)


@pytest.fixture(scope="session")
def browser(playwright: Any) -> Iterator[Any]:
    browser = _launch(playwright, [])
    yield browser
    browser.close()


@pytest.fixture
def launch(playwright: Any) -> Iterator[Any]:
    """``launch(*args)``: a Chromium of this test's own with extra command-line ``args``; closed after it."""
    browsers: list[Any] = []

    def start(*extra: str) -> Any:
        browsers.append(_launch(playwright, list(extra)))
        return browsers[-1]

    yield start
    for browser in browsers:
        browser.close()


@pytest.fixture(scope="session")
def media_browser(playwright: Any) -> Iterator[Any]:
    """Chromium with `MEDIA_ARGS`: getUserMedia answers with fake devices."""
    browser = _launch(playwright, MEDIA_ARGS)
    yield browser
    browser.close()


@pytest.fixture
def site(tmp_path: Path) -> Iterator[Site]:
    site = Site(tmp_path / "data", RealTimeSimClock(speed=1.0))
    site.start()
    yield site
    site.stop()


@pytest.fixture
def ready_site(site: Site) -> Site:
    """A site whose root admin password is already set."""
    site.users.set_password("admin", ADMIN_PW)
    return site


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    context = browser.new_context(viewport={"width": 1280, "height": 860}, accept_downloads=True)
    page = context.new_page()
    page.set_default_timeout(10_000)
    violations: list[str] = []
    page.on("console", lambda m: violations.append(m.text) if "Content Security Policy" in m.text else None)
    page.on("pageerror", lambda e: violations.append(f"uncaught: {e}"))
    yield page
    context.close()
    assert not violations, f"the page broke its own CSP or threw: {violations}"


@pytest.fixture(scope="session")
def shots() -> Path:
    shutil.rmtree(OUTPUT, ignore_errors=True)
    OUTPUT.mkdir(parents=True, exist_ok=True)
    return OUTPUT


def login(page: Any, url: str, username: str, password: str) -> None:
    page.goto(f"{url}/auth/login")
    page.fill("#username-input", username)
    page.fill("#password-input", password)
    page.click("#login-button")


def wait_for(page: Any, js: str, timeout_s: float = 15.0) -> Any:
    """Poll the function ``js`` (evaluated by Playwright, not by the page: its CSP forbids eval) until it
    returns something truthy, and return that."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = page.evaluate(js)
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"still false after {timeout_s:.0f} s: {js} → {value!r}")
        page.wait_for_timeout(100)


@pytest.fixture
def helpers() -> Any:
    class Helpers:
        ADMIN_PW = ADMIN_PW
        MEDIA_ARGS = MEDIA_ARGS
        FAST_SCRYPT = FAST_SCRYPT
        login = staticmethod(login)
        wait_for = staticmethod(wait_for)

    return Helpers
