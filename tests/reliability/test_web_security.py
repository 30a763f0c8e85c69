"""Web-security checks of issue 11 that tests/ui does not already make.

tests/ui covers: every route without a session or with the wrong role, CSRF on every form, the login rate
limit, traversal in media downloads, secure_filename and size limits on map uploads, Socket.IO connect and
per-event role checks, cross-origin Socket.IO handshakes, and the root admin in the user store. Added here:

* the root admin cannot be removed or demoted *through the dashboard*, even by another admin;
* no HTTP response carries a CORS grant (``Access-Control-Allow-Origin``) for a foreign origin, preflight
  or not (same origin only, docs/dashboard.md#security);
* a state-changing POST from a foreign origin with a stolen session but no CSRF token is refused and
  changes nothing;
* oversized bodies are refused (413) on routes that take no upload at all, before any handler runs;
* traversal and odd names in the user-management URLs are refused without touching any user.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from flask import Flask
from flask.testing import FlaskClient

from atemr.clock import SimClock
from atemr.config import Config, UiConfig
from atemr.ui.app import create_app

FAST_SCRYPT = "scrypt:1024:8:1"
ADMIN_PW = "root-secret-1"
OTHER_PW = "other-secret-1"
EVIL = "https://evil.example"


@pytest.fixture
def app(tmp_path: Path) -> Flask:
    config = Config(data_dir=tmp_path / "data", ui=UiConfig(max_upload_mb=1.0))
    app = create_app(config, None, clock=SimClock(), hash_method=FAST_SCRYPT)
    store = app.extensions["atemr.users"]
    store.set_password("admin", ADMIN_PW)
    store.create("deputy", OTHER_PW, "admin")  # a second administrator
    store.create("carol", OTHER_PW, "user")
    return app


def token_of(client: FlaskClient, path: str) -> str:
    match = re.search(r'name="csrf_token" value="([^"]+)"', client.get(path).get_data(as_text=True))
    assert match, f"no CSRF token on {path}"
    return match.group(1)


def logged_in(app: Flask, username: str, password: str) -> FlaskClient:
    client = app.test_client()
    response = client.post("/auth/login", data={"username": username, "password": password,
                                                "csrf_token": token_of(client, "/auth/login")})
    assert response.status_code == 302, response.status_code
    return client


def users(app: Flask) -> dict[str, str]:
    return {u.username: u.role for u in app.extensions["atemr.users"].list()}


def test_the_root_admin_can_be_neither_removed_nor_demoted_through_the_dashboard(app: Flask) -> None:
    deputy = logged_in(app, "deputy", OTHER_PW)
    token = token_of(deputy, "/settings")
    before = users(app)
    for role in ("user", "none", "admin "):
        deputy.post("/settings/users/admin/role", data={"role": role, "csrf_token": token})
    deputy.post("/settings/users/admin/remove", data={"csrf_token": token})
    assert users(app) == before and before["admin"] == "admin"
    root = logged_in(app, "admin", ADMIN_PW)  # and the root admin can still log in
    assert root.get("/settings").status_code == 200


@pytest.mark.parametrize("path", ["/", "/auth/login", "/settings", "/socket.io/?EIO=4&transport=polling"])
def test_no_response_grants_a_foreign_origin(app: Flask, path: str) -> None:
    client = logged_in(app, "carol", OTHER_PW)
    for method in ("GET", "OPTIONS"):
        response = client.open(path, method=method, headers={
            "Origin": EVIL, "Access-Control-Request-Method": "POST", "Access-Control-Request-Headers": "X-CSRFToken"})
        granted = response.headers.get("Access-Control-Allow-Origin")
        assert granted in (None, ""), (method, path, granted)
        assert response.headers.get("Access-Control-Allow-Credentials") != "true"


def test_a_foreign_post_with_a_stolen_session_but_no_token_changes_nothing(app: Flask) -> None:
    deputy = logged_in(app, "deputy", OTHER_PW)
    before = users(app)
    for path, data in [("/settings/users/add", {"username": "mallory", "password": "mallory-pw1", "role": "admin"}),
                       ("/settings/users/carol/role", {"role": "admin"}),
                       ("/settings/users/carol/remove", {})]:
        response = deputy.post(path, data=data, headers={"Origin": EVIL, "Referer": EVIL + "/attack"})
        assert response.status_code in (400, 403), (path, response.status_code)
    assert users(app) == before


@pytest.mark.parametrize("path", ["/auth/login", "/auth/register", "/settings/users/add"])
def test_oversized_bodies_are_refused_before_any_handler(app: Flask, path: str) -> None:
    client = logged_in(app, "deputy", OTHER_PW)
    before = users(app)
    big = {"username": "x" * (2 * 1024 * 1024), "password": "p", "csrf_token": token_of(client, "/settings")}
    response = client.post(path, data=big)
    assert response.status_code == 413, (path, response.status_code)
    assert users(app) == before


@pytest.mark.parametrize("name", ["..", "..%2F..%2Fadmin", "admin%00", "%2e%2e", "ADMIN", "admin/../carol",
                                  "a" * 500])
def test_odd_names_in_user_urls_touch_nobody(app: Flask, name: str) -> None:
    deputy = logged_in(app, "deputy", OTHER_PW)
    token = token_of(deputy, "/settings")
    before = users(app)
    for action, data in (("role", {"role": "none"}), ("remove", {})):
        response = deputy.post(f"/settings/users/{name}/{action}", data={**data, "csrf_token": token})
        assert response.status_code in (302, 303, 400, 404, 405), (name, action, response.status_code)
    assert users(app) == before
