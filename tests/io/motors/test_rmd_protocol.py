"""Both RMD protocol versions behind `RmdProtocol`: the documents' example frames, IDs, commands, error flags.

V4.2 frames are the examples of MyActuator's "Servo Motor Control Protocol V4.2" (driver V3) itself. No copy
of the V1.61 document with communication examples was at hand, so the V1.61 frames are built byte by byte
from its reply field tables (0x9A: [1] temperature, [3:5] voltage 0.1 V, [7] error byte; 0x9C: [1]
temperature, [2:4] iq ±2048 = ±33 A, [4:6] speed 1 dps, [6:8] encoder), with the same values as the V4.2
examples where the fields agree.
"""

from __future__ import annotations

import math

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.errors import ProtocolError
from atemr.io.motors import rmd_v4 as v4
from atemr.io.motors.rmd_codec import (
    AckReply,
    MotorErrorFlags,
    RmdCommand,
    RmdRequest,
    Status1Reply,
    Status2Reply,
    flag_names,
)
from atemr.io.motors.rmd_protocol import (
    PROTOCOL_V1,
    PROTOCOL_V4,
    PROTOCOL_VERSIONS,
    MotorReading,
    rmd_protocol,
)


def frame(arbitration_id: int, hex_bytes: str) -> can.Message:
    return can.Message(arbitration_id=arbitration_id, data=bytes.fromhex(hex_bytes), is_extended_id=False)


# -- V4.2: the document's own examples --------------------------------------------------------------------


def test_v4_status1_example_decodes_exactly() -> None:
    reply = PROTOCOL_V4.decode_reply(frame(0x241, "9A 32 00 01 E5 01 04 00"))
    assert isinstance(reply, v4.V4Status1Reply)
    assert (reply.motor_id, reply.command, reply.temperature_c) == (1, RmdCommand.READ_STATUS_1, 50)
    assert reply.voltage_v == pytest.approx(48.5)
    assert reply.errors == MotorErrorFlags.UNDER_VOLTAGE and reply.error_code == 0x0004
    assert reply.brake_released  # byte 3 = 1: the brake-release command was executed
    assert PROTOCOL_V4.error_text(reply.errors) == "UNDER_VOLTAGE (V4.2 0x0004 low voltage)"
    again = PROTOCOL_V4.encode_reply(reply)
    assert again.arbitration_id == 0x241 and bytes(again.data) == bytes.fromhex("9A 32 00 01 E5 01 04 00")


@pytest.mark.parametrize("command", ["9C", "A2"])
def test_v4_status2_example_decodes_exactly(command: str) -> None:
    reply = PROTOCOL_V4.decode_reply(frame(0x241, f"{command} 32 64 00 F4 01 2D 00"))
    assert isinstance(reply, v4.V4Status2Reply)
    assert reply.command == int(command, 16) and reply.temperature_c == 50
    assert reply.current_a == pytest.approx(1.00)
    assert math.degrees(reply.speed_radps) == pytest.approx(500.0)
    assert math.degrees(reply.angle_rad) == pytest.approx(45.0)
    assert bytes(PROTOCOL_V4.encode_reply(reply).data) == bytes.fromhex(f"{command} 32 64 00 F4 01 2D 00")


def test_v4_negative_status2_example() -> None:  # the document's 0xA2 example 2
    reply = PROTOCOL_V4.decode_reply(frame(0x241, "A2 32 9C FF 0C FE D3 FF"))
    assert isinstance(reply, v4.V4Status2Reply)
    assert reply.current_a == pytest.approx(-1.0)
    assert math.degrees(reply.speed_radps) == pytest.approx(-500.0)
    assert math.degrees(reply.angle_rad) == pytest.approx(-45.0)


@pytest.mark.parametrize(("data", "dps"), [("A2 00 00 00 10 27 00 00", 100.0), ("A2 00 00 00 F0 D8 FF FF", -100.0)])
def test_speed_command_examples_are_the_same_in_both_versions(data: str, dps: float) -> None:
    request = RmdRequest(1, RmdCommand.SPEED_CONTROL, math.radians(dps))
    for protocol in (PROTOCOL_V1, PROTOCOL_V4):
        msg = protocol.encode_request(request)
        assert msg.arbitration_id == 0x141 and bytes(msg.data) == bytes.fromhex(data)
        assert protocol.decode_request(msg) == request
        assert protocol.decode_any(msg) == request


def test_v4_echoes_and_the_id_tells_request_from_reply() -> None:
    stop = RmdRequest(2, RmdCommand.MOTOR_STOP)
    echo = PROTOCOL_V4.encode_reply(AckReply(2, RmdCommand.MOTOR_STOP))
    assert echo.arbitration_id == 0x242 and bytes(echo.data) == bytes(stop.encode().data)
    assert PROTOCOL_V4.decode_any(echo) == AckReply(2, RmdCommand.MOTOR_STOP)
    assert PROTOCOL_V4.decode_any(stop.encode()) == stop
    read = RmdRequest(2, RmdCommand.READ_STATUS_1)
    assert PROTOCOL_V4.decode_any(read.encode()) == read


# -- V1.61: frames built from the field tables -----------------------------------------------------------


def test_v1_status1_from_the_field_table() -> None:
    reply = PROTOCOL_V1.decode_reply(frame(0x141, "9A 32 00 E5 01 00 00 01"))
    assert reply == Status1Reply(1, RmdCommand.READ_STATUS_1, 50, 48.5, MotorErrorFlags.UNDER_VOLTAGE)
    over_temperature = PROTOCOL_V1.decode_reply(frame(0x142, "9A 32 00 E5 01 00 00 08"))
    assert isinstance(over_temperature, Status1Reply) and over_temperature.errors == MotorErrorFlags.OVER_TEMPERATURE
    assert PROTOCOL_V1.error_text(over_temperature.errors) == "OVER_TEMPERATURE"


def test_v1_status2_from_the_field_table() -> None:
    reply = PROTOCOL_V1.decode_reply(frame(0x141, "9C 32 64 00 F4 01 2D 00"))
    assert isinstance(reply, Status2Reply)
    assert reply.temperature_c == 50 and reply.encoder == 45
    assert reply.current_a == pytest.approx(100 * 33 / 2048)  # V1.61 scale, not V4.2's 0.01 A
    assert math.degrees(reply.speed_radps) == pytest.approx(500.0)
    assert bytes(PROTOCOL_V1.encode_reply(reply).data) == bytes.fromhex("9C 32 64 00 F4 01 2D 00")


# -- IDs and commands ------------------------------------------------------------------------------------


def test_ids() -> None:
    assert (PROTOCOL_V1.request_id(1), PROTOCOL_V1.reply_id(1)) == (0x141, 0x141)
    assert (PROTOCOL_V4.request_id(1), PROTOCOL_V4.reply_id(1)) == (0x141, 0x241)
    assert PROTOCOL_V4.reply_id(32) == 0x260
    assert PROTOCOL_V4.motor_of(0x242) == 2 and PROTOCOL_V4.motor_of(0x142) == 2
    assert PROTOCOL_V1.motor_of(0x242) is None and PROTOCOL_V4.motor_of(0x261) is None
    assert PROTOCOL_V4.is_motor_id(0x241) and not PROTOCOL_V1.is_motor_id(0x241)
    assert PROTOCOL_V4.motor_of(0x140) is None and PROTOCOL_V4.motor_of(0x240) is None
    with pytest.raises(ProtocolError, match="motor id 33"):
        PROTOCOL_V4.reply_id(33)


def test_each_version_refuses_the_other_versions_commands() -> None:
    with pytest.raises(ProtocolError, match=r"0x141 RMD motor 1: MOTOR_RUN \(0x88\) is not a V4.2 command"):
        PROTOCOL_V4.encode_request(RmdRequest(1, RmdCommand.MOTOR_RUN))
    with pytest.raises(ProtocolError, match=r"CLEAR_ERRORS .* not a V4\.2 command"):
        PROTOCOL_V4.decode_request(RmdRequest(1, RmdCommand.CLEAR_ERRORS).encode())
    with pytest.raises(ProtocolError, match=r"SYSTEM_RESET .* not a V1\.61 command"):
        PROTOCOL_V1.encode_request(RmdRequest(1, RmdCommand.SYSTEM_RESET))
    with pytest.raises(ProtocolError, match=r"unknown command byte 0x76 for V1\.61"):
        PROTOCOL_V1.decode_request(frame(0x141, "76 00 00 00 00 00 00 00"))
    with pytest.raises(ProtocolError, match=r"0x241 RMD motor 1 \(V4\.2 reply\): unknown command byte 0x88"):
        PROTOCOL_V4.decode_reply(frame(0x241, "88 00 00 00 00 00 00 00"))
    assert bytes(PROTOCOL_V4.encode_request(RmdRequest(1, RmdCommand.SYSTEM_RESET)).data) == bytes.fromhex(
        "76 00 00 00 00 00 00 00")
    assert PROTOCOL_V1.run_command is RmdCommand.MOTOR_RUN and PROTOCOL_V4.run_command is None
    assert PROTOCOL_V1.clear_command is RmdCommand.CLEAR_ERRORS and PROTOCOL_V4.clear_command is None


def test_version_names() -> None:
    assert PROTOCOL_VERSIONS == ("v1", "v4")
    assert rmd_protocol("v4") is PROTOCOL_V4 and rmd_protocol(PROTOCOL_V1) is PROTOCOL_V1
    with pytest.raises(ProtocolError, match=r"unknown RMD protocol version 'v2': expected one of v1 \(V1.61\)"):
        rmd_protocol("v2")


@pytest.mark.parametrize(
    ("data", "problem"),
    [
        ("9A 32 00 01 E5 01", "wrong length 6"),
        ("30 01 00 00 00 00 80 3F", "unknown command byte 0x30"),  # a V4.2 command this robot does not decode
    ],
)
def test_bad_v4_replies_say_where(data: str, problem: str) -> None:
    with pytest.raises(ProtocolError, match=problem) as info:
        PROTOCOL_V4.decode_reply(frame(0x242, data))
    assert str(info.value).startswith("0x242 RMD motor 2 (V4.2 reply)")
    with pytest.raises(ProtocolError, match=r"0x141: not an RMD V4\.2 reply ID"):
        PROTOCOL_V4.decode_reply(frame(0x141, "9A 32 00 01 E5 01 04 00"))


# -- error flags -----------------------------------------------------------------------------------------


def test_every_v4_error_bit_has_a_flag_and_back() -> None:
    for bit, flag, _name in v4.V4_ERROR_BITS:
        assert v4.errors_from_wire(bit) == flag
        assert v4.errors_to_wire("here", flag) == bit
    # the document's example: 0x0016 = stall + low voltage + over current
    assert v4.errors_from_wire(0x0016) == (MotorErrorFlags.MOTOR_STALL | MotorErrorFlags.UNDER_VOLTAGE
                                           | MotorErrorFlags.OVER_CURRENT)


def test_an_unnamed_v4_bit_is_still_an_error() -> None:
    reply = PROTOCOL_V4.decode_reply(frame(0x241, "9A 32 00 00 F0 00 00 02"))  # error state 0x0200
    assert isinstance(reply, v4.V4Status1Reply)
    assert reply.errors and reply.error_code == 0x0200
    assert flag_names(reply.errors) == "V4.2 bit 0x0200"
    assert "unnamed bit" in PROTOCOL_V4.error_text(reply.errors)
    assert bytes(reply.encode().data) == bytes.fromhex("9A 32 00 00 F0 00 00 02")


def test_flags_a_version_cannot_carry_are_refused() -> None:
    with pytest.raises(ProtocolError, match=r"MOTOR_STALL do not fit V1\.61's error byte"):
        Status1Reply(1, RmdCommand.READ_STATUS_1, 30, 24.0, MotorErrorFlags.MOTOR_STALL)
    with pytest.raises(ProtocolError, match=r"0x02 have no V4\.2 error-state bit"):
        v4.V4Status1Reply(1, RmdCommand.READ_STATUS_1, 30, 24.0, MotorErrorFlags(0x02))


def test_level_two_errors_clear_themselves_only_in_v4() -> None:
    both = MotorErrorFlags.UNDER_VOLTAGE | MotorErrorFlags.MOTOR_STALL
    assert PROTOCOL_V4.self_clearing(both) == MotorErrorFlags.UNDER_VOLTAGE
    assert PROTOCOL_V1.self_clearing(both) == MotorErrorFlags.NONE


# -- what an emulated motor sends ------------------------------------------------------------------------


def reading(**changes: object) -> MotorReading:
    values: dict[str, object] = {"temperature_c": 31.4, "voltage_v": 24.0, "errors": MotorErrorFlags.NONE,
                                 "current_a": 1.5, "speed_radps": 2.0, "encoder": 123, "angle_rad": 1.0}
    values.update(changes)
    return MotorReading(**values)  # type: ignore[arg-type]


def test_replies_follow_the_version() -> None:
    r1 = PROTOCOL_V1.reply(1, RmdCommand.READ_STATUS_2, reading())
    r4 = PROTOCOL_V4.reply(1, RmdCommand.READ_STATUS_2, reading())
    assert isinstance(r1, Status2Reply) and r1.encoder == 123
    assert isinstance(r4, v4.V4Status2Reply) and r4.angle_rad == pytest.approx(math.radians(57))
    assert PROTOCOL_V4.reply(1, RmdCommand.SYSTEM_RESET, reading()) is None
    assert PROTOCOL_V1.reply(1, RmdCommand.MOTOR_RUN, reading()) == AckReply(1, RmdCommand.MOTOR_RUN)
    # V1.61 has no bit for a stall: such a motor reports what its byte can carry
    stalled = PROTOCOL_V1.reply(1, RmdCommand.READ_STATUS_1, reading(errors=MotorErrorFlags.MOTOR_STALL))
    assert isinstance(stalled, Status1Reply) and stalled.errors == MotorErrorFlags.NONE
    # V4.2's int16 angle wraps like the counter it is
    far = PROTOCOL_V4.reply(1, RmdCommand.READ_STATUS_2, reading(angle_rad=math.radians(32768 + 10)))
    assert isinstance(far, v4.V4Status2Reply) and math.degrees(far.angle_rad) == pytest.approx(-32758)


def test_a_reply_of_the_other_version_is_refused() -> None:
    with pytest.raises(ProtocolError, match=r"V4Status2Reply is not a V1\.61 reply"):
        PROTOCOL_V1.encode_reply(v4.V4Status2Reply(1, RmdCommand.READ_STATUS_2, 20, 0.0, 0.0, 0.0))
    with pytest.raises(ProtocolError, match=r"Status1Reply is not a V4\.2 reply"):
        PROTOCOL_V4.encode_reply(Status1Reply(1, RmdCommand.READ_STATUS_1, 20, 24.0, MotorErrorFlags.NONE))
    with pytest.raises(ProtocolError, match=r"MOTOR_RUN is not a V4\.2 command"):
        PROTOCOL_V4.encode_reply(AckReply(1, RmdCommand.MOTOR_RUN))


# -- round trips and robustness --------------------------------------------------------------------------

ids = st.integers(1, 32)
v4_errors = st.integers(0, 0xFFFF).map(v4.errors_from_wire)
v4_replies = st.one_of(
    st.builds(AckReply, ids, st.sampled_from([RmdCommand.MOTOR_OFF, RmdCommand.MOTOR_STOP])),
    st.builds(v4.V4Status1Reply, ids, st.just(RmdCommand.READ_STATUS_1), st.integers(-128, 127),
              st.floats(0, 6000), v4_errors, st.booleans()),
    st.builds(v4.V4Status2Reply, ids, st.sampled_from([RmdCommand.READ_STATUS_2, RmdCommand.SPEED_CONTROL]),
              st.integers(-128, 127), st.floats(-300, 300), st.floats(-500, 500), st.floats(-500, 500)),
)


@given(v4_replies)
def test_v4_replies_round_trip(reply: AckReply | v4.V4Status1Reply | v4.V4Status2Reply) -> None:
    msg = PROTOCOL_V4.encode_reply(reply)
    assert msg.arbitration_id == 0x240 + reply.motor_id
    assert PROTOCOL_V4.decode_reply(msg) == reply
    assert PROTOCOL_V4.decode_any(msg) == reply


@settings(max_examples=400)
@given(st.one_of(st.integers(0x141, 0x160), st.integers(0x241, 0x260)), st.binary(max_size=8))
def test_random_v4_frames_only_raise_protocol_error(arbitration_id: int, data: bytes) -> None:
    msg = can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False)
    try:
        PROTOCOL_V4.decode_any(msg)
    except ProtocolError as exc:
        assert f"0x{arbitration_id:03X}" in str(exc)
