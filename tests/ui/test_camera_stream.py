"""The camera as MJPEG (``/api/camera.mjpeg``): JPEG parts of at least 640×480 to a logged-in user only,
only while the client reads, ending when the client leaves or the server stops."""

from __future__ import annotations

import http.client
import io
import re

import pytest
from PIL import Image

from atemr.ui.control.mjpeg import BOUNDARY, StreamCount, mjpeg_parts
from atemr.ui.server import DashboardServer

URL = "/api/camera.mjpeg"


class Camera:
    """A camera handing out a new 640×480 JPEG on every call (what a live camera does at 10 fps)."""

    def __init__(self) -> None:
        self.frames = 0

    def __call__(self) -> bytes:
        self.frames += 1
        out = io.BytesIO()
        Image.new("RGB", (640, 480), (self.frames % 256, 80, 160)).save(out, "JPEG")
        return out.getvalue()


@pytest.fixture
def camera(gateway):
    cam = Camera()
    gateway.camera_jpeg = cam
    return cam


def jpegs_of(chunks: list[bytes]) -> list[Image.Image]:
    """The JPEG images in the multipart body ``chunks``, each checked against its Content-Length."""
    body = b"".join(chunks)
    images = []
    head = rb"--" + BOUNDARY.encode() + rb"\r\nContent-Type: image/jpeg\r\nContent-Length: (\d+)\r\n\r\n"
    for match in re.finditer(head, body):
        start, length = match.end(), int(match.group(1))
        data = body[start:start + length]
        assert len(data) == length and body[start + length:start + length + 2] == b"\r\n"
        images.append(Image.open(io.BytesIO(data)))
    return images


def test_refused_without_a_session(app, camera):
    response = app.test_client().get(URL)
    assert response.status_code == 401
    assert camera.frames == 0


def test_refused_for_a_user_without_access(app, camera, ui):
    client = app.test_client()
    ui.login(client, "bob", ui.USER_PW)  # role none: no session is opened
    assert client.get(URL).status_code == 401
    app.extensions["atemr.users"].set_role("bob", "user")
    ui.login(client, "bob", ui.USER_PW)
    app.extensions["atemr.users"].set_role("bob", "none")  # revoked while logged in: the session ends
    assert client.get(URL).status_code == 401
    assert camera.frames == 0


def test_streams_jpeg_parts_while_read_and_stops_when_the_client_leaves(app, alice, camera):
    response = alice.get(URL, buffered=False)
    assert response.status_code == 200
    assert response.mimetype == "multipart/x-mixed-replace"
    assert response.mimetype_params["boundary"] == BOUNDARY
    parts = iter(response.response)
    chunks = [next(parts) for _ in range(3)]
    images = jpegs_of(chunks)
    assert len(images) == 3
    assert all(img.format == "JPEG" and img.size[0] >= 640 and img.size[1] >= 480 for img in images)
    streams = app.extensions["atemr.camera_streams"]
    assert streams.open == 1
    read = camera.frames
    response.close()  # the client leaves
    assert streams.open == 0
    assert camera.frames == read  # nothing is read for nobody


def test_a_stream_ends_when_the_server_stops(app, alice, camera):
    response = alice.get(URL, buffered=False)
    parts = iter(response.response)
    next(parts)
    app.extensions["atemr.stopping"].set()
    rest = list(parts)  # ends by itself
    assert len(rest) <= 1
    assert app.extensions["atemr.camera_streams"].open == 0


def test_an_unchanged_frame_is_not_sent_again_at_once(app, alice, gateway):
    frame = Camera()()
    gateway.jpeg = frame  # the same bytes object: no new frame
    response = alice.get(URL, buffered=False)
    parts = iter(response.response)
    first, second = next(parts), next(parts)  # the second is the repeat after REPEAT_S
    assert jpegs_of([first]) and first == second
    response.close()


def test_a_stream_waits_for_the_cameras_first_frame(app, alice, gateway):
    camera = Camera()
    calls = []

    def warming_up() -> bytes | None:  # no frame for the first three reads, as a camera just switched on
        calls.append(1)
        return camera() if len(calls) > 3 else None

    gateway.camera_jpeg = warming_up
    response = alice.get(URL, buffered=False)
    assert response.status_code == 200
    assert jpegs_of([next(iter(response.response))])[0].size == (640, 480)
    assert len(calls) == 4
    response.close()


def test_no_stream_without_a_robot(ui, tmp_path):
    from atemr.ui.app import create_app

    robotless = create_app(ui.make_config(tmp_path / "other"), None, hash_method=ui.FAST_SCRYPT)
    robotless.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    client = robotless.test_client()
    ui.login(client, "admin", ui.ADMIN_PW)
    assert client.get(URL).status_code == 404


def _read_parts(response: http.client.HTTPResponse, count: int) -> int:
    seen = 0
    while seen < count:
        line = response.readline()
        if not line:
            break
        if line.startswith(b"Content-Length:"):
            response.readline()
            response.read(int(line.split(b":")[1]))
            seen += 1
    return seen


def test_over_http_a_watcher_leaving_ends_its_stream_and_shutdown_ends_the_others(tmp_path, gateway, camera, ui):
    server = DashboardServer(ui.make_config(tmp_path, port=0), gateway, hash_method=ui.FAST_SCRYPT)
    users = server.app.extensions["atemr.users"]
    users.set_password("admin", ui.ADMIN_PW)
    streams = server.app.extensions["atemr.camera_streams"]
    server.start()
    try:
        # log in with the test client to get a signed session cookie valid for the real server too
        client = server.app.test_client()
        ui.login(client, "admin", ui.ADMIN_PW)
        cookie = f"atemr_session={client.get_cookie('atemr_session').value}"

        def watch() -> tuple[http.client.HTTPConnection, http.client.HTTPResponse]:
            conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
            conn.request("GET", URL, headers={"Cookie": cookie})
            response = conn.getresponse()
            assert response.status == 200
            return conn, response

        leaving, leaving_response = watch()
        assert _read_parts(leaving_response, 2) == 2
        leaving_response.close()
        leaving.close()
        staying, staying_response = watch()
        assert _read_parts(staying_response, 2) == 2
        # The left stream's thread notices at its next write; wait for that without timing anything.
        while streams.open > 1:
            assert _read_parts(staying_response, 1) == 1
        assert streams.open == 1
    finally:
        server.shutdown()
    assert _read_parts(staying_response, 1000) < 1000  # the stream ended with the server
    staying.close()
    assert streams.open == 0


class FakeTime:
    """Simulated seconds: ``wait`` (the generator's sleep) and the consumer move them on."""

    def __init__(self) -> None:
        self.now = 0.0

    def is_set(self) -> bool:
        return False

    def wait(self, seconds: float) -> bool:
        self.now += seconds
        return False


def test_a_ten_fps_camera_streams_every_frame_even_when_writing_a_part_takes_time() -> None:
    # The camera makes a new frame every 0.1 s; writing each part to the client takes 20 ms. Every frame
    # must go out (a look once per period, delayed by the writes, lost one frame in six: 8.3 fps).
    fake = FakeTime()
    made: dict[int, bytes] = {}

    def camera() -> bytes:
        index = int(fake.now / 0.1 + 1e-9)
        return made.setdefault(index, f"frame {index}".encode())

    sent = []
    for chunk in mjpeg_parts(camera, fake, StreamCount(), clock=lambda: fake.now):  # type: ignore[arg-type]
        sent.append(chunk)
        fake.now += 0.02
        if fake.now >= 10.0:
            break
    frames = [c.split(b"\r\n\r\n", 1)[1][:-2] for c in sent]
    assert len(frames) == len(set(frames)), "no frame sent twice"
    assert len(frames) >= 99, f"{len(frames)} frames in 10 s from a 10 fps camera"
    numbers = [int(f.split()[1]) for f in frames]
    assert numbers == list(range(numbers[0], numbers[0] + len(numbers))), "in order, none skipped"


def test_a_faster_camera_is_thinned_to_the_stream_rate() -> None:
    fake = FakeTime()
    made: dict[int, bytes] = {}

    def camera() -> bytes:  # 40 fps
        index = int(fake.now / 0.025 + 1e-9)
        return made.setdefault(index, f"frame {index}".encode())

    count = 0
    for _ in mjpeg_parts(camera, fake, StreamCount(), fps=10.0, clock=lambda: fake.now):  # type: ignore[arg-type]
        count += 1
        if fake.now >= 10.0:
            break
    assert 95 <= count <= 112, count
