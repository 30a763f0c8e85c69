"""Segmented transfer of short texts over 8-byte frames (0x154 WiFi SSID, 0x155 WiFi password).

Wire format (docs/can.md#segmented-transfers-0x154-0x155): each frame is one control byte + seven data
bytes. Control bits 0–6 are the frame index from 0, bit 7 is set on the last frame; the last frame pads
with 0x00. The text is UTF-8 and may not contain NUL (padding would swallow it).

The receiver is a small state machine fed one frame at a time with the time it arrived (injected, so a
simulation is repeatable). It restarts on index 0 and drops the whole transfer on a gap, an
out-of-order duplicate, more than ``max_gap_s`` between frames, invalid UTF-8 or a length outside the
field's limits; each drop is counted and its reason kept for health displays and logs.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import can

from atemr.errors import ProtocolError
from atemr.io.can.protocol import (
    SEGMENT_DATA,
    SEGMENT_MAX_INDEX,
    CanId,
    WifiPasswordSegment,
    WifiSsidSegment,
    _Segment,
    id_name,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TextField:
    """A text carried by segmented transfer: its ID, segment class and UTF-8 length limits in bytes."""

    name: str
    segment: type[_Segment]
    min_bytes: int
    max_bytes: int

    @property
    def arbitration_id(self) -> int:
        return self.segment.arbitration_id


SSID = TextField("WiFi SSID", WifiSsidSegment, 1, 32)
PASSWORD = TextField("WiFi password", WifiPasswordSegment, 8, 63)
#: The text fields by ID.
TEXT_FIELDS: dict[int, TextField] = {CanId.WIFI_SSID: SSID, CanId.WIFI_PASSWORD: PASSWORD}


def _check_text(spec: TextField, raw: bytes) -> str:
    """The text in ``raw`` if it is valid for ``spec``; `ProtocolError` naming the problem otherwise."""
    where = id_name(spec.arbitration_id)
    if not spec.min_bytes <= len(raw) <= spec.max_bytes:
        raise ProtocolError(f"{where}: {spec.name} must be {spec.min_bytes}-{spec.max_bytes} bytes of UTF-8, "
                            f"got {len(raw)}")
    if b"\x00" in raw:
        raise ProtocolError(f"{where}: {spec.name} may not contain NUL characters")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ProtocolError(f"{where}: {spec.name} is not valid UTF-8 ({exc.reason} at byte {exc.start})") from None


def segment_text(spec: TextField, text: str) -> list[_Segment]:
    """Split ``text`` into the segment messages that carry it; invalid text raises `ProtocolError`."""
    try:
        raw = text.encode("utf-8")
    except (UnicodeEncodeError, AttributeError) as exc:
        raise ProtocolError(f"{id_name(spec.arbitration_id)}: {spec.name} cannot be encoded as UTF-8 ({exc})") from None
    _check_text(spec, raw)
    chunks = [raw[i:i + SEGMENT_DATA] for i in range(0, len(raw), SEGMENT_DATA)]
    last = len(chunks) - 1
    return [spec.segment(i, i == last, chunk.ljust(SEGMENT_DATA, b"\x00")) for i, chunk in enumerate(chunks)]


def encode_text(spec: TextField, text: str) -> list[can.Message]:
    """The CAN frames that carry ``text`` in order."""
    return [seg.encode() for seg in segment_text(spec, text)]


class SegmentedSender:
    """Sends texts over ``bus`` (all frames at once: at 1 Mbit/s nine frames take under 1.5 ms)."""

    def __init__(self, bus: can.BusABC, spec: TextField) -> None:
        self.bus = bus
        self.spec = spec

    def send(self, text: str) -> int:
        """Send ``text``; returns the number of frames sent. `ProtocolError` for invalid text."""
        frames = encode_text(self.spec, text)
        for frame in frames:
            self.bus.send(frame)
        return len(frames)


class SegmentedReceiver:
    """Reassembles one text field from its frames; feed it every frame of that ID with its arrival time.

    ``max_gap_s`` is the longest pause allowed between two frames of one transfer (1 s per the spec).
    """

    def __init__(self, spec: TextField, *, max_gap_s: float = 1.0) -> None:
        self.spec = spec
        self.max_gap_s = max_gap_s
        self.completed = 0
        self.drops = 0
        self.last_drop: str | None = None
        self._parts: list[bytes] = []
        self._last_t: float | None = None

    @property
    def in_progress(self) -> bool:
        """True while a transfer has started and not yet ended or been dropped."""
        return bool(self._parts)

    def reset(self) -> None:
        """Forget any transfer in progress."""
        self._parts = []
        self._last_t = None

    def feed(self, frame: can.Message | _Segment, now: float) -> str | None:
        """Take one frame received at ``now``; returns the text when this frame completes a valid transfer.

        A frame that cannot be decoded, or that breaks the transfer, drops it (see `last_drop`) and
        returns None; this method never raises for bad input, since a noisy bus must not stop the caller.
        """
        try:
            seg = frame if isinstance(frame, _Segment) else self.spec.segment.decode(frame)
        except ProtocolError as exc:
            self._drop(str(exc))
            return None
        if seg.arbitration_id != self.spec.arbitration_id:
            self._drop(f"a {id_name(seg.arbitration_id)} segment fed to the {self.spec.name} receiver")
            return None
        if seg.index == 0:
            if self._parts:
                self._drop("restarted by a new frame 0", reset=False)
            self._parts = []
        elif not self._parts:
            self._drop(f"frame {seg.index} without a transfer in progress")
            return None
        elif self._last_t is not None and now - self._last_t > self.max_gap_s:
            self._drop(f"{now - self._last_t:.3f} s between frames (limit {self.max_gap_s} s)")
            return None
        elif seg.index < len(self._parts):
            self._drop(f"frame {seg.index} repeated out of order (expected {len(self._parts)})")
            return None
        elif seg.index > len(self._parts):
            self._drop(f"gap: frame {seg.index} after frame {len(self._parts) - 1}")
            return None
        self._parts.append(seg.data)
        self._last_t = now
        if not seg.last:
            if len(self._parts) * SEGMENT_DATA > self.spec.max_bytes or seg.index == SEGMENT_MAX_INDEX:
                self._drop(f"longer than {self.spec.max_bytes} bytes")
            return None
        self._parts[-1] = self._parts[-1].rstrip(b"\x00")
        raw = b"".join(self._parts)
        self.reset()
        try:
            text = _check_text(self.spec, raw)
        except ProtocolError as exc:
            self._drop(str(exc))
            return None
        self.completed += 1
        return text

    def _drop(self, reason: str, *, reset: bool = True) -> None:
        self.drops += 1
        self.last_drop = reason
        log.warning("%s: transfer dropped: %s", id_name(self.spec.arbitration_id), reason)
        if reset:
            self.reset()
