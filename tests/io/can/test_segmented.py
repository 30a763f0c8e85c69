"""Segmented transfer of SSID and password over 0x154/0x155 (docs/can.md#segmented-transfers-0x154-0x155)."""

from __future__ import annotations

import can
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atemr.errors import ProtocolError
from atemr.io.can import PASSWORD, SSID, SegmentedReceiver, SegmentedSender, WifiSsidSegment, encode_text


def feed_all(rx: SegmentedReceiver, frames: list[can.Message], t0: float = 0.0, dt: float = 0.01) -> list[str]:
    out = []
    for i, f in enumerate(frames):
        text = rx.feed(f, t0 + i * dt)
        if text is not None:
            out.append(text)
    return out


def test_wire_format() -> None:
    frames = encode_text(SSID, "KAY-home-network")  # 16 bytes → 3 frames
    assert [f.arbitration_id for f in frames] == [0x154] * 3
    assert [f.data[0] for f in frames] == [0x00, 0x01, 0x82]
    assert bytes(frames[0].data[1:]) == b"KAY-hom"
    assert bytes(frames[2].data[1:]) == b"rk" + bytes(5)
    assert all(len(f.data) == 8 for f in frames)


texts = st.text(st.characters(codec="utf-8", exclude_characters="\x00"), min_size=1, max_size=32)


@given(texts.filter(lambda t: 1 <= len(t.encode()) <= 32))
def test_ssid_round_trip(text: str) -> None:
    rx = SegmentedReceiver(SSID)
    assert feed_all(rx, encode_text(SSID, text)) == [text]
    assert rx.drops == 0 and not rx.in_progress


@given(st.text(st.characters(codec="utf-8", exclude_characters="\x00"), min_size=2, max_size=63)
       .filter(lambda t: 8 <= len(t.encode()) <= 63))
def test_password_round_trip(text: str) -> None:
    rx = SegmentedReceiver(PASSWORD)
    assert feed_all(rx, encode_text(PASSWORD, text)) == [text]


@pytest.mark.parametrize(("spec", "text"), [(SSID, ""), (SSID, "x" * 33), (PASSWORD, "short"), (PASSWORD, "p" * 64),
                                            (SSID, "a\x00b")])
def test_sender_refuses_invalid_text(spec: object, text: str) -> None:
    with pytest.raises(ProtocolError):
        encode_text(spec, text)  # type: ignore[arg-type]


def test_restart_on_index_zero() -> None:
    rx = SegmentedReceiver(PASSWORD)
    first = encode_text(PASSWORD, "old-password-123")
    second = encode_text(PASSWORD, "new-password-456")
    assert feed_all(rx, first[:2] + second) == ["new-password-456"]
    assert rx.drops == 1 and "restarted" in (rx.last_drop or "")


def test_gap_drops_the_transfer() -> None:
    rx = SegmentedReceiver(PASSWORD)
    frames = encode_text(PASSWORD, "a-long-password-of-30-bytes!!!")
    assert feed_all(rx, [frames[0], frames[2], frames[3], frames[4]]) == []
    assert "gap" in (rx.last_drop or "") or "without a transfer" in (rx.last_drop or "")
    assert not rx.in_progress


def test_out_of_order_duplicate_drops() -> None:
    rx = SegmentedReceiver(PASSWORD)
    frames = encode_text(PASSWORD, "a-long-password-of-30-bytes!!!")
    assert feed_all(rx, [frames[0], frames[1], frames[2], frames[1], frames[3], frames[4]]) == []
    assert rx.drops >= 1
    assert any(word in (rx.last_drop or "") for word in ("repeated", "without a transfer"))


def test_more_than_one_second_between_frames_drops() -> None:
    rx = SegmentedReceiver(SSID)
    frames = encode_text(SSID, "network-name-xyz")
    assert rx.feed(frames[0], 10.0) is None
    assert rx.feed(frames[1], 11.001) is None
    assert "between frames" in (rx.last_drop or "")
    assert rx.feed(frames[2], 11.002) is None  # no transfer any more
    # exactly 1 s is still fine
    assert feed_all(rx, frames, t0=20.0, dt=1.0) == ["network-name-xyz"]


def test_invalid_utf8_and_bad_length_drop() -> None:
    rx = SegmentedReceiver(SSID)
    assert rx.feed(WifiSsidSegment(0, True, b"\xff\xfe" + bytes(5)), 0.0) is None
    assert "UTF-8" in (rx.last_drop or "")
    assert rx.feed(WifiSsidSegment(0, True, bytes(7)), 0.0) is None
    assert "1-32 bytes" in (rx.last_drop or "")
    too_long = [WifiSsidSegment(i, False, b"abcdefg") for i in range(5)]
    assert feed_all(rx, [s.encode() for s in too_long]) == []
    assert "longer than 32" in (rx.last_drop or "")


def test_wrong_frames_never_raise() -> None:
    rx = SegmentedReceiver(SSID)
    assert rx.feed(can.Message(arbitration_id=0x154, data=b"\x80", is_extended_id=False), 0.0) is None
    assert rx.feed(can.Message(arbitration_id=0x155, data=bytes(8), is_extended_id=False), 0.0) is None
    assert rx.drops == 2


def test_sender_over_a_virtual_bus() -> None:
    channel = "test_segmented_sender"
    with can.Bus(interface="virtual", channel=channel) as tx, can.Bus(interface="virtual", channel=channel) as rxb:
        n = SegmentedSender(tx, PASSWORD).send("correct horse battery staple")
        rx = SegmentedReceiver(PASSWORD)
        texts = [t for _ in range(n) if (m := rxb.recv(timeout=0)) is not None and (t := rx.feed(m, 0.0))]
        assert texts == ["correct horse battery staple"]
