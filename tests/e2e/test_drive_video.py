"""The drive camera over WebRTC in a real browser (issue 26): the running simulated robot numbers its camera
frames (``sim.camera_counter``), the Control page plays them over WebRTC (inbound video decoded, the numbers
read back from the <video> rising, the badge saying WebRTC), CAM-OFF closes the robot's connection; and when
WebRTC fails (the test confines the browser's ICE to relay servers it does not have, as a network that blocks
direct UDP does) the page falls back to MJPEG, says so and why, and the picture keeps updating."""

from __future__ import annotations

import re
import time
from typing import Any

import pytest

from atemr.io.sim.frame_counter import read_counter_js

pytestmark = pytest.mark.e2e

#: Generous waits, not speed checks: the robot renders and encodes in real time beside the browser.
WAIT_S = 30.0


def frame_number(page: Any, selector: str) -> int | None:
    return page.evaluate(f"() => ({read_counter_js()})(document.querySelector('{selector}'))")


def numbers_rise(page: Any, selector: str, helpers: Any) -> tuple[int, int]:
    """Two frame numbers read from the picture a moment apart, the second higher: the picture updates."""
    first = helpers.wait_for(page, f"() => ({read_counter_js()})(document.querySelector('{selector}'))", WAIT_S)
    deadline = time.monotonic() + WAIT_S
    while (later := frame_number(page, selector)) is None or later <= first:
        assert time.monotonic() < deadline, f"the picture stayed at frame {first} ({later})"
        page.wait_for_timeout(100)
    return first, later


def open_control(page: Any, site: Any, helpers: Any) -> None:
    helpers.login(page, site.url, "admin", helpers.ADMIN_PW)
    page.wait_for_url(re.compile(r"/control$"))


def test_the_drive_camera_plays_over_webrtc(webrtc_robot_site, page, shots, helpers):
    video = webrtc_robot_site.server.app.extensions["atemr.drive_video"]
    open_control(page, webrtc_robot_site, helpers)
    helpers.wait_for(page, "() => window.atemrDriveVideo && atemrDriveVideo.transport === 'webrtc'", WAIT_S)
    stats = helpers.wait_for(page, "async () => { const s = await atemrDriveVideo.stats(); "
                                   "return s && s.framesDecoded > 0 && s.bytesReceived > 0 ? s : null; }", WAIT_S)
    assert stats["state"] == "connected", stats
    _, later = numbers_rise(page, "#camera-video", helpers)
    assert page.locator("#camera-video").is_visible() and page.locator("#camera").is_hidden()
    assert page.text_content("#camera-transport") == "WebRTC"
    assert page.evaluate("document.body.dataset.driveVideo") == "webrtc"
    assert video.peers == 1
    assert webrtc_robot_site.server.app.extensions["atemr.camera_streams"].open == 0  # no MJPEG beside it
    page.screenshot(path=str(shots / "drive-video-webrtc.png"))

    page.click("#cam-toggle")  # CAM-OFF: the robot stops sending
    helpers.wait_for(page, "() => document.getElementById('cam-toggle').textContent === 'CAM-OFF'")
    deadline = time.monotonic() + 10
    while video.peers:
        assert time.monotonic() < deadline, "the robot still sends after CAM-OFF"
        page.wait_for_timeout(50)
    assert page.locator("#camera-video").is_hidden()
    page.click("#cam-toggle")  # CAM-ON: a new connection, the numbers go on from where the camera is
    helpers.wait_for(page, "async () => { const s = await atemrDriveVideo.stats(); return s && s.framesDecoded > 0; }",
                     WAIT_S)
    again, _ = numbers_rise(page, "#camera-video", helpers)
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


def test_the_page_falls_back_to_mjpeg_when_webrtc_fails(webrtc_robot_site, page, shots, helpers):
    page.context.add_init_script(script=NO_DIRECT_PATH)
    open_control(page, webrtc_robot_site, helpers)
    helpers.wait_for(page, "() => window.atemrDriveVideo && atemrDriveVideo.transport === 'mjpeg'", WAIT_S)
    assert page.text_content("#camera-transport") == "MJPEG"
    why = page.get_attribute("#camera-transport", "data-why") or ""
    assert "no picture within" in why or "connection failed" in why, why
    assert why in (page.get_attribute("#camera-transport", "title") or "")
    assert "/api/camera.mjpeg" in (page.get_attribute("#camera", "src") or "")
    numbers_rise(page, "#camera", helpers)  # the MJPEG picture updates
    assert page.locator("#camera").is_visible() and page.locator("#camera-video").is_hidden()
    assert webrtc_robot_site.server.app.extensions["atemr.drive_video"].peers == 0  # the page let its offer go
    page.screenshot(path=str(shots / "drive-video-mjpeg-fallback.png"))


def test_the_camera_starts_when_its_script_runs_after_the_socket_connected(robot_site, page, helpers):
    """The browser delivers the socket's messages while it waits for a page's later scripts to download: on a
    loaded machine the connection opened before camera.js ran, which then never heard of it and never started the
    camera (the drive-video benchmark saw it twice). Here camera.js comes two seconds late, the socket connects
    meanwhile, and the camera must still start (MJPEG here: choosing the transport is what never happened)."""
    arrived = []

    def late(route: Any) -> None:
        time.sleep(2.0)  # the browser runs on: its socket connects meanwhile
        arrived.append(time.monotonic())
        route.continue_()

    page.route(re.compile(r".*/camera\.js(\?.*)?$"), late)
    open_control(page, robot_site, helpers)
    helpers.wait_for(page, "() => window.atemrDriveVideo && atemrDriveVideo.transport === 'mjpeg'", WAIT_S)
    assert arrived, "camera.js was not delayed: the test proves nothing"
    helpers.wait_for(page, "() => document.getElementById('camera').naturalWidth >= 640", WAIT_S)
