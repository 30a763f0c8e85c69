"""The point of HTTPS (issue 26): reached by its name on the network, as the carer's laptop and the robot's
tablet reach it, the dashboard over HTTP gets no camera or microphone from the browser, and over HTTPS with
the robot's own certificate it does, so a call can start. ``kay.test`` resolves to 127.0.0.1 in this
Chromium only (the servers still listen on 127.0.0.1)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from atemr.config import Config, UiConfig
from atemr.ui.server import DashboardServer
from atemr.ui.tls import make_certificate

ASK_FOR_MEDIA = """async () => {
  if (!window.isSecureContext || !navigator.mediaDevices) return {secure: window.isSecureContext, tracks: 0};
  const stream = await navigator.mediaDevices.getUserMedia({video: true, audio: true});
  const kinds = stream.getTracks().map((t) => t.kind).sort();
  stream.getTracks().forEach((t) => t.stop());
  return {secure: window.isSecureContext, tracks: kinds.length, kinds};
}"""


def test_a_call_gets_camera_and_microphone_over_https_by_the_robots_name(tmp_path: Path, launch: Any,
                                                                          helpers: Any) -> None:
    cert, key = make_certificate(["kay.test"])
    (tmp_path / "cert.pem").write_bytes(cert)
    (tmp_path / "key.pem").write_bytes(key)
    servers = {}
    for name, tls in (("http", {}), ("https", {"tls_cert": tmp_path / "cert.pem", "tls_key": tmp_path / "key.pem"})):
        ui = UiConfig(port=0, trusted_hosts=("kay.test",), drive_video="mjpeg", **tls)  # type: ignore[arg-type]
        servers[name] = DashboardServer(Config(data_dir=tmp_path / name, ui=ui), None, hash_method=helpers.FAST_SCRYPT)
        servers[name].start()
    try:
        browser = launch("--host-resolver-rules=MAP kay.test 127.0.0.1", *helpers.MEDIA_ARGS)
        # the tablet accepted the robot's certificate once (here: the context trusts it without asking)
        context = browser.new_context(ignore_https_errors=True)
        page = context.new_page()
        page.goto(f"http://kay.test:{servers['http'].port}/auth/login")
        assert page.evaluate(ASK_FOR_MEDIA) == {"secure": False, "tracks": 0}  # no call over plain HTTP
        page.goto(f"https://kay.test:{servers['https'].port}/auth/login")
        assert page.evaluate(ASK_FOR_MEDIA) == {"secure": True, "tracks": 2, "kinds": ["audio", "video"]}
        cookies = {c["name"]: c for c in context.cookies()}
        assert cookies["atemr_session"]["secure"] is True
        context.close()
    finally:
        for server in servers.values():
            server.shutdown()
