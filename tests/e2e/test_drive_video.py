"""The drive camera over WebRTC in a real browser (issue 26): the running simulated robot numbers its camera
frames (``sim.camera_counter``), the Control page plays them over WebRTC (inbound video decoded, the numbers
read back from the <video> rising, the badge saying WebRTC), CAM-OFF closes the robot's connection; and when
WebRTC fails (the test confines the browser's ICE to relay servers it does not have, as a network that blocks
direct UDP does) the page falls back to MJPEG, says so and why, and the picture keeps updating."""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from atemr.io.sim.frame_counter import read_counter_js

pytestmark = pytest.mark.e2e

#: Generous waits, not speed checks: the robot renders and encodes in real time beside the browser.
WAIT_S = 30.0


@pytest.fixture
def webrtc_site(tmp_path: Path, helpers: Any) -> Iterator[Any]:
    pytest.importorskip("aiortc", reason="aiortc (the webrtc extra) is not installed")
    from tests.e2e.conftest import RobotSite

    site = RobotSite(tmp_path / "data", **{"ui.drive_video": "webrtc", "sim.camera_counter": True})
    site.users.set_password("admin", helpers.ADMIN_PW)
    site.start()
    yield site
    site.stop()


def wait_for(page: Any, js: str, timeout_s: float = WAIT_S) -> Any:
    """Poll the function ``js`` (evaluated by Playwright, not by the page: its CSP forbids eval) until truthy."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = page.evaluate(js)
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"still false after {timeout_s:.0f} s: {js} → {value!r}")
        page.wait_for_timeout(100)


def frame_number(page: Any, selector: str) -> int | None:
    return page.evaluate(f"() => ({read_counter_js()})(document.querySelector('{selector}'))")


def numbers_rise(page: Any, selector: str) -> tuple[int, int]:
    """Two frame numbers read from the picture a moment apart, the second higher: the picture updates."""
    first = wait_for(page, f"() => ({read_counter_js()})(document.querySelector('{selector}'))")
    deadline = time.monotonic() + WAIT_S
    while (later := frame_number(page, selector)) is None or later <= first:
        assert time.monotonic() < deadline, f"the picture stayed at frame {first} ({later})"
        page.wait_for_timeout(100)
    return first, later


def open_control(page: Any, site: Any, helpers: Any) -> None:
    helpers.login(page, site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))


def test_the_drive_camera_plays_over_webrtc(webrtc_site, page, shots, helpers):
    video = webrtc_site.server.app.extensions["atemr.drive_video"]
    open_control(page, webrtc_site, helpers)
    wait_for(page, "() => window.atemrDriveVideo && atemrDriveVideo.transport === 'webrtc'")
    stats = wait_for(page, "async () => { const s = await atemrDriveVideo.stats(); "
                           "return s && s.framesDecoded > 0 && s.bytesReceived > 0 ? s : null; }")
    assert stats["state"] == "connected", stats
    _, later = numbers_rise(page, "#camera-video")
    assert page.locator("#camera-video").is_visible() and page.locator("#camera").is_hidden()
    assert page.text_content("#camera-transport") == "WebRTC"
    assert page.evaluate("document.body.dataset.driveVideo") == "webrtc"
    assert video.peers == 1
    assert webrtc_site.server.app.extensions["atemr.camera_streams"].open == 0  # no MJPEG beside it
    page.screenshot(path=str(shots / "drive-video-webrtc.png"))

    page.click("#cam-toggle")  # CAM-OFF: the robot stops sending
    wait_for(page, "() => document.getElementById('cam-toggle').textContent === 'CAM-OFF'")
    deadline = time.monotonic() + 10
    while video.peers:
        assert time.monotonic() < deadline, "the robot still sends after CAM-OFF"
        page.wait_for_timeout(50)
    assert page.locator("#camera-video").is_hidden()
    page.click("#cam-toggle")  # CAM-ON: a new connection, the numbers go on from where the camera is
    wait_for(page, "async () => { const s = await atemrDriveVideo.stats(); return s && s.framesDecoded > 0; }")
    again, _ = numbers_rise(page, "#camera-video")
    assert again > later


#: Confines the page's ICE to relay (TURN) candidates, which it has none of: the offer goes out and is
#: answered, but no media path can form, as on a network that blocks direct UDP.
NO_DIRECT_PATH = """(() => {
  const Native = window.RTCPeerConnection;
  window.RTCPeerConnection = function (config) {
    return new Native({ ...(config || {}), iceTransportPolicy: "relay" });
  };
  window.RTCPeerConnection.prototype = Native.prototype;
})();"""


def test_the_page_falls_back_to_mjpeg_when_webrtc_fails(webrtc_site, page, shots, helpers):
    page.context.add_init_script(script=NO_DIRECT_PATH)
    open_control(page, webrtc_site, helpers)
    wait_for(page, "() => window.atemrDriveVideo && atemrDriveVideo.transport === 'mjpeg'")
    assert page.text_content("#camera-transport") == "MJPEG"
    why = page.get_attribute("#camera-transport", "data-why") or ""
    assert "no picture within" in why or "connection failed" in why, why
    assert why in (page.get_attribute("#camera-transport", "title") or "")
    assert "/api/camera.mjpeg" in (page.get_attribute("#camera", "src") or "")
    numbers_rise(page, "#camera")  # the MJPEG picture updates
    assert page.locator("#camera").is_visible() and page.locator("#camera-video").is_hidden()
    assert webrtc_site.server.app.extensions["atemr.drive_video"].peers == 0  # the page let its offer go
    page.screenshot(path=str(shots / "drive-video-mjpeg-fallback.png"))
