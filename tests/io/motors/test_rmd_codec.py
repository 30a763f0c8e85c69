"""The RMD CAN codec: exact bytes of the MyActuator protocol, round trips, only ProtocolError on bad frames."""

from __future__ import annotations

import math
import struct

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.errors import ProtocolError
from atemr.io.motors import rmd_codec as r

ids = st.integers(1, 32)
speeds = st.floats(-300, 300, allow_nan=False)
requests = st.one_of(
    st.builds(r.RmdRequest, ids, st.sampled_from([c for c in r.RmdCommand if c is not r.RmdCommand.SPEED_CONTROL])),
    st.builds(r.RmdRequest, ids, st.just(r.RmdCommand.SPEED_CONTROL), speeds),
)
replies = st.one_of(
    st.builds(r.AckReply, ids, st.sampled_from([r.RmdCommand.MOTOR_OFF, r.RmdCommand.MOTOR_STOP,
                                                r.RmdCommand.MOTOR_RUN])),
    st.builds(r.Status1Reply, ids, st.sampled_from([r.RmdCommand.READ_STATUS_1, r.RmdCommand.CLEAR_ERRORS]),
              st.integers(-128, 127), st.floats(0, 6000), st.integers(0, 255).map(r.MotorErrorFlags)),
    st.builds(r.Status2Reply, ids, st.sampled_from([r.RmdCommand.READ_STATUS_2, r.RmdCommand.SPEED_CONTROL]),
              st.integers(-128, 127), st.floats(-33, 33), st.floats(-500, 500), st.integers(0, 16383)),
)


@given(requests)
def test_requests_round_trip(req: r.RmdRequest) -> None:
    msg = req.encode()
    assert msg.arbitration_id == 0x140 + req.motor_id and len(msg.data) == 8 and msg.data[0] == req.command
    assert r.decode_request(msg) == req


@given(replies)
def test_replies_round_trip(reply: r.RmdReply) -> None:
    assert r.decode_reply(reply.encode()) == reply


@settings(max_examples=400)
@given(st.integers(0x141, 0x160), st.binary(max_size=8))
def test_random_frames_only_raise_protocol_error(arbitration_id: int, data: bytes) -> None:
    msg = can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False)
    for decoder in (r.decode_request, r.decode_reply, r.decode_any):
        try:
            decoder(msg)
        except ProtocolError as exc:
            assert f"0x{arbitration_id:03X}" in str(exc)


def test_speed_command_bytes() -> None:
    msg = r.RmdRequest(1, r.RmdCommand.SPEED_CONTROL, math.radians(100.0)).encode()
    assert msg.arbitration_id == 0x141
    assert bytes(msg.data) == bytes((0xA2, 0, 0, 0)) + struct.pack("<i", 10000)
    assert bytes(r.RmdRequest(2, r.RmdCommand.MOTOR_STOP).encode().data) == bytes((0x81, 0, 0, 0, 0, 0, 0, 0))


def test_status_reply_bytes() -> None:
    s1 = r.Status1Reply(1, r.RmdCommand.READ_STATUS_1, 31, 24.3, r.MotorErrorFlags.OVER_TEMPERATURE)
    assert bytes(s1.encode().data) == bytes((0x9A, 31, 0)) + struct.pack("<H", 243) + bytes((0, 0, 0x08))
    s2 = r.Status2Reply(2, r.RmdCommand.READ_STATUS_2, -5, 33.0, math.radians(-90), 16383)
    assert bytes(s2.encode().data) == bytes((0x9C, 0xFB)) + struct.pack("<hhH", 2048, -90, 16383)
    assert s1.fields()["errors"] == "OVER_TEMPERATURE"


@pytest.mark.parametrize(
    ("data", "problem"),
    [
        (bytes((0x55, 0, 0, 0, 0, 0, 0, 0)), "unknown command byte 0x55"),
        (bytes((0x9C, 0, 0, 0)), "wrong length 4"),
        (bytes((0x9C, 0)) + struct.pack("<hhH", 3000, 0, 0), "torque current 3000"),
    ],
)
def test_bad_replies(data: bytes, problem: str) -> None:
    with pytest.raises(ProtocolError, match=problem) as info:
        r.decode_reply(can.Message(arbitration_id=0x142, data=data, is_extended_id=False))
    assert str(info.value).startswith("0x142 RMD motor 2")


def test_bad_values_are_refused_at_construction() -> None:
    with pytest.raises(ProtocolError, match="motor id 0"):
        r.RmdRequest(0, r.RmdCommand.MOTOR_RUN)
    with pytest.raises(ProtocolError, match="finite"):
        r.RmdRequest(1, r.RmdCommand.SPEED_CONTROL, float("inf"))
    with pytest.raises(ProtocolError, match="only SPEED_CONTROL"):
        r.RmdRequest(1, r.RmdCommand.MOTOR_RUN, 1.0)
    with pytest.raises(ProtocolError, match="0x150"):
        r.decode_reply(can.Message(arbitration_id=0x150, data=bytes(8), is_extended_id=False))


def test_decode_any_tells_requests_from_replies() -> None:
    req = r.RmdRequest(1, r.RmdCommand.SPEED_CONTROL, 2.0)
    rep = r.Status2Reply(1, r.RmdCommand.SPEED_CONTROL, 30, 1.2, 2.0, 100)
    st1 = r.Status1Reply(1, r.RmdCommand.READ_STATUS_1, 25, 24.0, r.MotorErrorFlags.NONE)
    assert r.decode_any(req.encode()) == req
    assert r.decode_any(rep.encode()) == rep
    assert r.decode_any(st1.encode()) == st1
    read = r.RmdRequest(1, r.RmdCommand.READ_STATUS_1)
    assert r.decode_any(read.encode()) == read
