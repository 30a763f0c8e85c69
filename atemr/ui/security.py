"""What keeps the dashboard closed: CSRF tokens, the login rate limit, sessions, role checks, the
localhost rule, the trusted host names and safe post-login targets.

Everything here works on the Flask session (signed cookie, HttpOnly, SameSite=Lax) and on an
injected clock, so the rate limit is tested by advancing a `SimClock`, never by sleeping.
"""

from __future__ import annotations

import functools
import hmac
import ipaddress
import logging
import secrets
import threading
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import Any, TypeVar, cast
from urllib.parse import urlsplit

from flask import abort, current_app, flash, g, make_response, redirect, request, session, url_for
from werkzeug.wrappers import Response

from atemr.clock import Clock
from atemr.ui.permissions import PERMISSION_LABELS, Permission, Role, needed_role
from atemr.ui.screens import ScreenStore
from atemr.ui.users import User, UserStore

log = logging.getLogger(__name__)

F = TypeVar("F", bound=Callable[..., Any])

CSRF_SESSION_KEY = "csrf_token"
CSRF_FORM_FIELD = "csrf_token"
CSRF_HEADER = "X-CSRF-Token"
#: The session key holding the session token (the users database knows which are live).
SESSION_KEY = "sid"
#: The session key holding a screen's device token (`atemr.ui.screens`); a session holds it or a login, never both.
SCREEN_KEY = "screen"
#: Why a screen's session is refused an operator's page or event.
SCREEN_ONLY = "a screen device token opens only the robot's screen page and its events"
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
    """Counts failed logins per (username, address) and per address alone.

    ``max_failures`` within ``lockout_s`` lock that pair out, and ``max_failures_per_address`` (None: no
    such limit) lock the whole address out (random usernames from one address), each until ``lockout_s``
    after the last failure. `attempt` checks and counts in one step, before the password is hashed, so
    concurrent tries cannot outrun the limit; a correct password (`succeeded`) or a try that was never
    checked (`forgive`) takes its count back. Thread-safe; time comes from ``clock``; memory is bounded
    (``max_keys`` pairs and addresses).
    """

    clock: Clock
    max_failures: int = 5
    lockout_s: float = 300.0
    max_failures_per_address: int | None = None
    max_keys: int = 10_000
    _failures: dict[tuple[str, str], list[float]] = field(default_factory=dict)
    _by_address: dict[str, list[float]] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def _recent(self, table: dict[Any, list[float]], key: Any, now: float) -> list[float]:
        times = [t for t in table.get(key, []) if now - t < self.lockout_s]
        if times:
            table[key] = times
        else:
            table.pop(key, None)
        return times

    def _wait(self, username: str, address: str, now: float) -> float:
        wait = 0.0
        times = self._recent(self._failures, (username.lower(), address), now)
        if len(times) >= self.max_failures:
            wait = times[-1] + self.lockout_s - now
        if self.max_failures_per_address is not None:
            times = self._recent(self._by_address, address, now)
            if len(times) >= self.max_failures_per_address:
                wait = max(wait, times[-1] + self.lockout_s - now)
        return max(0.0, wait)

    def retry_after(self, username: str, address: str) -> float:
        """Seconds until this pair may try again; 0 when neither it nor its address is locked out."""
        with self._lock:
            return self._wait(username, address, self.clock.now())

    def attempt(self, username: str, address: str) -> float:
        """Check and count one try at once: 0 when it may go ahead (counted as a failure until
        `succeeded` or `forgive`), else the seconds to wait (nothing counted)."""
        with self._lock:
            now = self.clock.now()
            wait = self._wait(username, address, now)
            if wait <= 0.0:
                self._record(username, address, now)
            return wait

    @staticmethod
    def _append(table: dict[Any, list[float]], key: Any, now: float, keep: int, max_keys: int) -> None:
        if len(table) >= max_keys and key not in table:
            # Bounded memory under a flood of invented names: forget the stalest entries.
            for stale in sorted(table, key=lambda k: table[k][-1])[: max_keys // 10]:
                del table[stale]
        table.setdefault(key, []).append(now)
        del table[key][:-keep]

    def _record(self, username: str, address: str, now: float) -> None:
        self._append(self._failures, (username.lower(), address), now, self.max_failures, self.max_keys)
        if self.max_failures_per_address is not None:
            self._append(self._by_address, address, now, self.max_failures_per_address, self.max_keys)

    def failed(self, username: str, address: str) -> None:
        """Record a failed attempt."""
        with self._lock:
            self._record(username, address, self.clock.now())

    def forgive(self, username: str, address: str) -> None:
        """Take back the newest count of this pair and its address (a try that was never checked)."""
        with self._lock:
            self._take_back(self._failures, (username.lower(), address))
            self._take_back(self._by_address, address)

    @staticmethod
    def _take_back(table: dict[Any, list[float]], key: Any) -> None:
        times = table.get(key)
        if times:
            times.pop()
            if not times:
                del table[key]

    def succeeded(self, username: str, address: str) -> None:
        """A correct password clears the pair's failures and takes back this try's count of the address
        (its older failures stay: one known password does not reset the address)."""
        with self._lock:
            self._failures.pop((username.lower(), address), None)
            self._take_back(self._by_address, address)


# -- which host names this dashboard answers to (DNS rebinding) ------------------------------------------
#: Always trusted: this machine.
LOCAL_HOSTS = ("localhost", "127.0.0.1", "::1")
#: Listening addresses that mean "every interface".
WILDCARD_HOSTS = frozenset({"", "0.0.0.0", "::"})


def normalize_host(name: str) -> str | None:
    """``name`` (a host name or address, IPv6 with or without brackets, no port) in one spelling: lower
    case, no trailing dot, addresses in their compressed form; None if it is not a plausible host."""
    name = name.strip().lower().removesuffix(".")
    if name.startswith("[") and name.endswith("]"):
        name = name[1:-1]
    try:
        return ipaddress.ip_address(name).compressed
    except ValueError:
        pass
    if not name or len(name) > 253 or not all(c.isalnum() or c in "-." for c in name) or not name.isascii():
        return None
    return name


def host_of(header: str) -> str | None:
    """The host of a ``Host`` header (``name``, ``name:port``, ``[v6]:port``), normalized; None if malformed."""
    header = header.strip()
    if header.startswith("["):
        end = header.find("]")
        if end < 0:
            return None
        host, rest = header[: end + 1], header[end + 1:]
    else:
        host, _, port = header.partition(":")
        rest = f":{port}" if port or header.endswith(":") else ""
    if rest and not (rest.startswith(":") and rest[1:].isdigit() and 0 < int(rest[1:]) < 65536):
        return None
    return normalize_host(host)


def machine_hosts() -> set[str]:
    """This machine's names and interface addresses (trusted when the dashboard listens on every
    interface: that is how the robot is reached on its own network)."""
    import socket

    import psutil

    names = {socket.gethostname()}
    names |= {f"{n}.local" for n in names if "." not in n}
    try:
        for addresses in psutil.net_if_addrs().values():
            names.update(a.address for a in addresses if a.family in (socket.AF_INET, socket.AF_INET6))
    except OSError:
        pass
    return {h for h in map(normalize_host, names) if h}


def trusted_hosts(host: str, extra: Collection[str] = ()) -> frozenset[str]:
    """The host names the dashboard answers to: this machine (localhost, 127.0.0.1, ::1), the listening
    address ``host`` (every name and address of the machine when that is a wildcard such as 0.0.0.0), and
    ``extra`` (``ui.trusted_hosts``: the names a reverse proxy or the robot's network use)."""
    hosts = {h for h in map(normalize_host, LOCAL_HOSTS) if h}
    if host.strip() in WILDCARD_HOSTS:
        hosts |= machine_hosts()
    elif (name := normalize_host(host)) is not None:
        hosts.add(name)
    hosts |= {h for h in map(normalize_host, extra) if h}
    return frozenset(hosts)


class TrustedHostMiddleware:
    """WSGI middleware in front of everything (pages, Socket.IO, static files): a request whose ``Host``
    is not one of ``hosts`` gets 400, so a page on another name that resolves to this robot (DNS rebinding)
    cannot talk to it. A request without a ``Host`` (HTTP/1.0, never a browser) passes."""

    BODY = b"Bad Request: this dashboard does not answer to that host name (see ui.trusted_hosts).\n"

    def __init__(self, app: Any, hosts: Collection[str]) -> None:
        self.app = app
        self.hosts = frozenset(hosts)

    def __call__(self, environ: dict[str, Any], start_response: Any) -> Any:
        header = environ.get("HTTP_HOST")
        if header is None or host_of(header) in self.hosts:
            return self.app(environ, start_response)
        start_response("400 Bad Request", [("Content-Type", "text/plain; charset=utf-8"),
                                           ("Content-Length", str(len(self.BODY))), ("Connection", "close")])
        return [self.BODY]


# -- where to go after logging in -----------------------------------------------------------------------
def safe_next(target: str | None) -> str | None:
    """``target`` if it is a path on this site (``/...``: printable ASCII, no backslash, no scheme or host
    however it is spelled), else None (the caller goes home)."""
    if not target or not target.startswith("/") or target.startswith("//"):
        return None
    if not all(32 < ord(c) < 127 for c in target) or "\\" in target:
        return None  # control characters, spaces, non-ASCII: browsers drop or rewrite them
    parts = urlsplit(target)
    if parts.scheme or parts.netloc or not parts.path.startswith("/") or parts.path.startswith("//"):
        return None
    return target


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


def session_token() -> str | None:
    """The session token the signed cookie carries (see `UserStore.open_session`), or None."""
    token = session.get(SESSION_KEY)
    return token if isinstance(token, str) else None


def current_user() -> User | None:
    """The logged-in user, or None: the cookie's session token is looked up in the users database on
    every request and Socket.IO event, so a logout, a password or role change, or a removal takes effect
    at once (and a cookie from before is worth nothing)."""
    if "user" in g:
        return cast("User | None", g.user)
    token = session_token()
    user = user_store().session_user(token) if token is not None else None
    if user is None and (SESSION_KEY in session or "user" in session):
        session.pop(SESSION_KEY, None)
        session.pop("user", None)  # a cookie of an older version (name only): no longer a session
    g.user = user
    return user


def screen_store() -> ScreenStore:
    return cast(ScreenStore, current_app.extensions["atemr.screens"])


def screen_token() -> str | None:
    """The screen device token the signed cookie carries, or None."""
    token = session.get(SCREEN_KEY)
    return token if isinstance(token, str) else None


def current_screen() -> str | None:
    """The name of the screen this session belongs to, or None; looked up on every request and event,
    so a revoked token is refused at once."""
    if "screen" in g:
        return cast("str | None", g.screen)
    token = screen_token()
    name = screen_store().verify(token) if token is not None else None
    if name is None and SCREEN_KEY in session:
        session.pop(SCREEN_KEY, None)
    g.screen = name
    return name


def login_screen(token: str) -> str | None:
    """Start a screen session from a device token (a fresh session: any login in it ends); the screen's
    name, or None when the token is unknown or revoked (the session is left as it was)."""
    name = screen_store().verify(token)
    if name is None:
        return None
    logout_user()
    session[SCREEN_KEY] = token
    session.permanent = True
    g.screen = name
    return name


def login_user(user: User) -> None:
    """Start a fresh session for ``user`` (a new token and CSRF token too: no session fixation)."""
    session.clear()
    session[SESSION_KEY] = user_store().open_session(user.username)
    session.permanent = True
    g.user = user
    csrf_token()


def logout_user() -> str | None:
    """End this session (its token is deleted: the cookie is worth nothing, even replayed); returns the
    ended token, if there was one."""
    token = session_token()
    if token is not None:
        user_store().close_session(token)
    session.clear()
    g.user = None
    return token


def wants_json() -> bool:
    """Whether this request is an API call (answered with a bare status) rather than a page."""
    return request.path.startswith("/api/") or request.accept_mimetypes.best == "application/json"


def role_required(role: Role) -> Callable[[F], F]:
    """Route decorator: anonymous → login page (401 for JSON/API), role too low → no-access page (403)."""

    def decorate(view: F) -> F:
        @functools.wraps(view)
        def wrapped(*args: Any, **kwargs: Any) -> Any:
            user = current_user()
            api = wants_json()
            if user is None and current_screen() is not None:
                abort(403, description=f"Refused: {SCREEN_ONLY}.")
            if user is None:
                if api:
                    abort(401)
                return redirect(url_for("auth.login", next=request.path))
            if not user.can(role):
                if api:
                    abort(403)
                return html_response(
                    current_app.jinja_env.get_template("auth/no_access.html").render(
                        **_template_context(), user=user, needed=role
                    ),
                    403,
                )
            return view(*args, **kwargs)

        return cast(F, wrapped)

    return decorate


def user_permissions() -> tuple[Permission, ...]:
    """The actions this robot's configuration grants the user role too (``ui.user_permissions``)."""
    return tuple(current_app.config["ATEMR_CONFIG"].ui.user_permissions)


def may(permission: Permission) -> bool:
    """Whether the logged-in user may do ``permission`` (False when nobody is logged in)."""
    user = current_user()
    return user is not None and user.may(permission, user_permissions())


def refusal(permission: Permission) -> str:
    """Why ``permission`` was refused, naming the role it needs and the setting that could grant it."""
    return (f"{PERMISSION_LABELS[permission]} needs the {needed_role(permission, user_permissions())} role "
            f"(an admin can grant it to users with ui.user_permissions: {permission})")


def permission_required(permission: Permission, back: str) -> Callable[[F], F]:
    """Route decorator for a form that does a destructive or safety action: with at least the ``user``
    role but without ``permission``, the request is refused with 403 and nothing is changed; a browser gets
    the page the form is on (``back``, an endpoint) with the reason shown, JSON clients a bare 403."""

    def decorate(view: F) -> F:
        @role_required("user")
        @functools.wraps(view)
        def wrapped(*args: Any, **kwargs: Any) -> Any:
            if not may(permission):
                user = current_user()
                log.warning("%s refused for %s: needs the permission %r", request.path,
                            user.username if user else "anonymous", permission)
                if wants_json():
                    abort(403)
                flash(f"Refused: {refusal(permission)}.", "error")
                page = make_response(current_app.view_functions[back]())
                page.status_code = 403
                return page
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
