"""The OpenCV camera driver against real OpenCV: a video file written here, an MJPEG-over-HTTP camera served
here on 127.0.0.1 (lost, frozen and back), missing devices, the fps cap on a controllable clock.

Frames must be exactly what the simulated camera publishes (RGB uint8, (H, W, 3), C-contiguous), so the
colours are checked: a pure red source frame must arrive red, not blue (OpenCV decodes to BGR).
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np
import pytest

from atemr.errors import ConfigError
from atemr.io.devices.camera import (
    EARLY_FRACTION,
    INSTALL_HINT,
    QUEUE_FRAMES,
    V4L2_TIMEOUT_ENV,
    CameraSource,
    OpenCvCamera,
    RateCap,
    limit_v4l2_wait,
    redact,
    to_rgb,
)
from atemr.io.devices.config import CameraDeviceConfig

# The driver module imports without OpenCV; these tests need it.
cv2 = pytest.importorskip("cv2", reason="OpenCV is not installed (pip install 'atemr[camera]')")

ROOT = Path(__file__).resolve().parents[3]
RED_BGR, BLUE_BGR = (0, 0, 255), (255, 0, 0)
SRC_W, SRC_H = 64, 48


# -- helpers --------------------------------------------------------------------------------------------------
def solid(bgr, width=SRC_W, height=SRC_H):
    image = np.empty((height, width, 3), np.uint8)
    image[:] = bgr
    return image


def colour(frame) -> str:
    """'red', 'blue' or 'other' from an RGB frame's mean colour."""
    r, g, b = frame.reshape(-1, 3).mean(axis=0)
    if r > 200 and g < 60 and b < 60:
        return "red"
    if b > 200 and r < 60 and g < 60:
        return "blue"
    return "other"


def runs(values):
    """``values`` with repeats collapsed: red red blue red -> red blue red."""
    out = []
    for v in values:
        if not out or out[-1] != v:
            out.append(v)
    return out


def write_video(path: Path, colours_bgr, fps: float) -> Path:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (SRC_W, SRC_H))
    assert writer.isOpened(), "OpenCV cannot write MJPG .avi files here"
    try:
        for bgr in colours_bgr:
            writer.write(solid(bgr))
    finally:
        writer.release()
    return path


def poll(camera: OpenCvCamera, done: Callable[[], bool], timeout_s: float, what: str,
         now: Callable[[], float] = time.monotonic) -> float:
    """Tick ``camera`` until ``done()``; the seconds it took, or a failure saying what did not happen."""
    start = time.monotonic()
    while True:
        camera.tick(now())
        if done():
            return time.monotonic() - start
        if time.monotonic() - start > timeout_s:
            raise AssertionError(f"{what}: not within {timeout_s} s (health: {camera.health(now())})")
        time.sleep(0.01)


class ManualClock:
    """The robot's clock, moved by the test."""

    def __init__(self, t: float = 0.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def cameras() -> Iterator[Callable[..., OpenCvCamera]]:
    """Builds cameras and shuts every one down at the end, whatever the test did."""
    built: list[OpenCvCamera] = []

    def build(source: str, **kwargs) -> OpenCvCamera:
        kwargs.setdefault("now", time.monotonic)
        camera = OpenCvCamera(source, **kwargs)
        built.append(camera)
        return camera

    yield build
    for camera in built:
        camera.shutdown()
        assert camera._thread is None


class MjpegServer:
    """A network camera: an MJPEG stream (multipart/x-mixed-replace of JPEGs) on 127.0.0.1, ~30 fps.

    ``stop`` closes every connection (the camera vanished); ``start`` again brings it back on the same
    port; ``frozen`` keeps connections open but sends nothing (a camera that hangs)."""

    def __init__(self) -> None:
        self.jpeg = cv2.imencode(".jpg", solid(RED_BGR))[1].tobytes()
        self.frozen = threading.Event()
        self.port = 0
        self._server: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None
        self._stopping = threading.Event()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/stream.mjpg"

    def start(self) -> None:
        owner = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, format, *args):  # quiet
                pass

            def do_GET(self):
                self.send_response(200)
                self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
                self.end_headers()
                with contextlib.suppress(BrokenPipeError, ConnectionResetError):  # the driver hung up
                    owner.stream(self.wfile)

        self._stopping.clear()
        self._server = ThreadingHTTPServer(("127.0.0.1", self.port), Handler)
        self.port = self._server.server_address[1]
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.05})
        self._thread.start()

    def stream(self, out) -> None:
        part = b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n" % len(self.jpeg)
        while not self._stopping.is_set():
            if not self.frozen.is_set():
                out.write(part + self.jpeg + b"\r\n")
                out.flush()
            self._stopping.wait(0.03)

    def stop(self) -> None:
        """Stop serving and close every connection (joins the handler threads)."""
        if self._server is None:
            return
        self._stopping.set()
        self._server.shutdown()
        self._server.server_close()
        assert self._thread is not None
        self._thread.join()
        self._server = self._thread = None


@pytest.fixture
def mjpeg_server() -> Iterator[MjpegServer]:
    server = MjpegServer()
    server.start()
    yield server
    server.frozen.clear()
    server.stop()


# -- pure functions -------------------------------------------------------------------------------------------
def test_sources_are_classified():
    assert CameraSource.parse("0") == CameraSource("0", "index", 0)
    assert CameraSource.parse(" 2 ").index == 2
    assert CameraSource.parse("/dev/video1").kind == "device"
    assert CameraSource.parse("/dev/v4l/by-id/usb-cam-video-index0").kind == "device"
    assert CameraSource.parse("rtsp://10.0.0.5:554/stream").kind == "url"
    assert CameraSource.parse("http://cam.local/video.mjpg").kind == "url"
    assert CameraSource.parse("clips/hall.avi").kind == "file"
    assert CameraSource.parse("3").device_path() == ("/dev/video3" if sys.platform.startswith("linux") else None)
    with pytest.raises(ConfigError, match="empty"):
        CameraSource.parse("  ")


def test_passwords_never_reach_messages():
    assert redact("rtsp://admin:secret@10.0.0.5:554/s") == "rtsp://admin:***@10.0.0.5:554/s"
    assert redact("rtsp://10.0.0.5/s") == "rtsp://10.0.0.5/s"
    assert redact("/dev/video0") == "/dev/video0"
    camera = OpenCvCamera("rtsp://admin:secret@127.0.0.1:9/s", now=time.monotonic)
    assert "secret" not in (camera.info().port or "") and "secret" not in camera.health(0.0).detail


def test_a_stalled_scheduler_holds_only_a_few_frames():
    camera = OpenCvCamera("/dev/video0", now=time.monotonic)
    assert camera.queue_size == QUEUE_FRAMES == 4  # 64 queued 640x480 frames would be about 59 MB


def test_bgr_becomes_rgb_of_the_configured_size():
    frame = to_rgb(solid(RED_BGR), 32, 24)
    assert frame.shape == (24, 32, 3) and frame.dtype == np.uint8 and frame.flags.c_contiguous
    assert tuple(frame[0, 0]) == (255, 0, 0)
    assert to_rgb(solid(BLUE_BGR), 128, 96).shape == (96, 128, 3)  # upscaled too
    assert tuple(to_rgb(np.full((SRC_H, SRC_W), 77, np.uint8), SRC_W, SRC_H)[5, 5]) == (77, 77, 77)
    bgra = np.zeros((SRC_H, SRC_W, 4), np.uint8)
    bgra[..., 0] = 255  # blue
    assert tuple(to_rgb(bgra, SRC_W, SRC_H)[0, 0]) == (0, 0, 255)
    with pytest.raises(OSError, match="8-bit"):
        to_rgb(np.zeros((SRC_H, SRC_W, 3), np.uint16), SRC_W, SRC_H)


def test_v4l2_wait_is_bounded_unless_the_operator_chose(monkeypatch):
    monkeypatch.delenv(V4L2_TIMEOUT_ENV, raising=False)
    limit_v4l2_wait(1.5)
    assert os.environ[V4L2_TIMEOUT_ENV] == "2"
    monkeypatch.setenv(V4L2_TIMEOUT_ENV, "7")
    limit_v4l2_wait(1.0)
    assert os.environ[V4L2_TIMEOUT_ENV] == "7"


def test_rate_cap_keeps_the_rate_without_drift_or_bursts():
    def admitted(cap, times):
        return sum(cap.admit(t) for t in times)

    # A 30 fps source for 10 s capped at 10 fps: 100 frames, one more when the first kept frame is early.
    assert admitted(RateCap(10.0), [i / 30 for i in range(300)]) in (100, 101)
    rng = np.random.default_rng(1)
    # Arrival times jitter by up to 40 % of the allowed earliness either way (so 80 % frame to frame).
    jittery = [i / 10 + rng.uniform(-0.4, 0.4) * EARLY_FRACTION * 0.1 for i in range(100)]
    assert admitted(RateCap(10.0), jittery) == 100  # a source at the cap's rate loses nothing to jitter
    assert admitted(RateCap(10.0), [i / 5 for i in range(50)]) == 50  # a slower source: all kept
    cap = RateCap(10.0)
    assert admitted(cap, [0.0]) == 1
    assert admitted(cap, [5.0 + i / 100 for i in range(100)]) in (10, 11)  # after a gap: no catching up
    with pytest.raises(ValueError):
        RateCap(0.0)


def test_missing_opencv_is_a_clear_error_when_the_driver_is_built(monkeypatch):
    # Importing the driver module does not import OpenCV (a simulated robot never needs it) ...
    script = ("import sys\n"
              "import atemr.io.devices.camera, atemr.io.devices.drivers\n"
              "assert 'cv2' not in sys.modules, 'importing the camera driver imported OpenCV'\n")
    subprocess.run([sys.executable, "-c", script], check=True, cwd=ROOT, timeout=60)
    # ... and building it says what to install.
    monkeypatch.setitem(sys.modules, "cv2", None)
    with pytest.raises(ConfigError, match=r"pip install 'atemr\[camera\]'") as error:
        OpenCvCamera.from_config(CameraDeviceConfig(driver="opencv"), now=time.monotonic)
    assert INSTALL_HINT in str(error.value) and error.value.path == "devices.camera.driver"


# -- (a) a video file ---------------------------------------------------------------------------------------
def test_video_file_gives_rgb_frames_of_the_configured_size_and_loops(tmp_path):
    clip = write_video(tmp_path / "clip.avi", [RED_BGR] * 3 + [BLUE_BGR] * 3, fps=50.0)
    cfg = CameraDeviceConfig(driver="opencv", source=str(clip), width=32, height=24, fps=120.0)
    camera = OpenCvCamera.from_config(cfg, now=time.monotonic)
    frames = []
    camera.subscribe(frames.append)
    assert not camera.health(time.monotonic()).ok  # not started
    try:
        camera.start()
        poll(camera, lambda: camera.loops >= 2 and len(frames) >= 8, 5.0, "two loops of the clip")
        assert camera.health(time.monotonic()).ok
    finally:
        camera.shutdown()
    for frame in frames:
        assert frame.shape == (24, 32, 3) and frame.dtype == np.uint8 and frame.flags.c_contiguous
    seen = runs(colour(f) for f in frames)
    assert "other" not in seen
    assert seen[:4] == ["red", "blue", "red", "blue"]  # red first (BGR -> RGB is right), then it loops
    assert len({id(f) for f in frames}) == len(frames)  # a new array per frame (consumers key on identity)
    info = camera.info()
    assert (info.kind, info.driver, info.port, info.model) == ("camera", "opencv", str(clip), "FFMPEG")
    assert camera.reconnects == 0  # looping is not a reconnection


def test_a_file_plays_at_its_own_speed(tmp_path, cameras):
    clip = write_video(tmp_path / "slow.avi", [RED_BGR] * 2 + [BLUE_BGR] * 2, fps=20.0)
    camera = cameras(str(clip), width=SRC_W, height=SRC_H, fps=120.0)
    camera.start()
    poll(camera, lambda: camera.count >= 1, 5.0, "the first frame")
    start, first = time.monotonic(), camera.count
    # ticked as the scheduler does: a stalled one would get only the newest QUEUE_FRAMES frames
    poll(camera, lambda: time.monotonic() - start >= 0.5, 2.0, "half a second of frames")
    rate = (camera.count - first) / (time.monotonic() - start)
    assert 10.0 <= rate <= 25.0  # ~20 fps, not as fast as the file decodes


# -- (b) an MJPEG camera on the network --------------------------------------------------------------------------
def test_network_camera_lost_and_back(mjpeg_server, cameras):
    camera = cameras(mjpeg_server.url, width=SRC_W, height=SRC_H, fps=30.0, open_timeout_s=2.0,
                     read_timeout_s=1.0)
    camera.start()
    poll(camera, lambda: camera.count >= 3, 5.0, "frames from the stream")
    assert camera.health(time.monotonic()).ok and colour(camera.latest) == "red"
    assert camera.info().model == "FFMPEG"

    mjpeg_server.stop()  # the camera disappears
    lost = poll(camera, lambda: not camera.health(time.monotonic()).ok, 3.0, "unhealthy once the camera is gone")
    assert lost < 1.5
    assert mjpeg_server.url.split("/stream")[0] in camera.health(time.monotonic()).detail

    mjpeg_server.start()  # back on the same port
    before = camera.count
    poll(camera, lambda: camera.count > before + 3 and camera.health(time.monotonic()).ok, 5.0, "frames again")
    assert camera.reconnects >= 1


def test_a_frozen_network_camera_times_out_and_recovers(mjpeg_server, cameras):
    # A long max_age_s: only the driver's read timeout can make it unhealthy here.
    camera = cameras(mjpeg_server.url, width=SRC_W, height=SRC_H, fps=30.0, open_timeout_s=2.0,
                     read_timeout_s=1.0, max_age_s=30.0)
    camera.start()
    poll(camera, lambda: camera.count >= 3, 5.0, "frames from the stream")

    mjpeg_server.frozen.set()  # connected, silent
    lost = poll(camera, lambda: not camera.connected, 3.0, "the read timeout to give the stream up")
    assert 0.5 < lost < 2.0
    assert not camera.health(time.monotonic()).ok

    mjpeg_server.frozen.clear()
    before = camera.count
    poll(camera, lambda: camera.count > before + 3 and camera.health(time.monotonic()).ok, 5.0, "frames again")
    assert camera.reconnects >= 1


# -- (c) missing devices ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("source", ["/dev/video-atemr-missing", "63", "{tmp}/missing.avi",
                                    "http://127.0.0.1:9/stream.mjpg"])
def test_a_missing_source_is_an_unhealthy_device_naming_it(source, tmp_path, cameras):
    source = source.format(tmp=tmp_path)
    if source == "63" and os.path.exists("/dev/video63"):
        pytest.skip("this machine has a /dev/video63")
    camera = cameras(source, open_timeout_s=1.0)
    assert camera.health(time.monotonic()).detail == "not started"
    camera.start()
    poll(camera, lambda: camera.health(time.monotonic()).detail != "not started", 3.0, "a first open attempt")
    health = camera.health(time.monotonic())
    named = "/dev/video63" if source == "63" else source
    assert not health.ok and named in health.detail and camera.count == 0


def test_no_permission_names_the_video_group(monkeypatch, cameras):
    monkeypatch.setattr(os, "access", lambda *args, **kwargs: False)
    camera = cameras("/dev/null")
    with pytest.raises(PermissionError, match="/dev/null") as error:
        camera._open()
    assert "`video` group" in camera.missing_hint(error.value)


# -- (d) the fps cap ---------------------------------------------------------------------------------------------
def test_fps_cap_on_the_robot_clock(tmp_path, cameras):
    clip = write_video(tmp_path / "fast.avi", [RED_BGR] * 4, fps=200.0)
    clock = ManualClock(100.0)
    camera = cameras(str(clip), now=clock, width=SRC_W, height=SRC_H, fps=5.0)
    camera.start()

    def read_more(n: int) -> None:
        target = camera.frames_read + n
        poll(camera, lambda: camera.frames_read >= target, 5.0, f"{n} more frames read", now=clock)

    read_more(10)  # the robot's clock stands still: one frame kept, the rest dropped
    assert camera.count == 1 and camera.frames_skipped >= 9

    for _ in range(40):  # 2 s of robot time in 50 ms steps, frames read in each step
        clock.t += 0.05
        read_more(2)
    read_more(2)
    delivered = camera.count - 1
    assert 9 <= delivered <= 11  # 5 fps x 2 s
    assert camera.frames_read >= 90
