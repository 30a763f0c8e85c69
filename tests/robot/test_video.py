"""The video recorder and video files: MP4/H.264 (WebM/VP8 without x264) that plays at the times the frames were
taken, written by a worker so the robot's thread never encodes, finished under its name only when whole."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import av
import numpy as np
import pytest

from atemr.errors import HardwareError
from atemr.io import video_file
from atemr.io.video_file import MP4_H264, WEBM_VP8, VideoFileError, VideoWriter, first_frame, video_format
from atemr.robot.video import VideoRecorder

W, H = 64, 48


def frame(value: int, width: int = W, height: int = H) -> np.ndarray:
    """A flat frame of one grey level, so the decoded colour says which frame it was."""
    return np.full((height, width, 3), value, dtype=np.uint8)


def decoded(path: Path) -> tuple[str, list[float], list[np.ndarray]]:
    """(codec, frame times in seconds, RGB arrays) of a video file."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        frames = list(container.decode(stream))
        return (stream.codec_context.name, [float(f.pts * f.time_base) for f in frames],
                [f.to_ndarray(format="rgb24") for f in frames])


class Camera:
    """The newest frame, a new array each time `next` is called."""

    def __init__(self) -> None:
        self.latest: np.ndarray | None = None
        self.count = 0

    def next(self, width: int = W, height: int = H) -> None:
        self.count += 1
        self.latest = frame(min(250, 20 * self.count), width, height)


def recorder(tmp_path: Path, camera: Camera, **kwargs) -> VideoRecorder:
    return VideoRecorder(tmp_path / "videos", lambda: camera.latest, lambda: 1_700_000_000.0, **kwargs)


def test_mp4_h264_is_preferred_and_webm_vp8_stands_in_without_x264(monkeypatch):
    video_format.cache_clear()
    assert video_format() is MP4_H264
    video_format.cache_clear()
    monkeypatch.setattr(video_file, "has_encoder", lambda codec: codec != "libx264")
    assert video_format() is WEBM_VP8
    video_format.cache_clear()
    monkeypatch.setattr(video_file, "has_encoder", lambda codec: False)
    with pytest.raises(VideoFileError, match="none of the video encoders libx264, libvpx"):
        video_format()
    video_format.cache_clear()


@pytest.mark.parametrize("fmt", [MP4_H264, WEBM_VP8], ids=["mp4", "webm"])
def test_a_recording_plays_at_the_times_its_frames_were_taken(tmp_path, fmt):
    camera = Camera()
    rec = recorder(tmp_path, camera, fmt=fmt)
    path = rec.begin()
    assert path.name == f"video-20231114-221320-000000{fmt.suffix}"
    assert not path.exists() and path.with_name(path.name + ".part").exists()  # unlisted while written
    times = [10.0, 10.1, 10.2, 10.5, 10.6, 10.6]  # a skipped frame, and a tick without a new frame
    for i, t in enumerate(times):
        if i != 5:
            camera.next()
        rec.tick(t)
    rec.tick(10.7)  # the same frame again: not written twice
    assert rec.end() == path
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]
    codec, pts, pictures = decoded(path)
    assert codec == {"libx264": "h264", "libvpx": "vp8"}[fmt.codec]
    assert pts == pytest.approx([0.0, 0.1, 0.2, 0.5, 0.6], abs=0.002)
    assert [int(p.mean()) for p in pictures] == pytest.approx([20, 40, 60, 80, 100], abs=3)
    assert rec.frames_written == 5 and rec.frames_dropped == 0 and not rec.recording


def test_begin_and_end_refuse_what_cannot_be(tmp_path):
    camera = Camera()
    rec = recorder(tmp_path, camera, fmt=MP4_H264)
    with pytest.raises(HardwareError, match="no video is being recorded"):
        rec.end()
    path = rec.begin()
    with pytest.raises(HardwareError, match=f"already recording {path.name}"):
        rec.begin()
    with pytest.raises(HardwareError, match="no camera frame came while recording; nothing saved"):
        rec.end()
    assert not list(path.parent.iterdir())
    (tmp_path / "file").write_text("")
    blocked = VideoRecorder(tmp_path / "file" / "videos", lambda: camera.latest, time.time)
    with pytest.raises(HardwareError, match="cannot create video-"):
        blocked.begin()


def test_the_robots_thread_only_queues_frames_and_drops_them_when_the_encoder_is_behind(tmp_path, monkeypatch):
    release = threading.Event()
    write = VideoWriter.write

    def slow_write(self, *args):
        release.wait(5)
        return write(self, *args)

    monkeypatch.setattr(VideoWriter, "write", slow_write)
    camera = Camera()
    rec = recorder(tmp_path, camera, fmt=MP4_H264, queue_frames=3)
    rec.begin()
    started = time.perf_counter()
    for i in range(10):
        camera.next()
        rec.tick(i * 0.1)
    assert time.perf_counter() - started < 0.5  # the encoder is stuck, the ticks are not
    assert rec.frames_written == 0
    assert rec.frames_dropped in (6, 7)  # 3 queued, 1 maybe taken by the blocked worker
    release.set()
    path = rec.end()
    assert len(decoded(path)[1]) == 10 - rec.frames_dropped


def test_an_encoder_failure_ends_the_recording_keeps_what_was_written_and_is_reported(tmp_path, monkeypatch):
    write = VideoWriter.write

    def failing_write(self, *args):
        if self.frames == 2:
            raise OSError(28, "No space left on device")
        return write(self, *args)

    monkeypatch.setattr(VideoWriter, "write", failing_write)
    camera = Camera()
    reports: list[str] = []
    rec = recorder(tmp_path, camera, fmt=MP4_H264, on_failure=reports.append)
    path = rec.begin()
    for i in range(4):
        camera.next()
        rec.tick(i * 0.1)
        time.sleep(0.05)  # the worker writes
    deadline = time.monotonic() + 5
    while rec.recording and time.monotonic() < deadline:
        rec.tick(1.0)
        time.sleep(0.01)
    assert not rec.recording
    assert reports == [f"recording {path.name} stopped after 2 frames: OSError: [Errno 28] No space left on device"]
    assert len(decoded(path)[1]) == 2


def test_odd_sizes_are_rounded_to_even_and_later_sizes_scaled(tmp_path):
    writer = VideoWriter(tmp_path / "odd.mp4", MP4_H264, 10.0)
    writer.write(frame(100, 65, 49), 0.0)
    writer.write(frame(100, 32, 24), 0.1)  # the camera changed size: scaled to the first
    assert not writer.write(frame(100, 65, 49), 0.1)  # no later than the previous frame: skipped
    with pytest.raises(ValueError, match="RGB"):
        writer.write(np.zeros((4, 4), dtype=np.uint8), 0.2)
    writer.close()
    pictures = decoded(tmp_path / "odd.mp4")[2]
    assert [p.shape for p in pictures] == [(48, 64, 3)] * 2


def test_shutdown_finishes_a_video_being_recorded(tmp_path):
    camera = Camera()
    rec = recorder(tmp_path, camera, fmt=MP4_H264)
    path = rec.begin()
    camera.next()
    rec.tick(0.0)
    rec.shutdown()
    assert not rec.recording and len(decoded(path)[1]) == 1


def test_start_names_unfinished_videos_of_an_earlier_run(tmp_path, caplog):
    (tmp_path / "videos").mkdir()
    (tmp_path / "videos" / "video-1.mp4.part").write_bytes(b"x")
    recorder(tmp_path, Camera()).start()
    assert "video-1.mp4.part" in caplog.text


def test_first_frame_of_a_video_or_why_there_is_none(tmp_path):
    path = tmp_path / "a.mp4"
    writer = VideoWriter(path, MP4_H264, 10.0)
    writer.write(frame(200), 0.0)
    writer.close()
    image = first_frame(path)
    assert image.size == (W, H) and abs(image.getpixel((10, 10))[0] - 200) <= 3
    (tmp_path / "bad.mp4").write_bytes(b"not a video")
    with pytest.raises(VideoFileError, match=r"cannot read bad\.mp4"):
        first_frame(tmp_path / "bad.mp4")
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(path.read_bytes()[: 200])
    with pytest.raises(VideoFileError, match=r"cut\.mp4"):
        first_frame(cut)

