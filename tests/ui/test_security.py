"""Security contracts: every route and every Socket.IO event is covered by a role check; the pieces."""

from __future__ import annotations

from pathlib import Path

import pytest

from atemr.clock import SimClock
from atemr.ui.security import LoginRateLimiter, is_local_address

#: The only endpoints an anonymous visitor may reach.
PUBLIC = {"static", "auth.login", "auth.logout", "auth.register", "auth.no_access", "auth.first_start", "index",
          "control.static", "mapping.static", "agent.static", "favicon", "screen.static", "routines.static"}
#: Endpoints that open with a screen device token only: 403 with the reason for everyone else.
SCREEN_ONLY = {"screen.page"}


def _url_for_rule(rule) -> str:
    path = rule.rule
    for arg in rule.arguments:
        path = path.replace(f"<{arg}>", "images" if arg == "kind" else "x.jpg").replace(f"<path:{arg}>", "x")
    return path


def test_every_non_public_route_refuses_anonymous_and_no_access_users(app, ui):
    rules = [r for r in app.url_map.iter_rules() if r.endpoint not in PUBLIC]
    assert len(rules) >= 20
    assert {r.endpoint for r in rules} >= SCREEN_ONLY
    anon = app.test_client()
    bob = app.test_client()
    app.extensions["atemr.users"].set_role("bob", "user")
    ui.login(bob, "bob", ui.USER_PW)
    bob_token = ui.csrf_of(bob, "/settings")
    app.extensions["atemr.users"].set_role("bob", "none")  # logged in, then access revoked: the session ends
    for rule in rules:
        path = _url_for_rule(rule)
        method = "POST" if "POST" in rule.methods else "GET"
        # anonymous POSTs are refused by the CSRF check (400) before anything else; bob's form token is
        # still good, but his session is not
        refused = {403} if rule.endpoint in SCREEN_ONLY else {302, 401}
        for client, allowed in ((anon, {400} if method == "POST" else refused), (bob, refused)):
            if method == "POST":
                data = {"csrf_token": bob_token} if client is bob else {}
                response = client.post(path, data=data)
            else:
                response = client.get(path)
            response.close()
            assert response.status_code in allowed, (rule.endpoint, path, response.status_code)


def test_admin_routes_refuse_plain_users(alice, app, ui):
    for rule in app.url_map.iter_rules():
        if rule.endpoint.startswith("settings.") and "/users" in rule.rule:
            assert ui.post(alice, _url_for_rule(rule).replace("x.jpg", "bob")).status_code == 403


def test_every_registered_socket_event_is_tested(app):
    """A new event must get rows in test_sockets' EVENTS (accepted, refused, role) and BAD tables."""
    events = set(app.extensions["socketio"].server.handlers["/"]) - {"connect", "disconnect"}
    source = (Path(__file__).parent / "test_sockets.py").read_text()
    missing = [event for event in sorted(events) if f'("{event}",' not in source]
    assert not missing, f"Socket.IO events without a row in test_sockets.py: {missing}"


@pytest.mark.parametrize(("address", "local"), [("127.0.0.1", True), ("127.8.9.10", True), ("::1", True),
                                                ("::ffff:127.0.0.1", True), ("192.168.1.2", False),
                                                ("::ffff:10.0.0.1", False), ("", False), (None, False),
                                                ("localhost", False), ("fe80::1%eth0", False)])
def test_is_local_address(address, local):
    assert is_local_address(address) is local


def test_rate_limiter_window_and_lockout():
    clock = SimClock()
    limiter = LoginRateLimiter(clock, max_failures=3, lockout_s=10.0)
    for _ in range(2):
        limiter.failed("Alice", "1.2.3.4")
        clock.advance(1.0)
    assert limiter.retry_after("alice", "1.2.3.4") == 0.0
    limiter.failed("ALICE", "1.2.3.4")  # names are case-insensitive
    assert limiter.retry_after("alice", "1.2.3.4") == pytest.approx(10.0)
    clock.advance(4.0)
    assert limiter.retry_after("alice", "1.2.3.4") == pytest.approx(6.0)
    assert limiter.retry_after("alice", "5.6.7.8") == 0.0
    clock.advance(6.0)
    assert limiter.retry_after("alice", "1.2.3.4") == 0.0


def test_rate_limiter_memory_is_bounded():
    clock = SimClock()
    limiter = LoginRateLimiter(clock, max_failures=3, lockout_s=100.0, max_keys=100)
    for i in range(1000):
        limiter.failed(f"user{i}", "1.2.3.4")
        clock.advance(0.01)
    assert len(limiter._failures) <= 100
    assert limiter.retry_after("user999", "1.2.3.4") == 0.0  # one failure only: not locked
