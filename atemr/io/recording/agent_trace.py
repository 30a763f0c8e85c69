"""The agent's records of a recording, for ``atemr trace show`` and the Agent page's replay.

A recording keeps the agent recorder's records (`atemr.fsm.recording`) as JSON messages, one topic per
kind (`atemr.io.recording.topics.AGENT_TOPICS`); read back in file order they are the same records an
``.atrace`` file held, so `atemr.fsm.trace_timeline.TraceTimeline` replays either. `read_agent_trace` takes
both (an ``.atrace`` is told by its first line), so traces recorded before MCAP still open; `convert_atrace`
turns one into an MCAP file.
"""

from __future__ import annotations

from pathlib import Path

from atemr.errors import ConfigError
from atemr.io.recording.codec import encode_json
from atemr.io.recording.mcap_reader import RecordingReader, is_mcap
from atemr.io.recording.mcap_writer import RecordingWriter
from atemr.io.recording.ros2_convert import nanoseconds
from atemr.io.recording.topics import KIND_TOPIC, TOPIC_KIND
from atemr.io.trace_file import MAGIC as ATRACE_MAGIC
from atemr.io.trace_file import SUFFIX as ATRACE_SUFFIX
from atemr.io.trace_file import Record, TraceContents, decode_trace

#: What the recordings' folder holds: MCAP recordings, and traces recorded before them.
RECORDING_SUFFIXES = (".mcap", ATRACE_SUFFIX)


def record_entry(record: Record) -> tuple[str, int, bytes]:
    """An agent record as a message: its kind's topic, its time, its JSON (`ConfigError` for an unknown kind)."""
    kind = record.get("k") if isinstance(record, dict) else None
    name = KIND_TOPIC.get(kind) if isinstance(kind, str) else None
    if name is None:
        raise ConfigError(f"an agent record is a dict with a known 'k' kind, got {record!r:.80}")
    return name, nanoseconds(float(record.get("t") or 0.0)), encode_json(record)


def decode_agent_trace(data: bytes, path: Path) -> TraceContents:
    """The agent records in ``data`` (an uploaded file's bytes), read as `read_agent_trace` reads a file."""
    if data.startswith(ATRACE_MAGIC):
        return decode_trace(data, path)
    if not is_mcap(data):
        raise ConfigError("neither an MCAP recording nor an ATEMR trace (it begins with neither's magic bytes)",
                          file=path)
    import tempfile

    with tempfile.TemporaryDirectory(prefix="atemr-upload-") as tmp:
        copy = Path(tmp) / "upload.mcap"
        copy.write_bytes(data)
        contents = read_agent_trace(copy)
    contents.path = path
    contents.warnings = [w.replace(str(copy), str(path)) for w in contents.warnings]
    return contents


def read_agent_trace(path: str | Path) -> TraceContents:
    """Every agent record of the recording (or ``.atrace``) at ``path`` up to the first damage, with a warning
    naming the file and offset of the damage. Raises `ConfigError` when the file cannot be read or is neither."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            head = f.read(len(ATRACE_MAGIC))
    except OSError as exc:
        raise ConfigError(f"cannot read the recording: {exc.strerror}", file=path) from None
    if head.startswith(ATRACE_MAGIC):
        return decode_trace(path.read_bytes(), path)
    if not is_mcap(head):
        raise ConfigError("neither an MCAP recording nor an ATEMR trace (it begins with neither's magic bytes)",
                          file=path)
    reader = RecordingReader(path)
    out = TraceContents(path, size_bytes=reader.size_bytes)
    for message in reader.messages(set(TOPIC_KIND)):
        record = reader.decode(message)
        if not isinstance(record, dict) or TOPIC_KIND[message.topic] != record.get("k"):
            raise ConfigError(f"topic {message.topic} holds a record of another kind: {record!r:.80}", file=path)
        out.records.append(record)
    out.warnings = list(reader.warnings)
    out.good_bytes = reader.good_bytes
    return out


def convert_atrace(source: str | Path, target: str | Path) -> TraceContents:
    """Write the records of the ``.atrace`` file ``source`` to the MCAP file ``target``; returns what was read
    (its warnings say where a damaged source stopped)."""
    source, target = Path(source), Path(target)
    try:
        data = source.read_bytes()
    except OSError as exc:
        raise ConfigError(f"cannot read the trace: {exc.strerror}", file=source) from None
    if is_mcap(data):
        raise ConfigError("already an MCAP recording: nothing to convert", file=source)
    contents = decode_trace(data, source)
    with RecordingWriter(target, max_bytes=1 << 40, metadata={"converted_from": source.name}) as writer:
        for record in contents.records:
            writer.write(*record_entry(record))
    return contents


__all__ = ["RECORDING_SUFFIXES", "convert_atrace", "decode_agent_trace", "read_agent_trace", "record_entry"]
