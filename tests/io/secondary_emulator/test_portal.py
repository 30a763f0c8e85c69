"""The captive portal: pages, validation, CSRF, open only in CONFIG, and the WiFi transfer end to end
(portal form → 0x154/0x155 frames → the primary's SecondaryLink → RecordingNetworkBackend)."""

from __future__ import annotations

import re
import urllib.request
from collections.abc import Iterator
from typing import Any

import can
import pytest
from flask.testing import FlaskClient

from atemr.clock import SimClock
from atemr.io.can import CanId
from atemr.io.can.faults import FaultInjectionBus, FaultPlan
from atemr.io.network import AppliedNetwork
from atemr.io.secondary_emulator.portal import PortalHost, create_portal_app
from atemr.io.secondary_link import WifiResult
from secondary_core.harness import LinkBench


class DropNth:
    """Bus wrapper that silently loses the ``nth`` frame (from 0) this side sends with ``arbitration_id``."""

    def __init__(self, inner: can.BusABC, arbitration_id: int, nth: int) -> None:
        self.inner = inner
        self.arbitration_id = arbitration_id
        self.nth = nth
        self.seen = 0

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.arbitration_id == self.arbitration_id:
            self.seen += 1
            if self.seen - 1 == self.nth:
                return
        self.inner.send(msg, timeout)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        return self.inner.recv(timeout)


def open_config(bench: LinkBench) -> None:
    bench.bring_up()
    bench.core.button.short_press()
    bench.run(0.1)
    assert bench.core.state == "config" and bench.core.portal_active


@pytest.fixture
def bench() -> Iterator[LinkBench]:
    with LinkBench() as b:
        open_config(b)
        yield b


@pytest.fixture
def client(bench: LinkBench) -> FlaskClient:
    return create_portal_app(bench.core, test_config={"TESTING": True}).test_client()


def token(client: FlaskClient, path: str = "/") -> str:
    page = client.get(path).get_data(as_text=True)
    match = re.search(r'name="csrf_token" value="([^"]+)"', page)
    assert match, page
    return match.group(1)


def connect(client: FlaskClient, ssid: str, password: str, **extra: Any) -> Any:
    return client.post("/connect", data={"csrf_token": token(client), "ssid": ssid, "password": password, **extra})


def wifi_frames(bench: LinkBench) -> list[can.Message]:
    return [m for _, m in bench.frames if m.arbitration_id in (CanId.WIFI_SSID, CanId.WIFI_PASSWORD)]


def test_join_network_page(client: FlaskClient) -> None:
    page = client.get("/")
    html = page.get_data(as_text=True)
    assert page.status_code == 200
    assert "Join network" in html and "CONNECT" in html and "VIEW IP" in html and 'name="ssid"' in html
    assert "KAY" in html


def test_connect_end_to_end_applies_credentials(bench: LinkBench, client: FlaskClient) -> None:
    results: list[WifiResult] = []
    bench.link.on_wifi_result = results.append
    page = connect(client, "Casa Ñandú 5G", "correct horse battery")
    assert page.status_code == 200 and "Sent" in page.get_data(as_text=True)
    bench.run(0.1)
    assert bench.network.applied == [AppliedNetwork("Casa Ñandú 5G", "correct horse battery", ok=True)]
    assert len(results) == 1 and results[0].ok and results[0].ssid == "Casa Ñandú 5G"
    ids = [m.arbitration_id for m in wifi_frames(bench)]
    assert ids == [CanId.WIFI_SSID] * 3 + [CanId.WIFI_PASSWORD] * 3  # 15 and 21 bytes: 3 frames each
    assert bench.link.diagnostics()["wifi"]["ok"] is True


@pytest.mark.parametrize(
    ("ssid", "password", "problem"),
    [
        ("", "long enough pw", "SSID) is empty"),
        ("   ", "long enough pw", "SSID) is empty"),
        ("Home", "short", "at least 8"),
        ("Home", "ñññ", "at least 8"),  # 3 characters, 6 bytes
        ("Home", "x" * 64, "at most 63"),
        ("Home", "é" * 32, "at most 63"),  # 32 characters, 64 bytes
        ("S" * 33, "long enough pw", "at most 32"),
        ("Home\x00", "long enough pw", "control characters"),
    ],
)
def test_bad_input_refused_on_page_and_nothing_sent(
    bench: LinkBench, client: FlaskClient, ssid: str, password: str, problem: str
) -> None:
    page = connect(client, ssid, password)
    html = page.get_data(as_text=True)
    assert page.status_code == 400
    assert "Nothing was sent" in html and problem in html
    assert password not in html or password == "", "the password is never echoed back"
    bench.run(0.5)
    assert wifi_frames(bench) == [] and bench.network.applied == []


def test_limits_are_bytes_not_characters(bench: LinkBench, client: FlaskClient) -> None:
    assert connect(client, "é" * 16, "ü" * 4).status_code == 200  # 32-byte SSID, 8-byte password
    bench.run(0.1)
    assert bench.network.applied == [AppliedNetwork("é" * 16, "ü" * 4, ok=True)]


def test_post_without_csrf_token_refused(bench: LinkBench, client: FlaskClient) -> None:
    client.get("/")
    page = client.post("/connect", data={"ssid": "Home", "password": "long enough pw"})
    assert page.status_code == 400
    page = client.post("/connect", data={"ssid": "Home", "password": "long enough pw", "csrf_token": "forged"})
    assert page.status_code == 400
    bench.run(0.2)
    assert wifi_frames(bench) == []


def test_dropped_frame_refuses_transfer_and_applies_nothing() -> None:
    # The board loses the second SSID frame on its way to the bus.
    with LinkBench(wrap_board_bus=lambda bus, clock: DropNth(bus, CanId.WIFI_SSID, 1)) as bench:
        open_config(bench)
        client = create_portal_app(bench.core, test_config={"TESTING": True}).test_client()
        assert connect(client, "A long network name", "password1234").status_code == 200
        bench.run(0.2)
        assert bench.network.applied == []
        results = list(bench.link.wifi_results)
        assert results and not results[-1].ok
        assert "gap" in (results[-1].error or "") or "without a complete SSID" in (results[-1].error or "")
        # A second attempt with nothing lost goes through.
        assert connect(client, "A long network name", "password1234").status_code == 200
        bench.run(0.2)
        assert bench.network.applied == [AppliedNetwork("A long network name", "password1234", ok=True)]


def test_dropped_password_frame_refuses_transfer() -> None:
    with LinkBench(wrap_board_bus=lambda bus, clock: DropNth(bus, CanId.WIFI_PASSWORD, 0)) as bench:
        open_config(bench)
        client = create_portal_app(bench.core, test_config={"TESTING": True}).test_client()
        connect(client, "Home", "a password of some length")
        bench.run(0.2)
        assert bench.network.applied == []
        assert not bench.link.wifi_results[-1].ok


def test_random_frame_loss_never_applies_a_damaged_transfer() -> None:
    outcomes = set()
    for seed in range(16):
        def wrap(bus: can.BusABC, clock: SimClock, seed: int = seed) -> FaultInjectionBus:
            return FaultInjectionBus(bus, FaultPlan(drop=0.1, seed=seed), clock, direction="send")

        with LinkBench(wrap_board_bus=wrap) as bench:
            open_config(bench)
            bench.frames.clear()
            bench.core.send_wifi("Network seven", "password-of-23-bytes!!!")
            bench.run(2.5)  # long enough for an unfinished transfer to be given up
            complete = len(wifi_frames(bench)) == 2 + 4  # 13-byte SSID: 2 frames; 23-byte password: 4
            if complete:
                assert bench.network.applied == [AppliedNetwork("Network seven", "password-of-23-bytes!!!", ok=True)]
            else:
                assert bench.network.applied == [] and not bench.link.wifi_results[-1].ok
            outcomes.add(complete)
    assert outcomes == {True, False}, "the seeds exercise both a clean and a damaged transfer"


def test_backend_failure_reported(bench: LinkBench, client: FlaskClient) -> None:
    bench.network.fail_with = "Secrets were required, but not provided"
    connect(client, "Home", "wrong password")
    bench.run(0.1)
    result = bench.link.wifi_results[-1]
    assert not result.ok and "Secrets were required" in (result.error or "")
    assert bench.link.diagnostics()["wifi"]["ok"] is False


def test_view_ip_and_refresh_twice(bench: LinkBench, client: FlaskClient) -> None:
    assert "192.168.1.42" in client.get("/ip").get_data(as_text=True)  # asked on entering CONFIG
    bench.network.ip = "10.0.0.8"
    page = client.post("/ip/refresh", data={"csrf_token": token(client, "/ip")}).get_data(as_text=True)
    assert "192.168.1.42" in page and "REFRESH" in page and "asked" in page
    bench.run(0.1)
    page = client.post("/ip/refresh", data={"csrf_token": token(client, "/ip")}).get_data(as_text=True)
    assert "10.0.0.8" in page
    assert bench.core.robot_ip == "10.0.0.8"


def test_favicon_is_empty_not_redirected(client: FlaskClient) -> None:
    assert client.get("/favicon.ico").status_code == 204


def test_unknown_urls_redirect_to_portal(client: FlaskClient) -> None:
    for probe in ("/generate_204", "/hotspot-detect.html", "/nothing/here"):
        page = client.get(probe)
        assert page.status_code == 302 and page.headers["Location"].endswith("/")


def test_portal_closed_outside_config(bench: LinkBench, client: FlaskClient) -> None:
    bench.core.button.short_press()
    bench.run(3.1)
    assert bench.core.state == "ops" and not bench.core.portal_active
    page = client.get("/")
    assert page.status_code == 503 and "Portal closed" in page.get_data(as_text=True)
    assert client.post("/connect", data={"ssid": "x", "password": "y" * 8}).status_code == 503
    bench.run(0.2)
    assert wifi_frames(bench) == []


def test_portal_host_serves_only_while_active(bench: LinkBench) -> None:
    host = PortalHost(bench.core, host="127.0.0.1", port=0)
    try:
        host.tick(bench.now)
        assert host.serving and host.url
        with urllib.request.urlopen(host.url, timeout=5) as answer:
            assert answer.status == 200 and "Join network" in answer.read().decode()
        bench.core.button.short_press()
        bench.run(3.1)
        host.tick(bench.now)
        assert not host.serving
    finally:
        host.shutdown()
