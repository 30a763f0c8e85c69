"""What keeps the dashboard closed: CSRF tokens, the login rate limit, role checks, the localhost rule.

Everything here works on the Flask session (signed cookie, HttpOnly, SameSite=Lax) and on an
injected clock, so the rate limit is tested by advancing a `SimClock`, never by sleeping.
"""

from __future__ import annotations

import functools
import hmac
import ipaddress
import secrets
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar, cast

from flask import abort, current_app, g, redirect, request, session, url_for
from werkzeug.wrappers import Response

from atemr.clock import Clock
from atemr.ui.users import Role, User, UserStore

F = TypeVar("F", bound=Callable[..., Any])

CSRF_SESSION_KEY = "csrf_token"
CSRF_FORM_FIELD = "csrf_token"
CSRF_HEADER = "X-CSRF-Token"
#: Methods that change something and so must carry the CSRF token.
UNSAFE_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})


# -- CSRF ---------------------------------------------------------------------------------------------
def csrf_token() -> str:
    """The session's CSRF token, created on first use; templates put it in every form."""
    token = session.get(CSRF_SESSION_KEY)
    if not isinstance(token, str):
        token = secrets.token_urlsafe(32)
        session[CSRF_SESSION_KEY] = token
    return token


def csrf_valid() -> bool:
    """True when the request carries the session's token in the form field or the header."""
    expected = session.get(CSRF_SESSION_KEY)
    given = request.form.get(CSRF_FORM_FIELD) or request.headers.get(CSRF_HEADER)
    return isinstance(expected, str) and isinstance(given, str) and hmac.compare_digest(expected, given)


def check_csrf() -> None:
    """``before_request`` hook: refuse (400) a state-changing request without the right token."""
    if request.method in UNSAFE_METHODS and not csrf_valid():
        abort(400, description="The form was stale or forged (CSRF token missing or wrong); reload the page.")


# -- login rate limit ---------------------------------------------------------------------------------
@dataclass
class LoginRateLimiter:
    """Counts failed logins per (username, address); ``max_failures`` within ``lockout_s`` locks that
    pair out until ``lockout_s`` after the last failure. Thread-safe; time comes from ``clock``."""

    clock: Clock
    max_failures: int = 5
    lockout_s: float = 300.0
    max_keys: int = 10_000
    _failures: dict[tuple[str, str], list[float]] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def _recent(self, key: tuple[str, str], now: float) -> list[float]:
        times = [t for t in self._failures.get(key, []) if now - t < self.lockout_s]
        if times:
            self._failures[key] = times
        else:
            self._failures.pop(key, None)
        return times

    def retry_after(self, username: str, address: str) -> float:
        """Seconds until this pair may try again; 0 when it is not locked out."""
        with self._lock:
            now = self.clock.now()
            times = self._recent((username.lower(), address), now)
            if len(times) < self.max_failures:
                return 0.0
            return max(0.0, times[-1] + self.lockout_s - now)

    def failed(self, username: str, address: str) -> None:
        """Record a failed attempt."""
        with self._lock:
            now = self.clock.now()
            key = (username.lower(), address)
            if len(self._failures) >= self.max_keys and key not in self._failures:
                # Bounded memory under a flood of invented names: forget the stalest pairs.
                for stale in sorted(self._failures, key=lambda k: self._failures[k][-1])[: self.max_keys // 10]:
                    del self._failures[stale]
            self._failures.setdefault(key, []).append(now)
            del self._failures[key][: -self.max_failures]

    def succeeded(self, username: str, address: str) -> None:
        """A correct password clears the pair's failures."""
        with self._lock:
            self._failures.pop((username.lower(), address), None)


# -- who is asking ------------------------------------------------------------------------------------
def is_local_address(address: str | None) -> bool:
    """True for loopback addresses (127.0.0.0/8, ::1): the first-start page is served only to these."""
    if not address:
        return False
    try:
        ip = ipaddress.ip_address(address.split("%", 1)[0])
    except ValueError:
        return False
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped  # ::ffff:127.0.0.1 from a dual-stack socket
    return ip.is_loopback


def user_store() -> UserStore:
    return cast(UserStore, current_app.extensions["atemr.users"])


def current_user() -> User | None:
    """The logged-in user (re-read from the database on every request, so a revoked role or a removed
    user takes effect at once), or None."""
    if "user" in g:
        return cast("User | None", g.user)
    name = session.get("user")
    user = user_store().get(name) if isinstance(name, str) else None
    if user is None and name is not None:
        session.pop("user", None)
    g.user = user
    return user


def login_user(user: User) -> None:
    """Start a fresh session for ``user`` (a new CSRF token too: no session fixation)."""
    session.clear()
    session["user"] = user.username
    session.permanent = True
    g.user = user
    csrf_token()


def logout_user() -> None:
    session.clear()
    g.user = None


def role_required(role: Role) -> Callable[[F], F]:
    """Route decorator: anonymous → login page (401 for JSON/API), role too low → no-access page (403)."""

    def decorate(view: F) -> F:
        @functools.wraps(view)
        def wrapped(*args: Any, **kwargs: Any) -> Any:
            user = current_user()
            wants_json = request.path.startswith("/api/") or request.accept_mimetypes.best == "application/json"
            if user is None:
                if wants_json:
                    abort(401)
                return redirect(url_for("auth.login", next=request.path))
            if not user.can(role):
                if wants_json:
                    abort(403)
                return html_response(
                    current_app.jinja_env.get_template("auth/no_access.html").render(
                        **_template_context(), user=user
                    ),
                    403,
                )
            return view(*args, **kwargs)

        return cast(F, wrapped)

    return decorate


def html_response(body: str, status: int, headers: dict[str, str] | None = None) -> Response:
    """A rendered page with a status other than 200 (a bare `Response` would be text/plain)."""
    return Response(body, status=status, headers=headers, mimetype="text/html")


def _template_context() -> dict[str, Any]:
    ctx: dict[str, Any] = {}
    current_app.update_template_context(ctx)
    return ctx
