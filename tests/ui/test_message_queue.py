"""Beyond one machine: robots publish their state into a Redis message queue and a dashboard worker without
a robot of its own (``atemr dashboard``) delivers both robots' state to a logged-in Socket.IO client.

Runs against a real ``redis-server`` (Debian package; ``./test`` installs it as root) started here on
127.0.0.1 on a free port without persistence; skips with the reason when it is not installed.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.errors import ConfigError, HardwareError
from atemr.io.can.bus import unique_channel
from atemr.robot.assembly import build_robot
from atemr.robot.headless import headless_config
from atemr.ui.users import UserStore

FAST_SCRYPT = "scrypt:1024:8:1"
PASSWORD = "watch-secret-1"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def redis_url(tmp_path: Path) -> Iterator[str]:
    """A private redis-server on 127.0.0.1 (no RDB, no AOF), stopped after the test."""
    server = shutil.which("redis-server")
    if server is None:
        pytest.skip("redis-server is not installed (Debian package redis-server; ./test installs it as root)")
    redis = pytest.importorskip("redis", reason="the redis package is a test extra: pip install -e '.[test]'")
    port = free_port()
    proc = subprocess.Popen(
        [server, "--bind", "127.0.0.1", "--port", str(port), "--save", "", "--appendonly", "no",
         "--dir", str(tmp_path), "--daemonize", "no", "--loglevel", "warning"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    url = f"redis://127.0.0.1:{port}/0"
    try:
        client = redis.Redis.from_url(url)
        for _ in range(200):  # until it answers (it starts in milliseconds); no timing is asserted
            try:
                client.ping()
                break
            except redis.ConnectionError:
                if proc.poll() is not None:
                    pytest.fail(f"redis-server exited with {proc.returncode}")
                threading.Event().wait(0.05)
        client.close()
        yield url
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def _env(tmp_path: Path, name: str, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("ATEMR_")}
    env.update(ATEMR_DATA_DIR=str(tmp_path / name), ATEMR_LOG_LEVEL="WARNING", **extra)
    return env


def _robot(tmp_path: Path, name: str, url: str, *, dashboard: bool) -> subprocess.Popen[str]:
    """A simulated robot publishing its state into the queue: through its own dashboard (on a free port),
    or without one (`StatePublisher`)."""
    env = _env(tmp_path, name, ATEMR_UI__ENABLED=str(dashboard).lower(), ATEMR_UI__PORT="0",
               ATEMR_UI__MESSAGE_QUEUE=url, ATEMR_SECONDARY__ROBOT_NAME=name,
               ATEMR_SECONDARY__PORTAL_SERVE="false", ATEMR_SIM__CAMERA_HZ="0")
    return subprocess.Popen([sys.executable, "-m", "atemr", "run"], env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _stop(proc: subprocess.Popen[str]) -> str:
    if proc.poll() is None:
        proc.terminate()
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return err


def _login(base: str) -> Any:
    import requests

    session = requests.Session()
    page = session.get(f"{base}/auth/login", timeout=30).text
    token = page.split('name="csrf_token" value="', 1)[1].split('"', 1)[0]
    answer = session.post(f"{base}/auth/login", timeout=30, allow_redirects=False,
                          data={"username": "watcher", "password": PASSWORD, "csrf_token": token})
    assert answer.status_code == 302, answer.text
    return session


@pytest.mark.slow
def test_two_robots_reach_one_dashboard_worker_through_redis(tmp_path, redis_url):
    socketio = pytest.importorskip("socketio", reason="python-socketio[client] is a test extra")
    pytest.importorskip("websocket", reason="python-socketio[client] is a test extra (websocket-client)")
    users = UserStore(tmp_path / "dash" / "users.sqlite3", hash_method=FAST_SCRYPT)
    users.set_password("admin", "root-secret-1")
    users.create("watcher", PASSWORD, "user")

    dashboard = subprocess.Popen(
        [sys.executable, "-m", "atemr", "dashboard", "--message-queue", redis_url, "--port", "0"],
        env=_env(tmp_path, "dash"), text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )
    # ALPHA has no dashboard (a StatePublisher); BRAVO emits through its own dashboard's Socket.IO server.
    robots = [_robot(tmp_path, "ALPHA", redis_url, dashboard=False),
              _robot(tmp_path, "BRAVO", redis_url, dashboard=True)]
    client = None
    seen: dict[str, dict[str, Any]] = {}
    both = threading.Event()

    def on_state(state: dict[str, Any]) -> None:
        seen.setdefault(state.get("robot", "?"), state)
        if {"ALPHA", "BRAVO"} <= seen.keys():
            both.set()

    try:
        line = dashboard.stdout.readline()  # blocks until the worker listens (or exits: empty line)
        assert "ATEMR dashboard on http://127.0.0.1:" in line, _stop(dashboard)
        base = line.split(" on ", 1)[1].split(",", 1)[0]
        client = socketio.Client(reconnection=False, http_session=_login(base))  # sends the session's cookie
        client.on("state", on_state)
        client.connect(base, transports=["websocket"], wait_timeout=30)
        assert both.wait(timeout=120), (
            f"robots seen: {sorted(seen)}; robot stderr: {[_stop(r)[-2000:] for r in robots]}"
        )
    finally:
        if client is not None and client.connected:
            client.disconnect()
        errors = [_stop(p) for p in (*robots, dashboard)]
    for name in ("ALPHA", "BRAVO"):
        state = seen[name]
        assert state["simulation"] is True and state["agent_state"] in ("STARTUP", "IDLE"), state
        assert isinstance(state["sent_unix_s"], float)
    for proc, err in zip((*robots, dashboard), errors, strict=True):
        assert proc.returncode == 0, err[-3000:]


def test_a_dashboard_worker_needs_a_queue(tmp_path, capsys):
    from atemr.cli.main import main

    assert main(["dashboard", "--data-dir", str(tmp_path), "--port", "0"]) == 2
    assert "ui.message_queue" in capsys.readouterr().err


def test_the_queue_must_be_redis():
    with pytest.raises(ConfigError, match="ATEMR_UI__MESSAGE_QUEUE: must start with redis:// or rediss://"):
        load_config(environ={"ATEMR_UI__MESSAGE_QUEUE": "amqp://127.0.0.1/"})


def test_a_robot_publishes_only_when_a_queue_is_set_and_refuses_to_start_without_it(tmp_path):
    pytest.importorskip("redis", reason="the redis package is a test extra")

    def build(**overrides: Any) -> Any:
        config = load_config(environ={}, overrides={
            "data_dir": str(tmp_path), "can.channel": unique_channel("mq"), "ui.enabled": False,
            "secondary.portal_serve": False, **overrides})
        return build_robot(config, realtime=False, clock=SimClock())

    plain = build()
    try:
        assert "state_publisher" not in plain.components
    finally:
        plain.shutdown()
    url = f"redis://127.0.0.1:{free_port()}/0"  # nothing listens there
    queued = build(**{"ui.message_queue": url})
    try:
        assert queued.parts.state_publisher.url == url and "state_publisher" in queued.components
        with pytest.raises(HardwareError, match=f"cannot reach the message queue {url}"):
            queued.start()
        assert not queued.parts.state_publisher.running
    finally:
        queued.shutdown()
    assert headless_config(queued.config).ui.message_queue is None  # headless runs never publish
