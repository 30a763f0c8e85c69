"""Destructive and safety actions need their permission: admin only by default, grantable to the user role
by ``ui.user_permissions``, refused with the reason and with nothing changed, shown read-only on the pages."""

from __future__ import annotations

import re

import pytest

from atemr.config import load_config
from atemr.errors import ConfigError
from atemr.ui.app import create_app
from atemr.ui.permissions import PERMISSIONS, role_may

# permission → how a browser asks for it: ("form", path, form data, gateway call) or ("event", name, payload, call)
ACTIONS = {
    "speed_limits": ("form", "/settings/limits", {"linear_mps": "0.8", "angular_radps": "1.2"}, "set_limits"),
    "awareness": ("form", "/settings/awareness", {"awareness": "on"}, "set_awareness"),
    "wifi": ("form", "/settings/wifi", {"ssid": "home", "password": "wifi-pass-1"}, "set_wifi"),
    "delete_all": ("form", "/media/images/delete-all", {}, None),
    "power": ("event", "sim_button", {"hold_s": 5.2}, "sim_button"),
    "agent_reload": ("event", "agent_reload", None, "reload_agent"),
}


def test_every_permission_has_a_way_to_be_asked_for():
    assert set(ACTIONS) == set(PERMISSIONS)


def images(app):
    return app.config["ATEMR_CONFIG"].data_dir / "media" / "images"


def ask(app, client, ui, permission, status=None):
    """Do ``permission``'s action as ``client``; returns the page text or the socket acknowledgement. A form
    answers ``status`` when given (403: refused on the page itself)."""
    kind, where, data, _call = ACTIONS[permission]
    if kind == "form":
        response = ui.post(client, where, data, follow_redirects=True)
        assert status is None or response.status_code == status, (where, response.status_code)
        return response.get_data(as_text=True)
    ws = app.extensions["socketio"].test_client(app, flask_test_client=client)
    try:
        return ws.emit(where, data, callback=True)
    finally:
        ws.disconnect()


@pytest.fixture
def with_images(app):
    images(app).mkdir(parents=True, exist_ok=True)
    (images(app) / "capture-00.jpg").write_bytes(b"\xff\xd8\xff\xd9")
    return app


@pytest.mark.parametrize("permission", PERMISSIONS)
def test_by_default_a_user_is_refused_with_the_reason_and_nothing_changes(with_images, alice, gateway, ui,
                                                                           permission):
    answer = ask(with_images, alice, ui, permission, status=403)
    reason = answer if isinstance(answer, str) else answer["reason"]
    assert "needs the admin role" in reason and f"ui.user_permissions: {permission}" in reason
    if not isinstance(answer, str):
        assert answer["ok"] is False and answer["status"] == 403
    assert gateway.calls == []
    assert (images(with_images) / "capture-00.jpg").exists()


@pytest.mark.parametrize("permission", PERMISSIONS)
def test_an_admin_may_do_each_action(with_images, admin, gateway, ui, permission):
    answer = ask(with_images, admin, ui, permission, status=200)
    call = ACTIONS[permission][3]
    if call is None:
        assert not (images(with_images) / "capture-00.jpg").exists()
    else:
        assert gateway.names() == [call]
    if not isinstance(answer, str):
        assert answer == {"ok": True, "reason": ""}


def test_a_granted_permission_lets_users_do_that_action_only(tmp_path, gateway, clock, ui):
    app = create_app(ui.make_config(tmp_path, user_permissions=("awareness",)), gateway, clock=clock,
                     hash_method=ui.FAST_SCRYPT)
    app.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    app.extensions["atemr.users"].create("alice", ui.USER_PW, "user")
    client = app.test_client()
    ui.login(client, "alice", ui.USER_PW)
    ask(app, client, ui, "awareness")
    page = ask(app, client, ui, "speed_limits")
    assert gateway.calls == [("set_awareness", (True,))]
    assert "change the speed limits needs the admin role" in page


def test_the_pages_show_what_a_user_may_not_do_as_read_only(with_images, alice, ui):
    settings = alice.get("/settings").get_data(as_text=True)
    for form in ("limits-form", "awareness-form", "wifi-form"):
        block = settings[settings.index(f'id="{form}"'):]
        assert re.match(r'[^>]*>\s*<fieldset disabled', block), f"{form} is not read-only for a user"
    assert settings.count("Read-only:") == 3
    assert "delete-all" not in alice.get("/media").get_data(as_text=True)
    control = alice.get("/control").get_data(as_text=True)
    assert re.search(r'id="sim-press-5s"[^>]*disabled', control)
    assert re.search(r'id="agent-reload"[^>]*disabled', alice.get("/agent").get_data(as_text=True))


def test_an_admin_sees_every_control_and_what_each_role_may_do(with_images, admin, ui):
    settings = admin.get("/settings").get_data(as_text=True)
    assert "<fieldset disabled" not in settings and "Read-only:" not in settings
    assert "delete-all" in admin.get("/media").get_data(as_text=True)
    assert not re.search(r'id="sim-press-5s"[^>]*disabled', admin.get("/control").get_data(as_text=True))
    table = settings[settings.index('id="role-permissions"'):settings.index("</table>", settings.index(
        'id="role-permissions"'))]
    rows = re.findall(r'<tr data-permission="(\w+)"><td>[^<]*</td><td>(\w*)</td><td>(\w*)</td><td>(\w*)</td>', table)
    assert [r[0] for r in rows] == list(PERMISSIONS)
    assert all(r[1:] == ("", "", "yes") for r in rows)  # by default: admin only


def test_the_role_names_are_the_same_in_the_users_table_and_the_add_user_form(admin):
    settings = admin.get("/settings").get_data(as_text=True)
    table = settings[settings.index('id="manage-users"'):settings.index('id="add-user-form"')]
    form = settings[settings.index('id="add-user-form"'):]
    labels = {re.sub(r"\s+", " ", x) for x in re.findall(r"<option[^>]*>([^<]+)</option>", table)}
    assert labels == {"no access", "user", "admin"}
    assert {x for x in re.findall(r"<option[^>]*>([^<]+)</option>", form)} == labels


def test_only_admin_and_granted_users_may():
    assert all(role_may("admin", p, ()) for p in PERMISSIONS)
    assert not any(role_may("user", p, ()) for p in PERMISSIONS)
    assert role_may("user", "wifi", ("wifi",)) and not role_may("user", "power", ("wifi",))
    assert not any(role_may("none", p, PERMISSIONS) for p in PERMISSIONS)


def test_an_unknown_permission_in_the_configuration_is_refused_with_its_key(tmp_path):
    with pytest.raises(ConfigError, match=r"ATEMR_UI__USER_PERMISSIONS.*'shutdown'"):
        load_config(None, environ={"ATEMR_UI__USER_PERMISSIONS": "wifi,shutdown"})
    config = load_config(None, environ={"ATEMR_UI__USER_PERMISSIONS": "wifi, awareness"})
    assert config.ui.user_permissions == ("wifi", "awareness")
