"""The Settings page: robot parameters (WiFi, speed limits, awareness) through the gateway, the current
user's password, and for admins the user management (grant/revoke access and admin, add, remove)."""

from __future__ import annotations

import math
from typing import Any, cast

from flask import Blueprint, current_app, flash, make_response, redirect, render_template, request, url_for
from werkzeug.wrappers import Response

from atemr.ui import sockets
from atemr.ui.gateway import NO_ROBOT, CommandResult, RobotGateway
from atemr.ui.permissions import PERMISSION_LABELS, PERMISSIONS, ROLE_LABELS, ROLES, role_may
from atemr.ui.security import (
    current_user,
    login_user,
    permission_required,
    role_required,
    user_permissions,
    user_store,
)
from atemr.ui.state import RobotState
from atemr.ui.users import UserError

bp = Blueprint("settings", __name__, url_prefix="/settings", template_folder="templates")

#: What the form accepts; the robot refuses anything above its own hardware limits.
MAX_LINEAR_MPS = 1.8
MAX_ANGULAR_RADPS = 4.0


def _gateway() -> RobotGateway | None:
    return cast("RobotGateway | None", current_app.extensions["atemr.gateway"])


def _back() -> Response:
    return redirect(url_for("settings.page"))


#: Form fields never sent back into the page after an error (what was typed there is a secret).
SECRET_FIELDS = frozenset({"password", "current", "new", "confirm", "csrf_token"})


def _page(status: int = 200, *, form: str | None = None, error: str | None = None) -> Response:
    """The Settings page; after a refused form, with the reason beside that form (``form``: its id stem) and
    what was typed kept in it (passwords excepted), answered with ``status``."""
    robot = _gateway()
    state: RobotState | dict[str, Any] = robot.state() if robot else {}  # no robot: every field shows "—"
    user = current_user()
    users = user_store().list() if user is not None and user.can("admin") else []
    granted = user_permissions()
    typed = {k: v for k, v in request.form.items() if k not in SECRET_FIELDS} if form else {}
    html = render_template("settings/settings.html", state=state, users=users, roles=ROLES,
                           connected=robot is not None, role_labels=ROLE_LABELS, permissions=PERMISSIONS,
                           permission_labels=PERMISSION_LABELS,
                           role_may=lambda role, permission: role_may(role, permission, granted),
                           errors={form: error} if form and error else {}, typed=typed, typed_form=form)
    return make_response(html, status)


def _report(form: str, what: str, result: CommandResult) -> Response:
    """Done: back to the page with the news; refused by the robot: the reason beside the form (409)."""
    if not result.ok:
        return _page(409, form=form, error=f"{what}: refused: {result.reason}")
    flash(f"{what}: done", "ok")
    return _back()


@bp.route("")
@role_required("user")
def page() -> Response:
    return _page()


def _form_number(key: str, hi: float) -> float:
    raw = request.form.get(key, "").strip()
    try:
        value = float(raw)
    except ValueError:
        raise UserError(f"{key.replace('_', ' ')}: expected a number, got {raw!r}") from None
    if not math.isfinite(value) or not 0.0 < value <= hi:
        raise UserError(f"{key.replace('_', ' ')}: expected a value in (0, {hi}], got {raw}")
    return value


@bp.route("/limits", methods=["POST"])
@permission_required("speed_limits", back="settings.page")
def limits() -> Response:
    """Linear and angular speed limits, applied by the robot at once (no restart)."""
    try:
        linear = _form_number("linear_mps", MAX_LINEAR_MPS)
        angular = _form_number("angular_radps", MAX_ANGULAR_RADPS)
    except UserError as exc:
        return _page(400, form="limits", error=f"Speed limits: {exc}")
    robot = _gateway()
    return _report("limits", "Speed limits", robot.set_limits(linear, angular) if robot else NO_ROBOT)


@bp.route("/awareness", methods=["POST"])
@permission_required("awareness", back="settings.page")
def awareness() -> Response:
    robot = _gateway()
    on = request.form.get("awareness") == "on"
    return _report("awareness", f"Awareness {'on' if on else 'off'}", robot.set_awareness(on) if robot else NO_ROBOT)


@bp.route("/wifi", methods=["POST"])
@permission_required("wifi", back="settings.page")
def wifi() -> Response:
    """SSID 1-32 bytes, password 8-63 bytes (what the secondary core's transfer accepts too)."""
    ssid = request.form.get("ssid", "")
    password = request.form.get("password", "")
    if not 1 <= len(ssid.encode()) <= 32 or not 8 <= len(password.encode()) <= 63:
        return _page(400, form="wifi", error="WiFi: the SSID has 1-32 bytes and the password 8-63 bytes.")
    robot = _gateway()
    return _report("wifi", "WiFi", robot.set_wifi(ssid, password) if robot else NO_ROBOT)


@bp.route("/password", methods=["POST"])
@role_required("user")
def password() -> Response:
    """Change one's own password (the current one is asked again)."""
    user = current_user()
    assert user is not None
    store = user_store()
    if store.verify(user.username, request.form.get("current", "")) is None:
        return _page(400, form="password", error="Password: the current password is wrong.")
    if request.form.get("new", "") != request.form.get("confirm", ""):
        return _page(400, form="password", error="Password: the two new passwords differ.")
    try:
        store.set_password(user.username, request.form.get("new", ""))  # ends every session of the user
    except UserError as exc:
        return _page(400, form="password", error=f"Password: {exc}")
    sockets.disconnect_user(current_app._get_current_object(), user.username)  # type: ignore[attr-defined]
    login_user(user)  # this browser goes on in a fresh session; every other one is logged out
    flash("Password changed. Every other session of yours is logged out.", "ok")
    return _back()


@bp.route("/users/add", methods=["POST"])
@role_required("admin")
def add_user() -> Response:
    role = request.form.get("role", "none")
    try:
        if role not in ROLES:
            raise UserError(f"unknown role {role!r}")
        user_store().create(request.form.get("username", "").strip(), request.form.get("password", ""),
                            role)
    except UserError as exc:
        return _page(400, form="add-user", error=f"Add user: {exc}")
    flash(f"User {request.form.get('username', '').strip()} added.", "ok")
    return _back()


@bp.route("/users/<username>/role", methods=["POST"])
@role_required("admin")
def set_role(username: str) -> Response:
    role = request.form.get("role", "")
    try:
        if role not in ROLES:
            raise UserError(f"unknown role {role!r}")
        user_store().set_role(username, role)
    except UserError as exc:
        flash(f"Role of {username}: {exc}", "error")
        return _back()
    sockets.disconnect_user(current_app._get_current_object(), username)  # type: ignore[attr-defined]
    flash(f"{username} is now {role}.", "ok")
    return _back()


@bp.route("/users/<username>/remove", methods=["POST"])
@role_required("admin")
def remove_user(username: str) -> Any:
    user = current_user()
    if user is not None and user.username == username:
        flash("Remove user: you cannot remove yourself.", "error")
        return _back()
    try:
        user_store().remove(username)
    except UserError as exc:
        flash(f"Remove {username}: {exc}", "error")
        return _back()
    sockets.disconnect_user(current_app._get_current_object(), username)  # type: ignore[attr-defined]
    flash(f"User {username} removed.", "ok")
    return _back()
