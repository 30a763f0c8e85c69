"""Settings page: own password, robot parameters through the gateway, user management by admins."""

from __future__ import annotations

import pytest


def test_page_shows_limits_from_the_robot(alice, ui):
    html = alice.get("/settings").get_data(as_text=True)
    assert 'value="0.5"' in html and 'value="1.0"' in html
    assert "Manage users" not in html  # not an admin


def test_speed_limits_go_to_the_gateway(admin, gateway, ui):
    response = ui.post(admin, "/settings/limits", {"linear_mps": "0.8", "angular_radps": "1.2"},
                       follow_redirects=True)
    assert ("set_limits", (0.8, 1.2)) in gateway.calls
    assert b"Speed limits: done" in response.data


@pytest.mark.parametrize(("linear", "angular"), [("fast", "1"), ("nan", "1"), ("0", "1"), ("2.5", "1"),
                                                 ("0.5", "-1"), ("0.5", "inf")])
def test_bad_speed_limits_never_reach_the_robot(admin, gateway, ui, linear, angular):
    response = ui.post(admin, "/settings/limits", {"linear_mps": linear, "angular_radps": angular},
                       follow_redirects=True)
    assert "set_limits" not in gateway.names()
    assert b"Speed limits: " in response.data and b"expected" in response.data


def test_robot_refusal_is_shown(admin, gateway, ui):
    gateway.refuse["set_limits"] = "the motors are in emergency"
    response = ui.post(admin, "/settings/limits", {"linear_mps": "0.8", "angular_radps": "1.2"},
                       follow_redirects=True)
    assert b"refused: the motors are in emergency" in response.data


def test_awareness_and_wifi(admin, gateway, ui):
    ui.post(admin, "/settings/awareness", {"awareness": "on"})
    ui.post(admin, "/settings/awareness", {})
    ui.post(admin, "/settings/wifi", {"ssid": "home", "password": "wifi-pass-1"})
    bad = ui.post(admin, "/settings/wifi", {"ssid": "home", "password": "short"}, follow_redirects=True)
    assert b"8-63 bytes" in bad.data
    ui.post(admin, "/settings/wifi", {"ssid": "x" * 33, "password": "wifi-pass-1"})
    assert gateway.calls == [("set_awareness", (True,)), ("set_awareness", (False,)),
                             ("set_wifi", ("home", "wifi-pass-1"))]


def test_change_own_password(alice, app, ui):
    wrong = ui.post(alice, "/settings/password", {"current": "nope", "new": "new-pass-1", "confirm": "new-pass-1"},
                    follow_redirects=True)
    assert b"current password is wrong" in wrong.data
    differ = ui.post(alice, "/settings/password", {"current": ui.USER_PW, "new": "new-pass-1", "confirm": "x"},
                     follow_redirects=True)
    assert b"differ" in differ.data
    ok = ui.post(alice, "/settings/password", {"current": ui.USER_PW, "new": "new-pass-1", "confirm": "new-pass-1"},
                 follow_redirects=True)
    assert b"Password changed" in ok.data
    store = app.extensions["atemr.users"]
    assert store.verify("alice", "new-pass-1") and not store.verify("alice", ui.USER_PW)


ADMIN_ROUTES = [("/settings/users/add", {"username": "x1", "password": "password1", "role": "user"}),
                ("/settings/users/bob/role", {"role": "user"}),
                ("/settings/users/bob/remove", {})]


@pytest.mark.parametrize(("path", "form"), ADMIN_ROUTES)
def test_user_management_is_for_admins_only(alice, app, ui, path, form):
    response = ui.post(alice, path, form)
    assert response.status_code == 403
    store = app.extensions["atemr.users"]
    assert store.get("x1") is None and store.get("bob").role == "none"


def test_admin_grants_and_revokes_access_and_admin(admin, app, ui):
    html = admin.get("/settings").get_data(as_text=True)
    assert "Manage users" in html and 'data-user="bob"' in html
    store = app.extensions["atemr.users"]
    ui.post(admin, "/settings/users/bob/role", {"role": "user"})
    assert store.get("bob").role == "user"
    ui.post(admin, "/settings/users/bob/role", {"role": "admin"})
    assert store.get("bob").role == "admin"
    ui.post(admin, "/settings/users/bob/role", {"role": "none"})
    assert store.get("bob").role == "none"
    bad = ui.post(admin, "/settings/users/bob/role", {"role": "god"}, follow_redirects=True)
    assert b"unknown role" in bad.data and store.get("bob").role == "none"


def test_admin_adds_and_removes_users(admin, app, ui):
    store = app.extensions["atemr.users"]
    ui.post(admin, "/settings/users/add", {"username": "carol", "password": "carol-pass", "role": "user"})
    assert store.get("carol").role == "user"
    dup = ui.post(admin, "/settings/users/add", {"username": "carol", "password": "carol-pass"},
                  follow_redirects=True)
    assert b"taken" in dup.data
    ui.post(admin, "/settings/users/carol/remove")
    assert store.get("carol") is None
    missing = ui.post(admin, "/settings/users/ghost/remove", follow_redirects=True)
    assert b"no user" in missing.data


def test_root_admin_can_be_neither_removed_nor_demoted_from_the_page(admin, app, ui):
    store = app.extensions["atemr.users"]
    store.set_role("alice", "admin")
    other = app.test_client()
    ui.login(other, "alice", ui.USER_PW)
    demote = ui.post(other, "/settings/users/admin/role", {"role": "none"}, follow_redirects=True)
    assert b"cannot be demoted" in demote.data
    remove = ui.post(other, "/settings/users/admin/remove", follow_redirects=True)
    assert b"cannot be removed" in remove.data
    assert store.get("admin").role == "admin"
    self_remove = ui.post(other, "/settings/users/alice/remove", follow_redirects=True)
    assert b"cannot remove yourself" in self_remove.data and store.get("alice") is not None


def test_without_a_robot_settings_are_refused_clearly(tmp_path, ui):
    from atemr.ui.app import create_app

    app = create_app(ui.make_config(tmp_path), None, hash_method=ui.FAST_SCRYPT)
    app.extensions["atemr.users"].create("alice", ui.USER_PW, "user")
    app.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    client = app.test_client()
    ui.login(client, "admin", ui.ADMIN_PW)
    assert b"No robot is connected" in client.get("/settings").data
    response = ui.post(client, "/settings/limits", {"linear_mps": "0.8", "angular_radps": "1.2"},
                       follow_redirects=True)
    assert b"no robot is connected" in response.data


def test_a_refused_form_shows_its_error_in_place_and_keeps_what_was_typed(admin, gateway, ui):
    bad = ui.post(admin, "/settings/limits", {"linear_mps": "fast", "angular_radps": "1.5"})
    page = bad.get_data(as_text=True)
    assert bad.status_code == 400 and 'id="limits-error"' in page and "expected a number" in page
    assert 'value="fast"' in page and 'value="1.5"' in page  # what was typed, not the robot's values
    wifi = ui.post(admin, "/settings/wifi", {"ssid": "Casa Ñandú", "password": "short"})
    page = wifi.get_data(as_text=True)
    assert wifi.status_code == 400 and 'id="wifi-error"' in page
    assert 'value="Casa Ñandú"' in page and "short" not in page.split('id="wifi-form"')[1].split("</form>")[0]
    gateway.refuse["set_awareness"] = "the robot is mapping"
    refused = ui.post(admin, "/settings/awareness", {"awareness": "on"})
    assert refused.status_code == 409 and "Awareness on: refused: the robot is mapping" in refused.get_data(
        as_text=True)
    user = ui.post(admin, "/settings/users/add", {"username": "carer one", "password": "pass-word-1", "role": "user"})
    page = user.get_data(as_text=True)
    assert user.status_code == 400 and 'id="add-user-error"' in page
    assert 'value="carer one"' in page and '<option value="user" selected>' in page and "pass-word-1" not in page
    assert gateway.names() == ["set_awareness"]
