"""Login, logout, create user, no-access, first start, CSRF, rate limit, cookies, role checks."""

from __future__ import annotations

import pytest


def test_fresh_robot_sends_every_page_to_first_start(fresh_app, ui):
    client = fresh_app.test_client()
    for path in ("/", "/control", "/auth/login", "/settings", "/media"):
        response = client.get(path)
        assert response.status_code == 302 and response.location.endswith("/auth/first-start"), path


def test_first_start_sets_the_admin_password_from_localhost(fresh_app, ui):
    client = fresh_app.test_client()
    page = client.get("/auth/first-start")
    assert page.status_code == 200 and b"no administrator password" in page.data
    token = ui.csrf_of(client, "/auth/first-start")
    bad = client.post("/auth/first-start", data={"password": "abcdefgh", "confirm": "abcdefgX", "csrf_token": token})
    assert bad.status_code == 400 and b"differ" in bad.data
    short = client.post("/auth/first-start", data={"password": "abc", "confirm": "abc", "csrf_token": token})
    assert short.status_code == 400
    ok = client.post("/auth/first-start", data={"password": ui.ADMIN_PW, "confirm": ui.ADMIN_PW, "csrf_token": token})
    assert ok.status_code == 302 and ok.location.endswith("/control")
    assert client.get("/control").status_code == 200  # logged in as admin
    assert fresh_app.extensions["atemr.users"].verify("admin", ui.ADMIN_PW) is not None
    # once set, the page is gone
    assert client.get("/auth/first-start").location.endswith("/auth/login")


def test_first_start_is_refused_from_another_host(fresh_app, ui):
    client = fresh_app.test_client()
    remote = {"REMOTE_ADDR": "192.168.1.20"}
    page = client.get("/auth/first-start", environ_base=remote)
    assert page.status_code == 403 and b"atemr user set-password admin" in page.data
    token = ui.csrf_of(client, "/auth/first-start")  # from localhost, but then posting from afar
    form = {"password": ui.ADMIN_PW, "confirm": ui.ADMIN_PW, "csrf_token": token}
    response = client.post("/auth/first-start", data=form, environ_base=remote)
    assert response.status_code == 403
    assert fresh_app.extensions["atemr.users"].needs_root_password()


def test_login_logout_and_session_cookie_flags(client, ui):
    response = ui.login(client, "alice", ui.USER_PW)
    assert response.status_code == 302 and response.location.endswith("/control")
    cookie = response.headers.getlist("Set-Cookie")
    session_cookie = next(c for c in cookie if c.startswith("atemr_session="))
    assert "HttpOnly" in session_cookie and "SameSite=Lax" in session_cookie
    assert client.get("/control").status_code == 200
    out = ui.post(client, "/auth/logout")
    assert out.status_code == 302 and out.location.endswith("/auth/login")
    assert client.get("/control").status_code == 302


def test_remember_username_cookie(client, ui):
    token = ui.csrf_of(client)
    response = client.post("/auth/login", data={"username": "alice", "password": ui.USER_PW, "remember": "on",
                                                "csrf_token": token})
    remembered = [c for c in response.headers.getlist("Set-Cookie") if c.startswith("atemr_username=alice")]
    assert remembered and "HttpOnly" in remembered[0]
    ui.post(client, "/auth/logout")
    page = client.get("/auth/login").get_data(as_text=True)
    assert 'value="alice"' in page and "checked" in page


def test_wrong_password_and_unknown_user(client, ui):
    wrong = ui.login(client, "alice", "nope-nope")
    assert wrong.status_code == 401 and wrong.mimetype == "text/html" and b"Wrong username" in wrong.data
    assert ui.login(client, "mallory", "whatever1").status_code == 401
    assert client.get("/control").status_code == 302


def test_user_without_access_gets_the_no_access_page_and_no_session(client, ui):
    response = ui.login(client, "bob", ui.USER_PW)
    assert response.status_code == 403 and b"No access" in response.data
    assert client.get("/control").status_code == 302
    assert client.get("/auth/no-access").status_code == 403


def test_open_redirect_is_refused(client, ui):
    token = ui.csrf_of(client)
    response = client.post("/auth/login?next=//evil.example/x",
                           data={"username": "alice", "password": ui.USER_PW, "csrf_token": token})
    assert response.location.endswith("/control")
    client2 = client.application.test_client()
    token = ui.csrf_of(client2)
    response = client2.post("/auth/login?next=/settings",
                            data={"username": "alice", "password": ui.USER_PW, "csrf_token": token})
    assert response.location.endswith("/settings")


def test_rate_limit_after_repeated_failures_per_user_and_address(client, clock, ui):
    for _ in range(3):
        assert ui.login(client, "alice", "wrong-pass").status_code == 401
    locked = ui.login(client, "alice", ui.USER_PW)  # even the right password waits
    assert locked.status_code == 429 and int(locked.headers["Retry-After"]) > 0
    # another address is not locked out, nor another username from this address
    token = ui.csrf_of(client)
    other = client.post("/auth/login", data={"username": "alice", "password": ui.USER_PW, "csrf_token": token},
                        environ_base={"REMOTE_ADDR": "10.0.0.7"})
    assert other.status_code == 302
    ui.post(client, "/auth/logout")
    assert ui.login(client, "admin", ui.ADMIN_PW).status_code == 302
    ui.post(client, "/auth/logout")
    clock.advance(61.0)
    assert ui.login(client, "alice", ui.USER_PW).status_code == 302


def test_a_success_clears_the_failures(client, clock, ui):
    for _ in range(2):
        ui.login(client, "alice", "wrong-pass")
    assert ui.login(client, "alice", ui.USER_PW).status_code == 302
    ui.post(client, "/auth/logout")
    for _ in range(2):
        assert ui.login(client, "alice", "wrong-pass").status_code == 401


def test_every_form_post_needs_the_csrf_token(alice, ui):
    for path in ("/auth/logout", "/settings/limits", "/settings/password", "/auth/register", "/mapping/upload",
                 "/media/images/delete-all"):
        assert alice.post(path, data={}).status_code == 400, path
        assert alice.post(path, data={"csrf_token": "forged"}).status_code == 400, path
    assert alice.get("/control").status_code == 200  # still logged in: nothing happened


def test_csrf_token_in_a_header_is_accepted(alice, ui):
    token = ui.csrf_of(alice, "/control")
    assert alice.post("/auth/logout", headers={"X-CSRF-Token": token}).status_code == 302


def test_register_creates_a_user_without_access(client, app, ui):
    token = ui.csrf_of(client, "/auth/register")
    response = client.post("/auth/register", data={"username": "carol", "password": "carol-pass",
                                                   "confirm": "carol-pass", "csrf_token": token})
    assert response.status_code == 302
    assert app.extensions["atemr.users"].get("carol").role == "none"
    assert ui.login(client, "carol", "carol-pass").status_code == 403


@pytest.mark.parametrize(("form", "message"), [
    ({"username": "x y", "password": "password1", "confirm": "password1"}, b"username"),
    ({"username": "dan", "password": "short", "confirm": "short"}, b"password"),
    ({"username": "dan", "password": "password1", "confirm": "password2"}, b"differ"),
])
def test_register_refusals(client, form, message, ui):
    token = ui.csrf_of(client, "/auth/register")
    response = client.post("/auth/register", data={**form, "csrf_token": token})
    assert response.status_code == 400 and message in response.data


PAGES = ["/control", "/mapping", "/settings", "/media", "/api/state", "/api/map", "/api/media/images"]


@pytest.mark.parametrize("path", PAGES)
def test_anonymous_is_sent_to_login_or_401(client, path, ui):
    response = client.get(path)
    if path.startswith("/api/"):
        assert response.status_code == 401
    else:
        assert response.status_code == 302 and "/auth/login" in response.location


def test_a_role_change_while_logged_in_ends_the_session_at_once(alice, app, ui):
    assert alice.get("/control").status_code == 200
    app.extensions["atemr.users"].set_role("alice", "none")
    response = alice.get("/control")
    assert response.status_code == 302 and "/auth/login" in response.location
    assert alice.get("/api/state").status_code == 401
    app.extensions["atemr.users"].set_role("alice", "user")  # access back: the old session stays ended
    assert alice.get("/api/state").status_code == 401
    assert ui.login(alice, "alice", ui.USER_PW).status_code == 302
    assert alice.get("/api/state").status_code == 200
    app.extensions["atemr.users"].remove("alice")
    assert alice.get("/control").status_code == 302


def test_status_bar_on_every_page(admin, ui):
    for path in ("/control", "/mapping", "/settings", "/media"):
        html = admin.get(path).get_data(as_text=True)
        assert 'id="sock"' in html and 'id="agent-state"' in html and 'id="emergency"' in html, path
        assert '<span id="username">admin</span>' in html, path


def test_secret_key_generated_once_and_private(tmp_path, gateway, ui):
    from atemr.ui.app import create_app

    config = ui.make_config(tmp_path)
    a = create_app(config, gateway, hash_method=ui.FAST_SCRYPT)
    b = create_app(config, gateway, hash_method=ui.FAST_SCRYPT)
    key_file = config.data_dir / "ui.key"
    assert key_file.stat().st_mode & 0o077 == 0
    assert a.secret_key == b.secret_key and len(a.secret_key) >= 32


def test_too_short_secret_key_file_is_a_config_error(tmp_path, gateway, ui):
    from atemr.errors import ConfigError
    from atemr.ui.app import create_app

    config = ui.make_config(tmp_path)
    config.data_dir.mkdir(parents=True)
    (config.data_dir / "ui.key").write_bytes(b"short")
    with pytest.raises(ConfigError, match=r"ui\.key.*delete it"):
        create_app(config, gateway)


def test_security_headers_on_every_response(client, ui):
    for path in ("/auth/login", "/static/js/socket.js", "/control"):
        response = client.get(path)
        response.close()
        csp = response.headers["Content-Security-Policy"]
        assert "script-src 'self'" in csp and "frame-ancestors 'none'" in csp and "unsafe-inline" not in csp
        assert response.headers["X-Frame-Options"] == "DENY"
        assert response.headers["X-Content-Type-Options"] == "nosniff"


def test_templates_have_no_inline_script_or_handlers(ui):
    import re
    from pathlib import Path

    import atemr.ui

    root = Path(atemr.ui.__file__).parent
    for template in root.rglob("*.html"):
        text = template.read_text()
        assert not re.search(r"<script>|\son[a-z]+=|style=", text), template


def test_registrations_per_address_are_limited(client, app, clock, ui):
    def register(name, addr="10.1.1.1"):
        token = ui.csrf_of(client, "/auth/register")
        form = {"username": name, "password": "password1", "confirm": "password1", "csrf_token": token}
        return client.post("/auth/register", data=form, environ_base={"REMOTE_ADDR": addr})

    for i in range(3):  # login_max_failures=3 in the test app
        assert register(f"new{i}").status_code == 302
    refused = register("new3")
    assert refused.status_code == 429 and "Retry-After" in refused.headers
    assert app.extensions["atemr.users"].get("new3") is None
    assert register("other", addr="10.1.1.2").status_code == 302
    clock.advance(61.0)
    assert register("new3").status_code == 302
