"""MCAP recordings: written in rotated parts (each opening with its preamble), read back in file order with the
`mcap` library and ours, a file cut mid-chunk read up to its last complete chunk, bad files refused with the
file and the reason, and random bytes never crashing the reader."""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap.writer import Writer

from atemr.errors import ConfigError
from atemr.io.recording.codec import Codec
from atemr.io.recording.mcap_reader import RecordingReader
from atemr.io.recording.mcap_writer import RecordingWriter, part_path
from atemr.io.recording.topics import EVENTS, SCAN, TOPICS

CODEC = Codec()


def event(i: int) -> tuple[str, int, bytes]:
    return EVENTS.name, i * 1_000_000, CODEC.encode(EVENTS.name, {"t": i / 1000, "kind": "test", "text": f"n{i}"})


def texts(path: Path) -> list[str]:
    reader = RecordingReader(path)
    return [reader.decode(m)["text"] for m in reader.messages({EVENTS.name})]


def test_a_recording_reads_back_in_order_with_the_mcap_library_too(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    with RecordingWriter(path) as writer:
        for i in range(500):
            writer.write(*event(i))
    assert texts(path) == [f"n{i}" for i in range(500)]
    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == 500
    channel = next(iter(summary.channels.values()))
    assert (channel.topic, summary.schemas[channel.schema_id].name) == ("/events", "atemr.Event")
    assert summary.schemas[channel.schema_id].encoding == "jsonschema" and channel.message_encoding == "json"


def test_parts_rotate_by_size_each_with_its_preamble_and_old_ones_are_pruned(tmp_path: Path) -> None:
    old, uploaded = tmp_path / "run-0.mcap", tmp_path / "uploaded.mcap"
    old.write_bytes(b"old")
    uploaded.write_bytes(b"kept")
    calls = []

    def preamble() -> list[tuple[str, int, bytes]]:
        calls.append(1)
        return [(EVENTS.name, 0, CODEC.encode(EVENTS.name, {"t": 0, "kind": "head", "text": f"part {len(calls)}"}))]

    with RecordingWriter(tmp_path / "run-1.mcap", max_bytes=8192, max_files=3, prune="run-*.mcap",
                         preamble=preamble) as writer:
        for i in range(600):
            writer.write(*event(i))
    assert len(writer.parts) == len(calls) > 3 and writer.parts[1] == part_path(tmp_path / "run-1.mcap", 1)
    kept = sorted(tmp_path.glob("run-*.mcap"))
    assert len(kept) == 3 and not old.exists() and uploaded.exists()
    assert all(p.stat().st_size <= 8192 for p in writer.parts if p.exists())
    last = texts(writer.parts[-1])
    assert last[0] == f"part {len(calls)}" and last[-1] == "n599"  # every part opens with its own preamble
    every = [t for p in writer.parts if p.exists() for t in texts(p)[1:]]
    assert every == [f"n{i}" for i in range(600 - len(every), 600)]  # nothing lost between the kept parts


def test_a_file_cut_mid_chunk_reads_up_to_the_last_complete_chunk(tmp_path: Path, caplog) -> None:
    path = tmp_path / "cut.mcap"
    with RecordingWriter(path) as writer:
        for i in range(300):
            writer.write(*event(i))
            if i % 100 == 99:
                writer.tick(i)  # a tick closes the chunk: three chunks of 100 messages
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2 + 40])  # a power cut in the middle of the file
    with caplog.at_level(logging.WARNING):
        reader = RecordingReader(path)
        got = [reader.decode(m)["text"] for m in reader.messages()]
    assert 0 < len(got) < 300 and len(got) % 100 == 0 and got == [f"n{i}" for i in range(len(got))]
    assert len(reader.warnings) == 1 and str(path) in reader.warnings[0] and "cut short" in reader.warnings[0]
    assert f"offset {reader.good_bytes}" in reader.warnings[0]


def test_bad_files_are_clear_errors_naming_the_file(tmp_path: Path) -> None:
    text = tmp_path / "notes.mcap"
    text.write_text("hello")
    with pytest.raises(ConfigError, match=r"notes\.mcap: not an MCAP recording"):
        RecordingReader(text)
    with pytest.raises(ConfigError, match=r"missing\.mcap: cannot read"):
        RecordingReader(tmp_path / "missing.mcap")
    wrong = tmp_path / "wrong.mcap"  # a /scan that is not a LaserScan
    with wrong.open("wb") as f:
        w = Writer(f)
        w.start()
        schema = w.register_schema("std_msgs/msg/String", "ros2msg", b"string data")
        channel = w.register_channel(SCAN.name, "cdr", schema)
        w.add_message(channel, log_time=0, data=b"\0\1\0\0\1\0\0\0\0", publish_time=0)
        w.finish()
    with pytest.raises(ConfigError, match=r"wrong\.mcap: topic /scan carries std_msgs/msg/String .*expected "
                                          r"sensor_msgs/msg/LaserScan"):
        list(RecordingReader(wrong).messages())
    garbled = tmp_path / "garbled.mcap"
    with RecordingWriter(garbled) as writer:
        writer.write(SCAN.name, 0, b"\0\1\0\0junk")
    reader = RecordingReader(garbled)
    with pytest.raises(ConfigError, match=r"garbled\.mcap: topic /scan at 0\.000 s does not decode"):
        reader.decode(next(iter(reader.messages())))


@given(st.binary(max_size=400), st.integers(min_value=0, max_value=2000))
def test_random_damage_never_crashes_the_reader(tmp_path_factory: pytest.TempPathFactory, junk: bytes,
                                                 at: int) -> None:
    path = tmp_path_factory.mktemp("fuzz") / "fuzz.mcap"
    with RecordingWriter(path) as writer:
        for i in range(20):
            writer.write(*event(i))
    data = path.read_bytes()
    at = min(at, len(data))
    path.write_bytes(data[:at] + junk)
    try:
        reader = RecordingReader(path)
        for message in reader.messages():
            reader.decode(message)
    except ConfigError:
        pass  # the project's own error, naming the file, is the only one allowed


def test_every_topic_has_a_schema_a_reader_understands() -> None:
    """Contract over the topic table: each ROS 2 schema compiles to an encoder (its decoder is the same text)."""
    for topic in TOPICS.values():
        assert topic.schema_data and topic.schema_name
        if topic.is_ros2:
            assert topic.schema_name.count("/msg/") == 1
            CODEC.encoder(topic)


def test_a_threaded_writer_never_blocks_the_caller_and_counts_what_it_drops(tmp_path: Path, monkeypatch) -> None:
    import atemr.io.recording.mcap_writer as mw

    release = threading.Event()
    real_add = mw._Part.add

    def stalled_add(self, *args):  # the disk hangs
        release.wait(timeout=30)
        real_add(self, *args)

    monkeypatch.setattr(mw._Part, "add", stalled_add)
    writer = RecordingWriter(tmp_path / "slow.mcap", threaded=True, queue_messages=50)
    writer.start()
    started = time.perf_counter()
    for i in range(1000):
        writer.write(*event(i))
    took = time.perf_counter() - started
    release.set()
    writer.shutdown()
    assert writer.dropped > 900 and writer.messages + writer.dropped == 1000
    assert took < 5.0, "the caller waited for the disk"
    got = texts(tmp_path / "slow.mcap")
    numbers = [int(t[1:]) for t in got]
    assert len(got) == writer.messages and numbers[:40] == list(range(40)) and numbers == sorted(set(numbers))


def test_json_messages_carry_non_finite_numbers_as_null_and_stay_valid_json() -> None:
    import json

    from atemr.io.recording.codec import encode_json

    message = {"t": 1.5, "values": [1.0, float("nan"), {"x": float("inf")}], "name": "é"}
    assert json.loads(encode_json(message)) == {"t": 1.5, "values": [1.0, None, {"x": None}], "name": "é"}
    assert encode_json({"t": 2.0, "ok": True}) == b'{"t":2.0,"ok":true}'
