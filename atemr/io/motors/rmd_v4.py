"""MyActuator RMD protocol V4.2 (RMD-L with driver V3): the replies that differ from V1.61.

Requests are the same bytes on the same ID as in V1.61 (`rmd_codec.RmdRequest`, ``0x140 + id``), but a
V4.2 motor answers on ``0x240 + id`` and lays its status replies out differently. MyActuator's
"Servo Motor Control Protocol V4.2" (driver V3, 2024-05), the commands this robot uses:

=========  =====================  ===================================================================
command    request                V4.2 reply (on 0x240 + id)
=========  =====================  ===================================================================
0x80       motor off              echo of the request
0x81       motor stop             echo of the request
0x9A       read status 1          [1] temperature int8 °C, [3] brake released (1) / locked (0),
                                  [4:6] voltage uint16 0.1 V, [6:8] error state uint16
0x9C       read status 2          [1] temperature int8 °C, [2:4] iq int16 0.01 A,
                                  [4:6] speed int16 1 dps, [6:8] output-shaft angle int16 1 degree
0xA2       speed control,         as 0x9C
           [4:8] int32 0.01 dps
0x76       system reset           none: the motor restarts
=========  =====================  ===================================================================

There is no 0x88 (motor running: the next speed command resumes after 0x81) and no 0x9B (clear errors).
The error state bits (`V4_ERROR_BITS`) map onto `MotorErrorFlags`. The document's section 8 sorts them into
level 2 (`V4_SELF_CLEARING`: under/over-voltage, power overrun, speeding, over-temperature, encoder
calibration), which the motor clears by itself once the cause is gone, and level 1 (stall, over-current,
calibration parameter error), which need the motor checked and restarted (0x76 or a power cycle).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import can

from atemr.errors import ProtocolError
from atemr.io.can.trusted import trusted_constructor
from atemr.io.motors.rmd_codec import (
    MOTOR_IDS,
    RMD_BASE_ID,
    V4_UNKNOWN_SHIFT,
    AckReply,
    MotorErrorFlags,
    RmdCommand,
    RmdRequest,
    check_finite,
    check_frame,
    check_motor_id,
    decode_request,
    flag_names,
    int8_temperature,
    make_ack,
)

#: V4.2 replies of motor ``n`` come on ``RMD_V4_REPLY_BASE_ID + n``.
RMD_V4_REPLY_BASE_ID = 0x240
#: V4.2 torque current and its reply range: int16 in 0.01 A.
V4_IQ_LSB_A = 0.01
V4_VOLTAGE_LSB_V = 0.1
_INT16 = (-0x8000, 0x7FFF)

#: The commands a V4.2 motor knows, of those this robot uses.
V4_COMMANDS = frozenset({RmdCommand.MOTOR_OFF, RmdCommand.MOTOR_STOP, RmdCommand.READ_STATUS_1,
                         RmdCommand.READ_STATUS_2, RmdCommand.SPEED_CONTROL, RmdCommand.SYSTEM_RESET})
#: V4.2 error-state bit → flag, and the document's name for it (section 2.14, table "System_errorState").
V4_ERROR_BITS: tuple[tuple[int, MotorErrorFlags, str], ...] = (
    (0x0002, MotorErrorFlags.MOTOR_STALL, "motor stall"),
    (0x0004, MotorErrorFlags.UNDER_VOLTAGE, "low voltage"),
    (0x0008, MotorErrorFlags.OVER_VOLTAGE, "over voltage"),
    (0x0010, MotorErrorFlags.OVER_CURRENT, "over current"),
    (0x0040, MotorErrorFlags.POWER_OVERRUN, "power overrun"),
    (0x0080, MotorErrorFlags.CALIBRATION_WRITE_ERROR, "calibration parameter writing error"),
    (0x0100, MotorErrorFlags.SPEEDING, "speeding"),
    (0x1000, MotorErrorFlags.OVER_TEMPERATURE, "motor temperature over temperature"),
    (0x2000, MotorErrorFlags.ENCODER_CALIBRATION_ERROR, "encoder calibration error"),
)
#: Level-2 errors (section 8.2): the motor resumes by itself once the cause is gone.
V4_SELF_CLEARING = (MotorErrorFlags.UNDER_VOLTAGE | MotorErrorFlags.OVER_VOLTAGE | MotorErrorFlags.POWER_OVERRUN
                    | MotorErrorFlags.SPEEDING | MotorErrorFlags.OVER_TEMPERATURE
                    | MotorErrorFlags.ENCODER_CALIBRATION_ERROR)
_WIRE_MASK = sum(bit for bit, _, _ in V4_ERROR_BITS)
_FLAG_MASK = sum(int(flag) for _, flag, _ in V4_ERROR_BITS)

_S_STATUS1 = struct.Struct("<BbBBHH")
_S_STATUS2 = struct.Struct("<Bbhhh")
_ECHO = frozenset({RmdCommand.MOTOR_OFF, RmdCommand.MOTOR_STOP})
_STATUS2 = frozenset({RmdCommand.READ_STATUS_2, RmdCommand.SPEED_CONTROL})
_REPLY_COMMANDS = {int(c): c for c in _ECHO | _STATUS2 | {RmdCommand.READ_STATUS_1}}
_REQUEST_COMMANDS = {int(c) for c in V4_COMMANDS}


def v4_reply_id(motor_id: int) -> int:
    """The CAN ID a V4.2 motor ``motor_id`` answers on."""
    check_motor_id(motor_id)
    return RMD_V4_REPLY_BASE_ID + motor_id


def is_v4_reply_id(arbitration_id: int) -> bool:
    """True for the IDs 0x241–0x260 of V4.2 replies."""
    return arbitration_id - RMD_V4_REPLY_BASE_ID in MOTOR_IDS


@lru_cache(maxsize=64)
def _where(motor_id: int) -> str:
    """Where a reply's error lies (made once per motor, as `rmd_codec._where`)."""
    return f"0x{RMD_V4_REPLY_BASE_ID + motor_id:03X} RMD motor {motor_id} (V4.2 reply)"


@lru_cache(maxsize=256)
def errors_from_wire(code: int) -> MotorErrorFlags:
    """The flags of a V4.2 error state; a bit the document does not name is kept (shifted, see `MotorErrorFlags`)."""
    flags = MotorErrorFlags.NONE
    for bit, flag, _ in V4_ERROR_BITS:
        if code & bit:
            flags |= flag
    return flags | MotorErrorFlags((code & ~_WIRE_MASK) << V4_UNKNOWN_SHIFT)


def errors_to_wire(where: str, flags: int) -> int:
    """The V4.2 error state of ``flags``; a `ProtocolError` at ``where`` for a bit V4.2 cannot carry."""
    named = int(flags) & _FLAG_MASK
    unknown = int(flags) >> V4_UNKNOWN_SHIFT
    stray = int(flags) & ~_FLAG_MASK & ((1 << V4_UNKNOWN_SHIFT) - 1)
    if stray or unknown > 0xFFFF or unknown & _WIRE_MASK:
        raise ProtocolError(f"{where}: error flags {flag_names(flags)} have no V4.2 error-state bit")
    code = unknown
    for bit, flag, _ in V4_ERROR_BITS:
        if named & flag:
            code |= bit
    return code


def error_text(flags: int) -> str:
    """``UNDER_VOLTAGE (V4.2 0x0004 low voltage)``: the flags with the document's code and name, for messages."""
    if not flags:
        return "none"
    try:
        code = errors_to_wire("", flags)
    except ProtocolError:
        return flag_names(flags)
    names = [name for bit, _, name in V4_ERROR_BITS if code & bit]
    if code & ~_WIRE_MASK:
        names.append("unnamed bit")
    return f"{flag_names(flags)} (V4.2 0x{code:04X} {', '.join(names)})"


@dataclass(frozen=True, slots=True)
class V4Status1Reply:
    """V4.2 answer to READ_STATUS_1: temperature (1 °C), brake state, supply voltage (0.1 V), error flags."""

    motor_id: int
    command: RmdCommand
    temperature_c: int
    voltage_v: float
    errors: MotorErrorFlags
    brake_released: bool = False

    def __post_init__(self) -> None:
        check_motor_id(self.motor_id)
        where = _where(self.motor_id)
        if self.command != RmdCommand.READ_STATUS_1:
            raise ProtocolError(f"{where}: {self.command!r} is not answered with status 1 in V4.2")
        object.__setattr__(self, "command", RmdCommand.READ_STATUS_1)
        object.__setattr__(self, "temperature_c", int8_temperature(where, self.temperature_c))
        volts = check_finite(where, "voltage", self.voltage_v)
        raw = round(volts / V4_VOLTAGE_LSB_V)
        if not 0 <= raw <= 0xFFFF:
            raise ProtocolError(f"{where}: voltage {volts!r} V outside 0..6553.5 V")
        object.__setattr__(self, "voltage_v", raw * V4_VOLTAGE_LSB_V)
        if not isinstance(self.errors, int) or self.errors < 0:
            raise ProtocolError(f"{where}: error flags {self.errors!r} are not MotorErrorFlags")
        errors_to_wire(where, self.errors)
        object.__setattr__(self, "errors", MotorErrorFlags(self.errors))
        object.__setattr__(self, "brake_released", bool(self.brake_released))

    @property
    def error_code(self) -> int:
        """The error state as the motor sends it (bytes 6–7)."""
        return errors_to_wire(_where(self.motor_id), self.errors)

    def encode(self) -> can.Message:
        data = _S_STATUS1.pack(self.command, self.temperature_c, 0, int(self.brake_released),
                               round(self.voltage_v / V4_VOLTAGE_LSB_V), self.error_code)
        return _frame(self.motor_id, data)

    def fields(self) -> dict[str, Any]:
        return {"motor": self.motor_id, "command": self.command.name, "temperature_c": self.temperature_c,
                "voltage_v": round(self.voltage_v, 1), "brake_released": self.brake_released,
                "errors": flag_names(self.errors), "error_code": f"0x{self.error_code:04X}"}


@dataclass(frozen=True, slots=True)
class V4Status2Reply:
    """V4.2 answer to READ_STATUS_2 and SPEED_CONTROL: temperature, torque current (0.01 A), speed (1 dps) and
    output-shaft angle (1 degree, int16, as radians here)."""

    motor_id: int
    command: RmdCommand
    temperature_c: int
    current_a: float
    speed_radps: float
    angle_rad: float

    def __post_init__(self) -> None:
        check_motor_id(self.motor_id)
        where = _where(self.motor_id)
        if self.command not in _STATUS2:
            raise ProtocolError(f"{where}: {self.command!r} is not answered with status 2")
        object.__setattr__(self, "command", RmdCommand(self.command))
        object.__setattr__(self, "temperature_c", int8_temperature(where, self.temperature_c))
        iq = _int16(where, "torque current", check_finite(where, "current", self.current_a) / V4_IQ_LSB_A, "A",
                    self.current_a)
        object.__setattr__(self, "current_a", iq * V4_IQ_LSB_A)
        speed = check_finite(where, "speed", self.speed_radps)
        dps = _int16(where, "speed", math.degrees(speed), "rad/s", speed)
        object.__setattr__(self, "speed_radps", math.radians(dps))
        angle = check_finite(where, "angle", self.angle_rad)
        degrees = _int16(where, "angle", math.degrees(angle), "rad", angle)
        object.__setattr__(self, "angle_rad", math.radians(degrees))

    def encode(self) -> can.Message:
        data = _S_STATUS2.pack(self.command, self.temperature_c, round(self.current_a / V4_IQ_LSB_A),
                               round(math.degrees(self.speed_radps)), round(math.degrees(self.angle_rad)))
        return _frame(self.motor_id, data)

    def fields(self) -> dict[str, Any]:
        return {"motor": self.motor_id, "command": self.command.name, "temperature_c": self.temperature_c,
                "current_a": round(self.current_a, 2), "speed_radps": round(self.speed_radps, 4),
                "angle_rad": round(self.angle_rad, 4)}


V4Reply = AckReply | V4Status1Reply | V4Status2Reply

# Decoders build from wire values, which are in range and quantised by construction.
_make_status1 = trusted_constructor(V4Status1Reply, "motor_id", "command", "temperature_c", "voltage_v", "errors",
                                    "brake_released")
_make_status2 = trusted_constructor(V4Status2Reply, "motor_id", "command", "temperature_c", "current_a",
                                    "speed_radps", "angle_rad")


def _int16(where: str, what: str, lsb: float, unit: str, given: float) -> int:
    raw = round(lsb)
    if not _INT16[0] <= raw <= _INT16[1]:
        raise ProtocolError(f"{where}: {what} {given!r} {unit} outside the int16 reply")
    return raw


def _frame(motor_id: int, data: bytes) -> can.Message:
    return can.Message(arbitration_id=RMD_V4_REPLY_BASE_ID + motor_id, data=bytearray(data), is_extended_id=False,
                       check=False)


def encode_ack(reply: AckReply) -> can.Message:
    """The V4.2 echo of MOTOR_OFF or MOTOR_STOP, on ``0x240 + id`` (V4.2 has no MOTOR_RUN to echo)."""
    if reply.command not in _ECHO:
        raise ProtocolError(f"{_where(reply.motor_id)}: {reply.command.name} is not a V4.2 command")
    return reply.encode_on(RMD_V4_REPLY_BASE_ID + reply.motor_id)


def decode_v4_request(msg: can.Message) -> RmdRequest:
    """Decode a frame sent to a V4.2 motor: a command V4.2 does not have (0x88, 0x9B) is a `ProtocolError`."""
    request = decode_request(msg)
    if request.command not in _REQUEST_COMMANDS:
        where = f"0x{RMD_BASE_ID + request.motor_id:03X} RMD motor {request.motor_id}"
        raise ProtocolError(f"{where}: {request.command.name} (0x{request.command:02X}) is not a V4.2 command")
    return request


def decode_v4_reply(msg: can.Message) -> V4Reply:
    """Decode a frame a V4.2 motor sent back (on 0x241–0x260)."""
    motor_id = msg.arbitration_id - RMD_V4_REPLY_BASE_ID
    if motor_id not in MOTOR_IDS:
        raise ProtocolError(f"0x{msg.arbitration_id:03X}: not an RMD V4.2 reply ID (0x241-0x260)")
    where = _where(motor_id)
    data = check_frame(msg, motor_id, where)
    command = _REPLY_COMMANDS.get(data[0])
    if command is None:
        raise ProtocolError(f"{where}: unknown command byte 0x{data[0]:02X} for a V4.2 reply")
    if command in _ECHO:
        return make_ack(motor_id, command)
    if command is RmdCommand.READ_STATUS_1:
        _, temperature, _, brake, voltage, code = _S_STATUS1.unpack(data)
        return _make_status1(motor_id, command, temperature, voltage * V4_VOLTAGE_LSB_V, errors_from_wire(code),
                             bool(brake))
    _, temperature, iq, dps, degrees = _S_STATUS2.unpack(data)
    return _make_status2(motor_id, command, temperature, iq * V4_IQ_LSB_A, math.radians(dps), math.radians(degrees))


def decode_v4_any(msg: can.Message) -> RmdRequest | V4Reply:
    """Decode a V4.2 frame seen on the bus: the ID tells a request (0x141–0x160) from a reply (0x241–0x260)."""
    if is_v4_reply_id(msg.arbitration_id):
        return decode_v4_reply(msg)
    return decode_v4_request(msg)
