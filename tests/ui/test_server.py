"""The dashboard server component: real HTTP on a free port in a thread, pushes on tick, clean shutdown."""

from __future__ import annotations

import urllib.request
from pathlib import Path

import pytest

from atemr.errors import HardwareError
from atemr.ui.server import PUSH_RATE_HZ, DashboardServer


def test_serves_on_a_free_port_and_shuts_down(tmp_path, gateway, ui):
    server = DashboardServer(ui.make_config(tmp_path, port=0), gateway, hash_method=ui.FAST_SCRYPT)
    with pytest.raises(HardwareError, match="not started"):
        _ = server.port
    server.start()
    try:
        assert server.running and server.port > 0
        with urllib.request.urlopen(f"{server.url}/auth/first-start", timeout=5) as response:
            assert response.status == 200 and b"First start" in response.read()
        server.tick(0.0)
        assert server.pushes == 1
    finally:
        server.shutdown()
    assert not server.running
    server.shutdown()  # idempotent
    assert PUSH_RATE_HZ == 10.0


def test_port_in_use_is_a_hardware_error(tmp_path, gateway, ui):
    first = DashboardServer(ui.make_config(tmp_path, port=0), gateway, hash_method=ui.FAST_SCRYPT)
    first.start()
    try:
        second = DashboardServer(ui.make_config(tmp_path, port=first.port), gateway, hash_method=ui.FAST_SCRYPT)
        with pytest.raises(HardwareError, match="cannot listen"):
            second.start()
    finally:
        first.shutdown()


def test_works_as_a_scheduler_component(tmp_path, gateway, ui):
    from atemr.clock import SimClock
    from atemr.scheduler import Scheduler

    clock = SimClock()
    sched = Scheduler(clock)
    server = DashboardServer(ui.make_config(tmp_path, port=0), gateway, clock=clock, hash_method=ui.FAST_SCRYPT)
    sched.add(server, PUSH_RATE_HZ)
    sched.start()
    try:
        sched.run(duration=1.0)
    finally:
        sched.shutdown()
    assert server.pushes == 11  # t = 0.0, 0.1, ..., 1.0
    assert not server.running


def test_close_early_closes_small_bodies_and_streams_big_ones():
    from atemr.ui.server import CloseEarly

    closed = []

    class Body:
        def __init__(self, chunks):
            self.chunks = chunks

        def __iter__(self):
            return iter(self.chunks)

        def close(self):
            closed.append(self)

    def app_of(body, length):
        def app(environ, start_response):
            start_response("200 OK", [("Content-Length", str(length))] if length is not None else [])
            return body
        return app

    small = Body([b"ab", b"c"])
    out = CloseEarly(app_of(small, 3), max_bytes=10)({}, lambda *a: None)
    assert out == [b"abc"] and closed == [small]
    big = Body([b"x" * 20])
    assert CloseEarly(app_of(big, 20), max_bytes=10)({}, lambda *a: None) is big and closed == [small]
    unknown = Body([b"y"])
    assert CloseEarly(app_of(unknown, None), max_bytes=10)({}, lambda *a: None) is unknown


def test_close_early_closes_a_not_modified_static_file_which_has_no_content_length():
    """A browser revalidating a cached script gets 304 without Content-Length; werkzeug skips close() when
    the page has moved on, so the static file must be closed here (a CI run saw socket.js leak)."""
    import time

    from flask import Flask
    from werkzeug.http import http_date
    from werkzeug.test import EnvironBuilder

    from atemr.ui.server import CloseEarly

    app = Flask(__name__, static_folder=str(Path(__file__).parents[2] / "atemr" / "ui" / "static"))
    statuses = []
    for headers, method in (({"If-Modified-Since": http_date(time.time() + 100)}, "GET"), ({}, "HEAD")):
        environ = EnvironBuilder(path="/static/js/socket.js", headers=headers, method=method).get_environ()
        body = CloseEarly(app.wsgi_app)(environ, lambda status, headers, exc_info=None: statuses.append(status))
        assert isinstance(body, list) and b"".join(body) == b""
    assert statuses == ["304 NOT MODIFIED", "200 OK"]
