"""Log in (remember the username), log out, create a user, the no-access page and the first start.

The first-start page sets the root admin's password; it is served only to loopback addresses, so
nobody on the network can claim a fresh robot. From elsewhere the page says how to do it on the console
(``atemr user set-password admin``).

Failed logins are limited per (username, address) and per address (``ui.login_max_failures`` and
``ui.login_max_failures_per_address`` within ``ui.login_lockout_s``); each try is counted before its
password is hashed. Creating a user answers the same whether the name was free or taken (nothing tells
which names exist) and is limited per address, every try counted.
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
    safe_next,
    user_store,
)
from atemr.ui.users import ROOT_USER, PasswordHashBusy, UserError, check_password, check_username

bp = Blueprint("auth", __name__, url_prefix="/auth", template_folder="templates")

REMEMBER_COOKIE = "atemr_username"
REMEMBER_DAYS = 30
#: Rate-limit key of registrations (the register limiter counts per address only).
REGISTER_KEY = " register"
#: What a registration answers, whether the name was free or taken.
REGISTERED = "Request received for {name}. An administrator must grant access before you can log in."


def _limiter() -> LoginRateLimiter:
    limiter: LoginRateLimiter = current_app.extensions["atemr.limiter"]
    return limiter


def _register_limiter() -> LoginRateLimiter:
    limiter: LoginRateLimiter = current_app.extensions["atemr.register_limiter"]
    return limiter


def _safe_next(target: str | None) -> str:
    """Only same-site relative paths as a post-login target (no open redirect); else the home page."""
    return safe_next(target) or url_for("control.page")


def _too_many(template: str, wait: float, **context: Any) -> Response:
    seconds = int(wait) + 1
    body = render_template(template, error=f"Too many attempts from here: try again in {seconds} s.", **context)
    return html_response(body, status=429, headers={"Retry-After": str(seconds)})


@bp.route("/login", methods=["GET", "POST"])
def login() -> Any:
    remembered = request.cookies.get(REMEMBER_COOKIE, "")
    if request.method == "GET":
        return render_template("auth/login.html", username=remembered, remember=bool(remembered))
    username = request.form.get("username", "").strip()
    password = request.form.get("password", "")
    remember = request.form.get("remember") == "on"
    address = request.remote_addr or "?"
    wait = _limiter().attempt(username, address)  # counted as a failure until the password is right
    if wait > 0:
        return _too_many("auth/login.html", wait, username=username, remember=remember)
    try:
        user = user_store().verify(username, password)
    except PasswordHashBusy:
        _limiter().forgive(username, address)  # never checked: not a failure
        raise
    if user is None:
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
    """End this session: its token is deleted (a replayed cookie is worth nothing) and its sockets close."""
    token = logout_user()
    if token is not None:
        sockets.disconnect_session(current_app._get_current_object(), token)  # type: ignore[attr-defined]
    return redirect(url_for("auth.login"))


@bp.route("/register", methods=["GET", "POST"])
def register() -> Any:
    """Ask for an account; new users have no access until an admin grants it.

    Whether the name was free or taken, the answer is the same (no list of names to probe), and every
    well-formed request from an address counts towards its limit (as many per lockout period as failed
    logins allowed per user)."""
    if request.method == "GET":
        return render_template("auth/register.html")
    username = request.form.get("username", "").strip()
    password = request.form.get("password", "")
    try:
        check_username(username)
        check_password(password)
    except UserError as exc:
        return html_response(render_template("auth/register.html", username=username, error=str(exc)), status=400)
    if password != request.form.get("confirm", ""):
        return html_response(render_template("auth/register.html", username=username,
                                             error="The two passwords differ."), status=400)
    # Anyone who can reach the page may register (thesis fig. 3.37), so each address gets only so many.
    address = request.remote_addr or "?"
    wait = _register_limiter().attempt(REGISTER_KEY, address)
    if wait > 0:
        return _too_many("auth/register.html", wait)
    try:
        user_store().create(username, password)
    except UserError:
        pass  # taken: say nothing that a free name would not get
    except PasswordHashBusy:
        _register_limiter().forgive(REGISTER_KEY, address)
        raise
    flash(REGISTERED.format(name=username), "ok")
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
