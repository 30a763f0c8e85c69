"""Fixtures for the dashboard, as in flaskr's conftest: an app on a temporary data dir, a client, logins.

`RecordingGateway` is a test double of the robot: it records every command and answers from a table
of refusals the test sets; it does not simulate anything.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
from flask import Flask
from flask.testing import FlaskClient

from atemr.clock import SimClock
from atemr.config import Config, UiConfig
from atemr.msgs import Pose2D
from atemr.ui.app import create_app
from atemr.ui.gateway import CommandResult, MapImage
from atemr.ui.state import RobotState

FAST_SCRYPT = "scrypt:1024:8:1"
ADMIN_PW = "root-secret-1"
USER_PW = "user-secret-1"


class RecordingGateway:
    """Records commands as (name, args); `refuse[name] = reason` makes that command refused."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.refuse: dict[str, str] = {}
        self.snapshot: RobotState = {
            "robot": "KAY", "agent_state": "IDLE", "mode": "MANUAL", "simulation": True, "active_map": None,
            "map_version": 0, "pose": None,
            "localization": {"confidence": 0.0, "limit": 0.7, "localized": False, "state": "no map", "candidates": [],
                             "looking_around": False},
            "scan": [], "depth_obstacles": [], "global_path": [], "local_path": [], "goal": None,
            "navigation": None, "wheel_speeds": {"left_radps": 0.0, "right_radps": 0.0}, "emergency": False,
            "stop_cause": None, "level1": {}, "level2": {},
            "system": None, "limits": {"linear_mps": 0.5, "angular_radps": 1.0}, "awareness": False,
            "wifi_ssid": None, "mapping": False, "recording": False, "mission": None, "missions": ["patrol"],
            "maps": [], "places": [], "battery": None, "events": [],
            "autonomy": {"level": "full", "levels": ["off", "low", "high", "full"], "timeout_s": 30.0,
                         "pending": None, "now": 0.0},
        }
        self.map: MapImage | None = None
        self.jpeg: bytes | None = None
        self.frame: Any = None  # the raw camera frame (H x W x 3 uint8) the WebRTC drive video sends
        self.screen: bytes | None = None
        self.agent: dict[str, Any] | None = None
        self.maps_changed_count = 0
        self.in_use: list[Path] = []  # what files_in_use answers: the files the robot is writing
        self.routine_data: dict[str, Any] | None = {
            "timezone": "Europe/Berlin", "now": "2026-06-03 08:00 CEST", "running": None, "error": None,
            "routines": [{"name": "check-on-resident", "mission": "patrol", "at": "09:00", "enabled": True,
                          "schedule": "daily at 09:00", "next": "2026-06-03 09:00 CEST"}],
            "history": [{"routine": "check-on-resident", "stamp": "2026-06-02 09:00 CEST", "time": "09:00",
                         "outcome": "skipped", "reason": "robot in MANUAL", "mission": "patrol"}],
        }

    def _cmd(self, name: str, *args: Any) -> CommandResult:
        self.calls.append((name, args))
        if name in self.refuse:
            return CommandResult.refused(self.refuse[name])
        return CommandResult.accepted()

    def names(self) -> list[str]:
        return [c[0] for c in self.calls]

    def state(self) -> RobotState:
        return self.snapshot.copy()

    def map_image(self) -> MapImage | None:
        return self.map

    def camera_jpeg(self) -> bytes | None:
        return self.jpeg

    def camera_frame(self) -> Any:
        return self.frame

    def secondary_screen_png(self) -> bytes | None:
        return self.screen

    def agent_snapshot(self) -> dict[str, Any] | None:
        return self.agent

    def joystick(self, twist: Any) -> CommandResult:
        return self._cmd("joystick", twist)

    def set_mode(self, mode: str) -> CommandResult:
        return self._cmd("set_mode", mode)

    def set_goal(self, goal: Pose2D) -> CommandResult:
        return self._cmd("set_goal", goal)

    def set_initial_pose(self, pose: Pose2D) -> CommandResult:
        return self._cmd("set_initial_pose", pose)

    def localize_globally(self) -> CommandResult:
        return self._cmd("localize_globally")

    def cancel_goal(self) -> CommandResult:
        return self._cmd("cancel_goal")

    def begin_mapping(self) -> CommandResult:
        return self._cmd("begin_mapping")

    def end_mapping(self) -> CommandResult:
        return self._cmd("end_mapping")

    def save_map(self, name: str) -> CommandResult:
        return self._cmd("save_map", name)

    def discard_map(self) -> CommandResult:
        return self._cmd("discard_map")

    def select_map(self, name: str) -> CommandResult:
        return self._cmd("select_map", name)

    def validate_map(self, yaml_path: Path) -> CommandResult:
        return self._cmd("validate_map", yaml_path)

    def maps_changed(self) -> None:
        self.maps_changed_count += 1

    def files_in_use(self) -> Any:
        return tuple(self.in_use)

    def routines(self) -> dict[str, Any] | None:
        return self.routine_data

    def save_routine(self, routine: dict[str, Any], previous: str | None = None) -> CommandResult:
        return self._cmd("save_routine", routine, previous)

    def delete_routine(self, name: str) -> CommandResult:
        return self._cmd("delete_routine", name)

    def set_routines_timezone(self, timezone: str) -> CommandResult:
        return self._cmd("set_routines_timezone", timezone)

    def go_to_place(self, name: str) -> CommandResult:
        return self._cmd("go_to_place", name)

    def save_place(self, name: str, pose: Pose2D, kind: str = "place", previous: str | None = None) -> CommandResult:
        return self._cmd("save_place", name, pose, kind, previous)

    def delete_place(self, name: str) -> CommandResult:
        return self._cmd("delete_place", name)

    def set_limits(self, linear_mps: float, angular_radps: float) -> CommandResult:
        return self._cmd("set_limits", linear_mps, angular_radps)

    def set_awareness(self, enabled: bool) -> CommandResult:
        return self._cmd("set_awareness", enabled)

    def set_wifi(self, ssid: str, password: str) -> CommandResult:
        return self._cmd("set_wifi", ssid, password)

    def capture_image(self) -> CommandResult:
        return self._cmd("capture_image")

    def record_video(self, on: bool) -> CommandResult:
        return self._cmd("record_video", on)

    def start_mission(self, name: str) -> CommandResult:
        return self._cmd("start_mission", name)

    def stop_mission(self) -> CommandResult:
        return self._cmd("stop_mission")

    def answer_transition(self, request_id: int, confirm: bool, by: str) -> CommandResult:
        return self._cmd("answer_transition", request_id, confirm, by)

    def set_autonomy(self, level: str, by: str) -> CommandResult:
        return self._cmd("set_autonomy", level, by)

    def reload_agent(self) -> CommandResult:
        return self._cmd("reload_agent")

    def sim_button(self, hold_s: float) -> CommandResult:
        return self._cmd("sim_button", hold_s)

    def sim_drop_obstacle(self, x_m: float, y_m: float) -> CommandResult:
        return self._cmd("sim_drop_obstacle", x_m, y_m)

    def sim_kidnap(self, pose: Pose2D) -> CommandResult:
        return self._cmd("sim_kidnap", pose)


def make_config(tmp_path: Path, **ui: Any) -> Config:
    return Config(data_dir=tmp_path / "data", ui=UiConfig(**ui))


@pytest.fixture
def gateway() -> RecordingGateway:
    return RecordingGateway()


@pytest.fixture
def clock() -> SimClock:
    return SimClock()


@pytest.fixture
def fresh_app(tmp_path: Path, gateway: RecordingGateway, clock: SimClock) -> Flask:
    """An app on a new data dir: the root admin has no password yet."""
    return create_app(make_config(tmp_path, login_max_failures=3, login_lockout_s=60.0), gateway,
                      clock=clock, hash_method=FAST_SCRYPT)


@pytest.fixture
def app(fresh_app: Flask) -> Flask:
    """An app whose root admin password is set and with a user 'alice' (role user) and 'bob' (none)."""
    store = fresh_app.extensions["atemr.users"]
    store.set_password("admin", ADMIN_PW)
    store.create("alice", USER_PW, "user")
    store.create("bob", USER_PW)
    return fresh_app


@pytest.fixture
def client(app: Flask) -> FlaskClient:
    return app.test_client()


def csrf_of(client: FlaskClient, path: str = "/auth/login") -> str:
    """The CSRF token the page at ``path`` puts in its forms."""
    html = client.get(path).get_data(as_text=True)
    match = re.search(r'name="csrf_token" value="([^"]+)"', html)
    assert match, f"no CSRF token on {path}"
    return match.group(1)


def login(client: FlaskClient, username: str, password: str) -> Any:
    token = csrf_of(client)
    return client.post("/auth/login", data={"username": username, "password": password, "csrf_token": token})


def post(client: FlaskClient, path: str, data: dict[str, Any] | None = None, **kw: Any) -> Any:
    """POST with the session's CSRF token (read from the control page, which every logged-in user sees)."""
    token = csrf_of(client, "/settings")
    return client.post(path, data={**(data or {}), "csrf_token": token}, **kw)


class UiHelp:
    """The helpers above as a fixture (tests import nothing from conftest under importlib mode)."""

    ADMIN_PW = ADMIN_PW
    USER_PW = USER_PW
    FAST_SCRYPT = FAST_SCRYPT
    csrf_of = staticmethod(csrf_of)
    login = staticmethod(login)
    post = staticmethod(post)
    make_config = staticmethod(make_config)


@pytest.fixture
def ui() -> type[UiHelp]:
    return UiHelp


@pytest.fixture
def alice(client: FlaskClient) -> FlaskClient:
    assert login(client, "alice", USER_PW).status_code == 302
    return client


@pytest.fixture
def admin(client: FlaskClient) -> FlaskClient:
    assert login(client, "admin", ADMIN_PW).status_code == 302
    return client
