"""The shipped DBC describes the bus: cantools decodes codec output to the same values."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.io.can import protocol as p
from atemr.io.can.dbc import dbc_path, load_database
from atemr.io.motors import rmd_codec as r
from atemr.io.motors import rmd_v4 as v4

DB = load_database()


def cantools_values(message: Any) -> dict[str, Any]:
    msg = message.encode()
    return dict(DB.decode_message(msg.arbitration_id, bytes(msg.data), decode_choices=False))


def test_dbc_ships_and_covers_every_id() -> None:
    assert dbc_path().is_file()
    ids = {m.frame_id for m in DB.messages}
    assert {int(i) for i in p.CanId} | {0x141, 0x142} <= ids
    assert all(not m.is_extended_frame for m in DB.messages)


def test_state_names_match_the_enum() -> None:
    choices = DB.get_message_by_name("PRIMARY_STATUS").get_signal_by_name("state").choices
    assert {int(k): str(v) for k, v in choices.items()} == {int(s): s.name for s in p.StateCode}


@settings(max_examples=60)
@given(st.integers(0, 0x1F), st.integers(0, 0xFF), st.sampled_from(list(p.StateCode)))
def test_status(agent: int, hardware: int, state: p.StateCode) -> None:
    status = p.PrimaryStatus(p.AgentBits(agent), p.HardwareBits(hardware), state)
    values = cantools_values(status)
    assert values["state"] == state
    names = ["heartbeat", "hardware", "auto", "connectivity", "localization"]
    assert [values[f"agent_{n}"] for n in names] == [int(b in status.agent) for b in p.AgentBits if b]
    hw = ["left_motor", "right_motor", "imu", "lidar", "camera", "webserver", "ir_front", "ir_rear"]
    assert [values[f"hw_{n}"] for n in hw] == [int(b in status.hardware) for b in p.HardwareBits if b]


@settings(max_examples=60)
@given(st.floats(0, 1000, width=32), st.floats(0, 1000, width=32))
def test_ir(left: float, right: float) -> None:
    assert cantools_values(p.IrFront(left, right)) == {"left_cm": left, "right_cm": right}
    assert cantools_values(p.IrRear(left)) == {"distance_cm": left}


def test_power_heartbeat_ip_segments() -> None:
    assert cantools_values(p.Power(p.PowerState.POWER_OFF_ACK, p.PowerRequest.POWER_OFF)) == {"state": 2, "request": 1}
    assert cantools_values(p.Heartbeat(True)) == {"value": 1}
    assert cantools_values(p.IpAddress("192.168.4.1")) == {  # type: ignore[arg-type]
        "octet_1": 192, "octet_2": 168, "octet_3": 4, "octet_4": 1}
    seg = p.WifiPasswordSegment(3, True, b"abc\x00\x00\x00\x00")
    assert cantools_values(seg) == {"index": 3, "last": 1, "data": int.from_bytes(seg.data, "little")}


@settings(max_examples=60)
@given(st.integers(1, 2), st.floats(-50, 50), st.integers(-128, 127), st.floats(-33, 33), st.integers(0, 16383),
       st.floats(0, 60), st.integers(0, 255))
def test_rmd_frames(
    motor: int, speed: float, temp: int, current: float, encoder: int, volts: float, flags: int
) -> None:
    req = r.RmdRequest(motor, r.RmdCommand.SPEED_CONTROL, speed)
    assert cantools_values(req)["speed_setpoint"] == pytest.approx(math.degrees(req.speed_radps), abs=1e-6)
    s2 = r.Status2Reply(motor, r.RmdCommand.READ_STATUS_2, temp, current, speed, encoder)
    v2 = cantools_values(s2)
    assert v2["s2_temperature"] == temp and v2["s2_encoder"] == encoder
    assert v2["s2_torque_current"] == pytest.approx(s2.current_a)
    assert v2["s2_speed"] == pytest.approx(math.degrees(s2.speed_radps))
    s1 = r.Status1Reply(motor, r.RmdCommand.READ_STATUS_1, temp, volts, r.MotorErrorFlags(flags))
    v1 = cantools_values(s1)
    assert v1["s1_voltage"] == pytest.approx(s1.voltage_v) and v1["s1_error_flags"] == flags


def test_dbc_names_the_protocol_versions() -> None:
    assert "V1.61" in DB.get_message_by_name("RMD_MOTOR_1").comment
    assert "V4.2" in DB.get_message_by_name("RMD_V4_REPLY_1").comment
    assert {m.frame_id for m in DB.messages} >= {0x241, 0x242}


def test_rmd_v4_document_examples() -> None:
    s1 = dict(DB.decode_message(0x241, bytes.fromhex("9A 32 00 01 E5 01 04 00"), decode_choices=False))
    assert s1 == {"command": 0x9A, "s1_temperature": 50, "s1_brake_released": 1, "s1_voltage": pytest.approx(48.5),
                  "s1_error_state": 0x0004}
    s2 = dict(DB.decode_message(0x242, bytes.fromhex("A2 32 64 00 F4 01 2D 00"), decode_choices=False))
    assert s2 == {"command": 0xA2, "s2_temperature": 50, "s2_torque_current": pytest.approx(1.0), "s2_speed": 500,
                  "s2_angle": 45}


@settings(max_examples=60)
@given(st.integers(1, 2), st.integers(-128, 127), st.floats(-300, 300), st.floats(-500, 500), st.floats(-500, 500),
       st.floats(0, 60), st.integers(0, 0xFFFF), st.booleans())
def test_rmd_v4_replies(
    motor: int, temp: int, current: float, speed: float, angle: float, volts: float, code: int, brake: bool
) -> None:
    s2 = v4.V4Status2Reply(motor, r.RmdCommand.READ_STATUS_2, temp, current, speed, angle)
    v2 = cantools_values(s2)
    assert v2["s2_temperature"] == temp and v2["s2_torque_current"] == pytest.approx(s2.current_a)
    assert v2["s2_speed"] == pytest.approx(math.degrees(s2.speed_radps))
    assert v2["s2_angle"] == pytest.approx(math.degrees(s2.angle_rad))
    s1 = v4.V4Status1Reply(motor, r.RmdCommand.READ_STATUS_1, temp, volts, v4.errors_from_wire(code), brake)
    v1 = cantools_values(s1)
    assert v1["s1_voltage"] == pytest.approx(s1.voltage_v) and v1["s1_error_state"] == code
    assert v1["s1_brake_released"] == int(brake)
