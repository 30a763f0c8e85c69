"""The inter-core protocol codec: round trips, exact bytes, and only ProtocolError for bad frames."""

from __future__ import annotations

import ipaddress
import struct

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.errors import ProtocolError
from atemr.io.can import protocol as p


def frame(arbitration_id: int, data: bytes, **kw: object) -> can.Message:
    return can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False, **kw)  # type: ignore[arg-type]


distances = st.floats(min_value=0.0, max_value=1e6, allow_nan=False, width=32)
messages = st.one_of(
    st.builds(p.Power, st.sampled_from(list(p.PowerState)), st.sampled_from(list(p.PowerRequest))),
    st.builds(p.IrFront, distances, distances),
    st.builds(p.IrRear, distances),
    st.builds(
        p.PrimaryStatus,
        st.integers(0, 0x1F).map(p.AgentBits),
        st.integers(0, 0xFF).map(p.HardwareBits),
        st.sampled_from(list(p.StateCode)),
    ),
    st.builds(p.WifiSsidSegment, st.integers(0, 127), st.booleans(), st.binary(min_size=7, max_size=7)),
    st.builds(p.WifiPasswordSegment, st.integers(0, 127), st.booleans(), st.binary(min_size=7, max_size=7)),
    st.just(p.IpRequest()),
    st.builds(p.IpAddress, st.ip_addresses(v=4)),
    st.builds(p.Heartbeat, st.booleans()),
)


@given(messages)
def test_every_message_round_trips(message: p.Message) -> None:
    msg = message.encode()
    assert msg.arbitration_id == message.arbitration_id
    assert not msg.is_extended_id
    assert p.decode(msg) == message
    assert type(message).decode(msg) == message


@settings(max_examples=500)
@given(st.integers(0x150, 0x157), st.binary(max_size=8), st.booleans())
def test_random_frames_decode_or_raise_protocol_error(arbitration_id: int, data: bytes, extended: bool) -> None:
    msg = can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=extended)
    try:
        decoded = p.decode(msg)
    except ProtocolError as exc:
        assert f"0x{arbitration_id:03X}" in str(exc)
    else:
        assert decoded.encode().data == msg.data or isinstance(decoded, p.IrFront | p.IrRear)


@given(st.integers(0, 0x7FF).filter(lambda i: not 0x150 <= i <= 0x157), st.binary(max_size=8))
def test_foreign_ids_are_refused_by_name(arbitration_id: int, data: bytes) -> None:
    with pytest.raises(ProtocolError, match=f"0x{arbitration_id:03X}: not an ID"):
        p.decode(frame(arbitration_id, data))


def test_status_exact_bytes_and_names() -> None:
    hardware = p.HardwareBits.LEFT_MOTOR | p.HardwareBits.IR_REAR
    status = p.PrimaryStatus(p.AgentBits.HEARTBEAT | p.AgentBits.AUTO, hardware, p.StateCode.EXEC)
    msg = status.encode()
    assert (msg.arbitration_id, bytes(msg.data)) == (0x153, bytes((0b101, 0b1000_0001, 0x03)))
    decoded = p.decode(msg)
    assert isinstance(decoded, p.PrimaryStatus)
    assert decoded.state is p.StateCode.EXEC and decoded.state.name == "EXEC"
    assert decoded.auto_mode
    assert decoded.agent_ok()["HEARTBEAT"] and not decoded.agent_ok()["HARDWARE"]
    assert decoded.hardware_ok() == {"LEFT_MOTOR": True, "RIGHT_MOTOR": False, "IMU": False, "LIDAR": False,
                                     "CAMERA": False, "WEBSERVER": False, "IR_FRONT": False, "IR_REAR": True}
    assert [int(s) for s in p.StateCode] == list(range(7))


@pytest.mark.parametrize(
    ("arbitration_id", "data", "problem"),
    [
        (0x153, bytes((0x20, 0, 2)), "byte 0 agent bits 0x20"),
        (0x153, bytes((0, 0, 7)), "byte 2 state code 7"),
        (0x153, bytes((0, 0)), "wrong length 2 bytes, expected 3"),
        (0x150, bytes((3, 0)), "byte 0 power state 3"),
        (0x150, bytes((1, 2)), "byte 1 power request 2"),
        (0x151, struct.pack("<ff", float("nan"), 1.0), "left distance"),
        (0x152, struct.pack("<f", -1.0), "finite distance"),
        (0x152, struct.pack("<f", float("inf")), "finite distance"),
        (0x156, bytes(3), "wrong length 3 bytes, expected 4"),
        (0x157, b"\x02", "neither 0x01"),
        (0x157, b"", "wrong length 0"),
        (0x154, bytes(5), "wrong length 5"),
    ],
)
def test_bad_frames_name_id_and_problem(arbitration_id: int, data: bytes, problem: str) -> None:
    with pytest.raises(ProtocolError) as info:
        p.decode(frame(arbitration_id, data))
    assert str(info.value).startswith(f"0x{arbitration_id:03X} ")
    assert problem in str(info.value)


def test_frame_kinds_are_checked() -> None:
    with pytest.raises(ProtocolError, match="extended"):
        p.decode(can.Message(arbitration_id=0x157, data=b"\x01", is_extended_id=True))
    with pytest.raises(ProtocolError, match="remote"):
        p.decode(can.Message(arbitration_id=0x157, dlc=1, is_remote_frame=True, is_extended_id=False))
    with pytest.raises(ProtocolError, match="got a frame with ID 0x157"):
        p.Power.decode(frame(0x157, b"\x01"))


def test_invalid_messages_cannot_be_built() -> None:
    with pytest.raises(ProtocolError, match="0x153 primary status: byte 2"):
        p.PrimaryStatus(state=9)  # type: ignore[arg-type]
    with pytest.raises(ProtocolError, match="0x151"):
        p.IrFront(float("nan"), 1.0)
    with pytest.raises(ProtocolError, match="0x156 IP address: not an IPv4"):
        p.IpAddress("300.1.1.1")  # type: ignore[arg-type]
    with pytest.raises(ProtocolError, match="segment index 128"):
        p.WifiSsidSegment(128, True, bytes(7))


def test_ip_request_and_answer_share_the_id() -> None:
    assert p.decode(frame(0x156, b"")) == p.IpRequest()
    answer = p.decode(frame(0x156, bytes((192, 168, 4, 1))))
    assert answer == p.IpAddress(ipaddress.IPv4Address("192.168.4.1"))
    assert p.IpAddress("10.0.0.7").encode().data == bytearray((10, 0, 0, 7))  # type: ignore[arg-type]


def test_power_and_heartbeat_bytes() -> None:
    assert bytes(p.Power(p.PowerState.POWER_OFF_ACK).encode().data) == b"\x02\x00"
    assert bytes(p.Power(request=p.PowerRequest.POWER_OFF).encode().data) == b"\x00\x01"
    assert bytes(p.Heartbeat(True).encode().data) == b"\x01"
    assert bytes(p.Heartbeat(False).encode().data) == b"\x00"
    front = p.IrFront(12.5, 30.0)
    assert bytes(front.encode().data) == struct.pack("<ff", 12.5, 30.0)


def test_fields_name_every_value() -> None:
    assert p.Power(p.PowerState.RUNNING).fields() == {"state": "RUNNING", "request": "NORMAL"}
    assert p.PrimaryStatus(state=p.StateCode.MAPPING).fields()["state"] == "MAPPING"


def test_trusted_constructor_needs_every_field() -> None:
    from atemr.io.can.trusted import trusted_constructor

    with pytest.raises(TypeError, match="must be all dataclass fields"):
        trusted_constructor(p.Power, "state")
    make = trusted_constructor(p.Power, "state", "request")
    assert make(p.PowerState.RUNNING, p.PowerRequest.NORMAL) == p.Power(p.PowerState.RUNNING)


def test_decoded_frames_do_not_share_the_frame_buffer() -> None:
    msg = p.WifiSsidSegment(0, True, b"abcdefg").encode()
    seg = p.decode(msg)
    msg.data[1] = 0x7A
    assert isinstance(seg, p.WifiSsidSegment) and seg.data == b"abcdefg"
