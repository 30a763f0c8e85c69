"""Reading a recording back, up to any damage, with errors that name the file and what is wrong.

`RecordingReader` walks an MCAP file from its start (it never trusts the summary at the end, which a file
cut by a power loss does not have) and yields each message in file order: the order the robot recorded
them. A chunk is yielded only once it has been read whole and its checksum holds, so a file truncated or
damaged mid-chunk gives everything up to its last complete chunk, plus a warning naming the file and the
byte offset of the damage (``warnings``). A file that is not MCAP, or whose known topics carry another
schema than `atemr.io.recording.topics` says, is a `ConfigError` naming the file and the topic; so is a
message that does not decode. No reader error escapes as a traceback.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from mcap.exceptions import EndOfFile
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Schema
from mcap.stream_reader import MAGIC_SIZE, StreamReader, breakup_chunk
from mcap_ros2.decoder import DecoderFactory

from atemr.errors import ConfigError
from atemr.io.recording.topics import TOPICS

log = logging.getLogger(__name__)

MAGIC = b"\x89MCAP0\r\n"
#: A chunk that claims to grow past this many times its compressed size is damage, not data.
MAX_EXPANSION = 1000


@dataclass(frozen=True)
class Recorded:
    """One message as read: its topic, log time (ns) and encoded bytes."""

    topic: str
    log_time: int
    data: bytes


def is_mcap(head: bytes) -> bool:
    """Whether bytes (a file's first 8 at least) begin as an MCAP file does."""
    return head[:MAGIC_SIZE] == MAGIC


class RecordingReader:
    """Reads the MCAP file at ``path`` (see the module docstring). ``topics`` limits what `messages` yields."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self.size_bytes = self.path.stat().st_size
            with self.path.open("rb") as f:
                head = f.read(MAGIC_SIZE)
        except OSError as exc:
            raise ConfigError(f"cannot read the recording: {exc.strerror}", file=self.path) from None
        if not is_mcap(head):
            what = "it is empty" if not head else "it does not begin with the MCAP magic bytes"
            raise ConfigError(f"not an MCAP recording ({what})", file=self.path)
        self.warnings: list[str] = []
        #: Topic → (schema name, message encoding) of every channel met so far.
        self.channels: dict[str, tuple[str, str]] = {}
        #: Bytes read as good records (the offset of the damage, or where the data section ended).
        self.good_bytes = MAGIC_SIZE
        self.messages_read = 0
        self._schemas: dict[int, Schema] = {}
        self._channel_records: dict[int, Channel] = {}
        self._ignored: set[int] = set()
        self._decoders = DecoderFactory()
        self._decode: dict[int, Callable[[bytes], Any]] = {}

    # -- walking the file ---------------------------------------------------------------------------------
    def messages(self, topics: set[str] | None = None) -> Iterator[Recorded]:
        """Every message (of ``topics``) in file order, up to the end or the first damage (then a warning)."""
        self.warnings = []
        try:
            f = self.path.open("rb")
        except OSError as exc:
            raise ConfigError(f"cannot read the recording: {exc.strerror}", file=self.path) from None
        with f:
            yield from self._walk(f, topics)

    def _walk(self, f: IO[bytes], topics: set[str] | None) -> Iterator[Recorded]:
        stream = StreamReader(f, emit_chunks=True, record_size_limit=max(self.size_bytes, 1))
        records = stream.records
        while True:
            try:
                record = next(records)
                batch = self._expand(record, topics)
            except StopIteration:
                return
            except ConfigError:
                raise
            except EndOfFile:
                if f.tell() == self.good_bytes:  # the last record is whole: the file simply stops there
                    self._unfinished()
                else:
                    self._damaged(f.tell(), EndOfFile())
                return
            except Exception as exc:  # any damage: the MCAP library, zstd, struct, a bad UTF-8 name...
                self._damaged(f.tell(), exc)
                return
            for out in batch:
                if topics is None or out.topic in topics:
                    yield out
            self.good_bytes = f.tell()
            if isinstance(record, (DataEnd, Footer)):
                return

    def _expand(self, record: Any, topics: set[str] | None) -> list[Recorded]:
        """The messages of ``record`` (a whole chunk, or one record), after taking in its schemas and channels."""
        inner = [record]
        if isinstance(record, Chunk):
            if record.uncompressed_size > MAX_EXPANSION * max(len(record.data), 1):
                raise ValueError(f"a chunk claims {record.uncompressed_size} bytes from {len(record.data)}")
            inner = breakup_chunk(record, validate_crc=True)
        out: list[Recorded] = []
        for r in inner:
            if isinstance(r, Schema):
                self._schemas[r.id] = r
            elif isinstance(r, Channel):
                self._add_channel(r, topics)
            elif isinstance(r, Message) and r.channel_id not in self._ignored:
                channel = self._channel_records.get(r.channel_id)
                if channel is None:
                    raise ValueError(f"a message on channel {r.channel_id}, which no channel record defines")
                out.append(Recorded(channel.topic, r.log_time, r.data))
        self.messages_read += len(out)
        return out

    def _add_channel(self, channel: Channel, topics: set[str] | None) -> None:
        """Take in a channel; one of the topics asked for that carries another schema than the table's is an error
        (one not asked for is only listed: a replay does not care what an older writer put on /can/frames)."""
        schema = self._schemas.get(channel.schema_id)
        name = schema.name if schema is not None else ""
        known = TOPICS.get(channel.topic)
        wrong = known is not None and (name != known.schema_name or channel.message_encoding != known.message_encoding)
        if wrong and topics is not None and channel.topic not in topics:
            self.channels[channel.topic] = (name, channel.message_encoding)
            self._ignored.add(channel.id)
            return
        if known is not None and wrong:
            raise ConfigError(f"topic {channel.topic} carries {name or 'no schema'} ({channel.message_encoding}), "
                              f"expected {known.schema_name} ({known.message_encoding})", file=self.path)
        self._channel_records[channel.id] = channel
        self.channels[channel.topic] = (name, channel.message_encoding)

    def _unfinished(self) -> None:
        self.warnings.append(f"{self.path}: offset {self.good_bytes}: the recording ends without its closing summary "
                             f"(still being recorded, or cut short there); read {self.messages_read} messages")
        log.info("%s", self.warnings[-1])

    def _damaged(self, offset: int, exc: Exception) -> None:
        why = "cut in the middle of a record" if isinstance(exc, EndOfFile) else str(exc) or type(exc).__name__
        self.warnings.append(f"{self.path}: offset {self.good_bytes}: the recording is cut short or damaged "
                             f"({why}); read {self.messages_read} messages up to its last complete chunk, the "
                             f"rest ({max(self.size_bytes - self.good_bytes, 0)} bytes) is skipped")
        log.warning("%s", self.warnings[-1])

    # -- decoding -------------------------------------------------------------------------------------------
    def decode(self, message: Recorded) -> Any:
        """The message as objects (ROS 2: attribute access as the field names; JSON: dicts and lists).
        Raises `ConfigError` naming the file, topic and time when it does not decode."""
        try:
            if TOPICS[message.topic].message_encoding == "json":
                return json.loads(message.data)
            channel_id = next(c.id for c in self._channel_records.values() if c.topic == message.topic)
            decode = self._decode.get(channel_id)
            if decode is None:
                channel = self._channel_records[channel_id]
                found = self._decoders.decoder_for(channel.message_encoding, self._schemas.get(channel.schema_id))
                if found is None:
                    raise ValueError("no decoder for its schema")
                decode = self._decode[channel_id] = found
            return decode(message.data)
        except ConfigError:
            raise
        except Exception as exc:
            raise ConfigError(f"topic {message.topic} at {message.log_time / 1e9:.3f} s does not decode: "
                              f"{str(exc) or type(exc).__name__}", file=self.path) from None


__all__ = ["MAGIC", "Recorded", "RecordingReader", "is_mcap"]
