"""Log in (remember the username), log out, create a user, the no-access page and the first start.

The first-start page sets the root admin's password; it is served only to loopback addresses, so
nobody on the network can claim a fresh robot. From elsewhere the page says how to do it on the console
(``atemr user set-password admin``).
"""

from __future__ import annotations

from typing import Any

from flask import (
    Blueprint,
    current_app,
    flash,
    redirect,
    render_template,
    request,
    url_for,
)
from werkzeug.wrappers import Response

from atemr.ui import sockets
from atemr.ui.security import (
    LoginRateLimiter,
    current_user,
    html_response,
    is_local_address,
    login_user,
    logout_user,
    user_store,
)
from atemr.ui.users import ROOT_USER, UserError

bp = Blueprint("auth", __name__, url_prefix="/auth", template_folder="templates")

REMEMBER_COOKIE = "atemr_username"
REMEMBER_DAYS = 30
#: Rate-limit key of registrations (not a valid username, so it never collides with a login).
REGISTER_KEY = " register"


def _limiter() -> LoginRateLimiter:
    limiter: LoginRateLimiter = current_app.extensions["atemr.limiter"]
    return limiter


def _safe_next(target: str | None) -> str:
    """Only same-site relative paths as a post-login target (no open redirect)."""
    if target and target.startswith("/") and not target.startswith("//") and "\\" not in target:
        return target
    return url_for("control.page")


@bp.route("/login", methods=["GET", "POST"])
def login() -> Any:
    remembered = request.cookies.get(REMEMBER_COOKIE, "")
    if request.method == "GET":
        return render_template("auth/login.html", username=remembered, remember=bool(remembered))
    username = request.form.get("username", "").strip()
    password = request.form.get("password", "")
    remember = request.form.get("remember") == "on"
    address = request.remote_addr or "?"
    wait = _limiter().retry_after(username, address)
    if wait > 0:
        body = render_template(
            "auth/login.html", username=username, remember=remember,
            error=f"Too many failed attempts: try again in {int(wait) + 1} s.",
        )
        return html_response(body, status=429, headers={"Retry-After": str(int(wait) + 1)})
    user = user_store().verify(username, password)
    if user is None:
        _limiter().failed(username, address)
        body = render_template("auth/login.html", username=username, remember=remember,
                               error="Wrong username or password.")
        return html_response(body, status=401)
    _limiter().succeeded(username, address)
    if not user.can("user"):
        # Log-in is denied: the account exists but has no access yet (thesis fig. 3.38).
        return html_response(render_template("auth/no_access.html", user=user), status=403)
    login_user(user)
    response = redirect(_safe_next(request.args.get("next")))
    if remember:
        response.set_cookie(REMEMBER_COOKIE, username, max_age=REMEMBER_DAYS * 86400, httponly=True,
                            samesite="Lax")
    else:
        response.delete_cookie(REMEMBER_COOKIE)
    return response


@bp.route("/logout", methods=["POST"])
def logout() -> Response:
    user = current_user()
    logout_user()
    if user is not None:
        sockets.disconnect_user(current_app._get_current_object(), user.username)  # type: ignore[attr-defined]
    return redirect(url_for("auth.login"))


@bp.route("/register", methods=["GET", "POST"])
def register() -> Any:
    """Create a user; new users have no access until an admin grants it."""
    if request.method == "GET":
        return render_template("auth/register.html")
    # Anyone who can reach the page may register (thesis fig. 3.37), so one address gets only as many
    # new accounts per lockout period as it gets failed logins.
    address = request.remote_addr or "?"
    wait = _limiter().retry_after(REGISTER_KEY, address)
    if wait > 0:
        return html_response(render_template("auth/register.html", error=f"Too many new users from this address: "
                                             f"try again in {int(wait) + 1} s."), status=429,
                             headers={"Retry-After": str(int(wait) + 1)})
    username = request.form.get("username", "").strip()
    password = request.form.get("password", "")
    if password != request.form.get("confirm", ""):
        return html_response(render_template("auth/register.html", username=username,
                                        error="The two passwords differ."), status=400)
    try:
        user_store().create(username, password)
    except UserError as exc:
        return html_response(render_template("auth/register.html", username=username, error=str(exc)), status=400)
    _limiter().failed(REGISTER_KEY, address)
    flash(f"User {username} created. An administrator must grant access before you can log in.", "ok")
    return redirect(url_for("auth.login"))


@bp.route("/no-access")
def no_access() -> Response:
    return html_response(render_template("auth/no_access.html", user=current_user()), status=403)


@bp.route("/first-start", methods=["GET", "POST"])
def first_start() -> Any:
    """Set the root admin's password on a fresh robot, from the robot itself (localhost) only."""
    store = user_store()
    if not store.needs_root_password():
        return redirect(url_for("auth.login"))
    if not is_local_address(request.remote_addr):
        return html_response(render_template("auth/first_start.html", local=False), status=403)
    if request.method == "GET":
        return render_template("auth/first_start.html", local=True)
    password = request.form.get("password", "")
    if password != request.form.get("confirm", ""):
        return html_response(render_template("auth/first_start.html", local=True, error="The two passwords differ."),
                        status=400)
    try:
        store.set_password(ROOT_USER, password)
    except UserError as exc:
        return html_response(render_template("auth/first_start.html", local=True, error=str(exc)), status=400)
    root = store.get(ROOT_USER)
    assert root is not None
    login_user(root)
    flash("The admin password is set. Keep it safe: there is no default to fall back to.", "ok")
    return redirect(url_for("control.page"))
