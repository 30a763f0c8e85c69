"""Drive video latency from capture to display: WebRTC against MJPEG, side by side in one run, in headless
Chromium.

The whole simulated robot (real-time clock) serves its dashboard on 127.0.0.1 with the camera numbering its
frames (``sim.camera_counter``: the number as black/white blocks in the image's corner,
`atemr.io.sim.frame_counter`). A subscriber on the robot's camera notes the wall-clock time each numbered
frame was captured (rendered and handed to the robot). Two Control pages in one headless Chromium, logged
in, watch at the same time: one gets the camera over WebRTC (the page's default), the other over MJPEG (its
``RTCPeerConnection`` is taken away, so it falls back as a browser without WebRTC would). On every animation
frame (the display's rate) each page draws its ``<video>`` or ``<img>`` to a canvas, reads the number back
(`read_counter_js`) and notes the wall-clock time it first showed it. Latency = first shown - captured, per
frame.

Rows (``python benchmarks/bench_drive_video.py`` or ``./benchmarks/run drive_video``):

* median latency over WebRTC against MJPEG (ratio = MJPEG / WebRTC: above 1, WebRTC shows a frame sooner;
  goal >= 1, the reason for WebRTC);
* the 95th percentile, the same way;
* frames shown / frames captured in the window, per transport (a transport may skip frames).

Each figure includes half a display frame on average (the pages look once per animation frame), the same
for both. Figures depend on the machine's load (a wall-clock measure); benchmarks report, they never fail.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from atemr.clock import RealTimeSimClock
from atemr.config import load_config
from atemr.io.can.bus import unique_channel
from atemr.io.sim.frame_counter import read_counter, read_counter_js
from atemr.logsetup import quieted
from atemr.robot import build_robot
from atemr.robot.dashboard import add_dashboard

CHROMIUM = "/usr/bin/chromium"
FAST_SCRYPT = "scrypt:1024:8:1"
PASSWORD = "bench-secret-1"
#: Robot time before measuring (the secondary core boots for 3 s, then the agent reaches IDLE).
BOOT_S = 5.0
#: Wall seconds for the pages to get their first numbered picture.
START_TIMEOUT_S = 60.0

#: Takes WebRTC away from a page: it falls back to MJPEG as a browser without WebRTC does.
NO_WEBRTC = "delete window.RTCPeerConnection;"

#: Installed in a page with the element's selector: notes when each frame number is first shown (the
#: decoder's source is written in: the page's CSP forbids eval).
SAMPLER = """(selector) => {
  const readNumber = READ_COUNTER;
  window.atemrShown = {};
  const look = () => {
    const el = document.querySelector(selector);
    const n = el && !el.hidden ? readNumber(el) : null;
    if (n !== null && !(n in window.atemrShown)) window.atemrShown[n] = performance.timeOrigin + performance.now();
    requestAnimationFrame(look);
  };
  requestAnimationFrame(look);
}"""


class Captures:
    """The wall-clock time each numbered camera frame was captured (thread-safe: the robot's thread writes)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.at_unix_s: dict[int, float] = {}

    def __call__(self, frame: NDArray[np.uint8]) -> None:
        now = time.time()
        number = read_counter(frame)
        if number is not None:
            with self.lock:
                self.at_unix_s.setdefault(number, now)

    def between(self, start_s: float, end_s: float) -> dict[int, float]:
        with self.lock:
            return {n: t for n, t in self.at_unix_s.items() if start_s <= t <= end_s}


def _page(browser: Any, url: str, *, webrtc: bool) -> Any:
    """A Control page logged in as admin, getting the camera over WebRTC or (``webrtc`` False) MJPEG."""
    context = browser.new_context(viewport={"width": 1280, "height": 860})
    if not webrtc:
        context.add_init_script(script=NO_WEBRTC)
    page = context.new_page()
    page.goto(f"{url}/auth/login")
    page.fill("#username-input", "admin")
    page.fill("#password-input", PASSWORD)
    page.click("#login-button")
    page.wait_for_url("**/control")
    return page


def _wait(page: Any, js: str, what: str) -> None:
    deadline = time.monotonic() + START_TIMEOUT_S
    while not page.evaluate(js):
        if time.monotonic() > deadline:
            raise RuntimeError(f"{what} did not start within {START_TIMEOUT_S:.0f} s")
        page.wait_for_timeout(100)


def measure(window_s: float) -> dict[str, Any]:
    """Run both pages for ``window_s`` wall-clock seconds; the raw latencies (s) and frame counts."""
    if not Path(CHROMIUM).exists():
        raise RuntimeError(f"{CHROMIUM} is missing (./test installs Debian's chromium when run as root)")
    from playwright.sync_api import sync_playwright

    quiet = quieted("atemr", "werkzeug", "aiortc", "aioice")
    with quiet, tempfile.TemporaryDirectory(prefix="atemr-bench-video-") as data_dir:
        config = load_config(environ={}, overrides={
            "data_dir": data_dir, "can.channel": unique_channel("bench-video"), "sim.seed": 3,
            "secondary.portal_serve": False, "ui.enabled": False, "ui.port": 0, "log_level": "WARNING",
            "ui.drive_video": "webrtc", "sim.camera_counter": True,
        })
        robot = build_robot(config, realtime=True, clock=RealTimeSimClock(speed=1.0))
        server = add_dashboard(robot, hash_method=FAST_SCRYPT)
        server.app.extensions["atemr.users"].set_password("admin", PASSWORD)
        camera = robot.parts.devices.camera
        if camera is None:
            raise RuntimeError("the simulated robot has no camera")
        captures = Captures()
        camera.subscribe(captures)
        thread = threading.Thread(target=robot.run, name="bench-robot", daemon=True)
        robot.start()
        thread.start()
        try:
            while robot.clock.now() < BOOT_S and thread.is_alive():
                time.sleep(0.1)
            args = ["--no-sandbox"] if os.geteuid() == 0 else []
            with sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path=CHROMIUM, args=[*args, "--disable-gpu"], headless=True)
                try:
                    pages = {"webrtc": _page(browser, server.url, webrtc=True),
                             "mjpeg": _page(browser, server.url, webrtc=False)}
                    for transport, page in pages.items():
                        _wait(page, f"() => window.atemrDriveVideo && atemrDriveVideo.transport === '{transport}'",
                              transport)
                    selector = {"webrtc": "#camera-video", "mjpeg": "#camera"}
                    for transport, page in pages.items():
                        page.evaluate(SAMPLER.replace("READ_COUNTER", read_counter_js()), selector[transport])
                        _wait(page, "() => Object.keys(window.atemrShown).length > 2", f"{transport} pictures")
                    start = time.time()
                    time.sleep(window_s)
                    end = time.time()
                    shown = {t: {int(n): at / 1000.0 for n, at in page.evaluate("window.atemrShown").items()}
                             for t, page in pages.items()}
                finally:
                    browser.close()
        finally:
            robot.stop()
            thread.join(timeout=10)
            robot.shutdown()
    captured = captures.between(start, end)
    out: dict[str, Any] = {"captured": len(captured), "window_s": end - start}
    for transport, seen in shown.items():
        out[transport] = [seen[n] - t for n, t in captured.items() if n in seen]
    return out


def _percentile(values: list[float], q: int) -> float:
    return statistics.quantiles(values, n=100, method="inclusive")[q - 1] if len(values) > 1 else values[0]


def run(quick: bool = False) -> list[dict[str, Any]]:
    try:
        import playwright  # noqa: F401
    except ImportError as exc:
        raise RuntimeError(f"the drive video benchmark needs playwright (a test extra): {exc}") from None
    r = measure(5.0 if quick else 20.0)
    webrtc, mjpeg = r["webrtc"] or [float("nan")], r["mjpeg"] or [float("nan")]
    rows = []
    for name, q in (("median", 50), ("p95", 95)):
        ours, base = 1000.0 * _percentile(webrtc, q), 1000.0 * _percentile(mjpeg, q)
        rows.append({"what": f"drive camera latency {name}, capture to display in headless Chromium: WebRTC "
                             "(vs MJPEG, same run)", "ours": round(ours, 1), "baseline": round(base, 1),
                     "ratio": round(base / ours, 2), "goal": 1.0 if q == 50 else None, "unit": "ms"})
    for transport in ("webrtc", "mjpeg"):
        shown = len(r[transport]) / r["captured"] if r["captured"] else 0.0
        rows.append({"what": f"  frames shown over {'WebRTC' if transport == 'webrtc' else 'MJPEG'} of the "
                             f"{r['captured']} captured in {r['window_s']:.0f} s", "ours": round(shown, 3),
                     "baseline": 1.0, "ratio": round(shown, 3), "goal": None, "unit": "fraction"})
    return rows


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        goal = f"goal >= {row['goal']}" if row["goal"] is not None else ""
        print(f"{row['what']:<100} ours {row['ours']:>8} {row['unit']:<9} baseline {row['baseline']:>8} "
              f"ratio {row['ratio']:>6} {goal}")
