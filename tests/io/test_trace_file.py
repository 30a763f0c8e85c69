"""Trace files: round trip, rotation by size (each part self-contained), pruning, and damaged files read up to
the damage with a warning that names the file and the byte offset."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.errors import ConfigError
from atemr.io.trace_file import MAGIC, TraceWriter, decode_trace, encode_record, part_path, read_trace, trace_files


def records(n: int) -> list[dict]:
    return [{"k": "bb", "t": i / 10, "key": f"/agent/k{i % 7}", "value": {"i": i, "text": "é✓" * (i % 3)},
             "by": "agent/agent"} for i in range(n)]


def test_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "run.atrace"
    written = [*records(50), {"k": "pose", "t": 5.0, "x": math.nan, "y": math.inf, "yaw": 0.5}]
    with TraceWriter(path) as writer:
        for r in written:
            writer.write(r)
    got = read_trace(path)
    assert got.warnings == [] and got.good_bytes == got.size_bytes == path.stat().st_size
    assert got.records[:-1] == written[:-1]
    assert got.records[-1] == {"k": "pose", "t": 5.0, "x": None, "y": None, "yaw": 0.5}  # JSON has no NaN


def test_a_record_needs_a_kind() -> None:
    with pytest.raises(ConfigError, match="'k' kind"):
        encode_record({"t": 1.0})


def test_rotation_by_size_each_part_opens_with_the_preamble(tmp_path: Path) -> None:
    path = tmp_path / "run.atrace"
    calls = []

    def preamble() -> list[dict]:
        calls.append(1)
        return [{"k": "head", "t": 0.0, "part": len(calls)}]

    written = records(400)
    with TraceWriter(path, max_bytes=4096, preamble=preamble) as writer:
        for r in written:
            writer.write(r)
    assert len(writer.parts) > 3 and writer.parts[0] == path and writer.parts[1] == tmp_path / "run.1.atrace"
    body: list[dict] = []
    for i, part in enumerate(writer.parts):
        assert part.stat().st_size <= 4096
        got = read_trace(part)
        assert got.warnings == []
        assert got.records[0] == {"k": "head", "t": 0.0, "part": i + 1}
        body.extend(got.records[1:])
    assert body == written  # nothing lost or doubled at the seams


def test_max_files_deletes_the_oldest_traces_of_the_pattern(tmp_path: Path) -> None:
    old, uploaded = tmp_path / "run-0.atrace", tmp_path / "uploaded.atrace"
    old.write_bytes(MAGIC)
    uploaded.write_bytes(MAGIC)
    with TraceWriter(tmp_path / "run-1.atrace", max_bytes=2048, max_files=3, prune="run-*.atrace") as writer:
        for r in records(300):
            writer.write(r)
    kept = trace_files(tmp_path, "run-*.atrace")
    assert len(writer.parts) > 4 and len(kept) == 3 and kept == writer.parts[-3:] and not old.exists()
    assert uploaded.exists()  # not the recorder's: never pruned


def test_a_truncated_file_is_read_up_to_the_damage_with_a_warning(tmp_path: Path,
                                                                   caplog: pytest.LogCaptureFixture) -> None:
    path = tmp_path / "cut.atrace"
    with TraceWriter(path) as writer:
        for r in records(20):
            writer.write(r)
    data = path.read_bytes()
    lines = data.split(b"\n")
    good = len(MAGIC) + sum(len(x) + 1 for x in lines[1:16])  # magic + 15 whole records
    path.write_bytes(data[: good + 20])  # the 16th record cut after 20 bytes (a power loss)
    got = read_trace(path)
    assert got.records == records(15)
    assert got.good_bytes == good
    assert len(got.warnings) == 1
    assert str(path) in got.warnings[0] and f"offset {good}" in got.warnings[0] and "cut short" in got.warnings[0]
    assert got.warnings[0] in caplog.text


def test_a_damaged_record_stops_the_reading_there(tmp_path: Path) -> None:
    path = tmp_path / "bad.atrace"
    with TraceWriter(path) as writer:
        for r in records(10):
            writer.write(r)
    data = bytearray(path.read_bytes())
    offset = data.index(b'"i":4')  # inside the 5th record
    data[offset + 4] = ord("5")  # a flipped digit: still JSON, but the checksum says no
    path.write_bytes(bytes(data))
    got = read_trace(path)
    start = len(MAGIC) + sum(len(encode_record(r)) for r in records(4))
    assert got.records == records(4)
    assert f"{path}: offset {start}: damaged record (checksum mismatch)" in got.warnings[0]


def test_not_a_trace_is_refused_with_the_file_named(tmp_path: Path) -> None:
    path = tmp_path / "notes.atrace"
    path.write_text("hello\n")
    with pytest.raises(ConfigError, match=r"notes\.atrace.*not an ATEMR trace"):
        read_trace(path)
    with pytest.raises(ConfigError, match="cannot read the trace"):
        read_trace(tmp_path / "missing.atrace")


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes_never_crash_the_reader(data: bytes) -> None:
    got = decode_trace(MAGIC + data, Path("random.atrace"))
    assert got.good_bytes <= len(MAGIC) + len(data)
    assert all(isinstance(r, dict) and isinstance(r["k"], str) for r in got.records)
    with pytest.raises(ConfigError):
        decode_trace(b"X" + data, Path("random.atrace"))


def test_a_failing_disk_stops_the_recording_not_the_robot(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    writer = TraceWriter(blocker / "run.atrace")
    writer.write({"k": "tr", "t": 0.0})
    writer.write({"k": "tr", "t": 0.1})
    assert writer.error is not None and "trace recording stopped" in writer.error
    writer.shutdown()
    writer.shutdown()  # idempotent


def test_part_names() -> None:
    base = Path("/d/run-1.atrace")
    assert [part_path(base, i).name for i in range(3)] == ["run-1.atrace", "run-1.1.atrace", "run-1.2.atrace"]
