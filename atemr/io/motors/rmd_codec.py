"""MyActuator RMD CAN protocol, as used by the RMD-L series (single-motor commands, protocol V1.x).

Requests and replies travel on the same standard ID, ``0x140 + motor id``, with 8 data bytes and the
command byte first. The commands this robot uses:

=========  =====================  ================================================================
command    request                reply
=========  =====================  ================================================================
0x80       motor off              echo of the request
0x81       motor stop             echo of the request
0x88       motor running          echo of the request
0x9A       read status 1          [1] temperature int8 °C, [3:5] voltage uint16 0.1 V, [7] error flags
0x9B       clear error flags      as 0x9A
0x9C       read status 2          [1] temperature int8 °C, [2:4] iq int16 (±2048 = ±33 A),
                                  [4:6] speed int16 1 dps, [6:8] encoder uint16 (14 bit)
0xA2       speed control,         as 0x9C
           [4:8] int32 0.01 dps
=========  =====================  ================================================================

All multi-byte fields are little-endian. Error flags: bit 0 under-voltage, bit 3 over-temperature.
The API speaks SI (rad/s, A, V, °C); protocol units stay inside this module. Values are quantised to
the wire resolution on construction so ``decode(encode(x)) == x``.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum, IntFlag
from typing import Any

import can

from atemr.errors import ProtocolError
from atemr.io.can.trusted import trusted_constructor

#: Requests and replies of motor ``n`` use ID ``RMD_BASE_ID + n``.
RMD_BASE_ID = 0x140
#: Motor ids the RMD-L accepts (set with MyActuator's tool).
MOTOR_IDS = range(1, 33)
#: 0.01 degree per second per LSB of the speed command.
SPEED_CMD_LSB_DPS = 0.01
#: Torque current: ±2048 LSB is ±33 A.
IQ_LSB_A = 33.0 / 2048.0
IQ_LIMIT = 2048
VOLTAGE_LSB_V = 0.1

_S_STATUS1 = struct.Struct("<BbBHBBB")
_S_STATUS2 = struct.Struct("<BbhhH")
_S_SPEED = struct.Struct("<B3xi")
_INT32 = (-(1 << 31), (1 << 31) - 1)


class RmdCommand(IntEnum):
    """The command byte (byte 0) of requests and replies."""

    MOTOR_OFF = 0x80
    MOTOR_STOP = 0x81
    MOTOR_RUN = 0x88
    READ_STATUS_1 = 0x9A
    CLEAR_ERRORS = 0x9B
    READ_STATUS_2 = 0x9C
    SPEED_CONTROL = 0xA2


class MotorErrorFlags(IntFlag):
    """Byte 7 of the status-1 reply; any set bit means the motor has switched its output off."""

    NONE = 0
    UNDER_VOLTAGE = 0x01
    OVER_TEMPERATURE = 0x08


_COMMANDS = {int(c): c for c in RmdCommand}
_ECHO = frozenset({RmdCommand.MOTOR_OFF, RmdCommand.MOTOR_STOP, RmdCommand.MOTOR_RUN})
_STATUS1 = frozenset({RmdCommand.READ_STATUS_1, RmdCommand.CLEAR_ERRORS})
_STATUS2 = frozenset({RmdCommand.READ_STATUS_2, RmdCommand.SPEED_CONTROL})


def motor_can_id(motor_id: int) -> int:
    """The CAN ID of motor ``motor_id``."""
    if motor_id not in MOTOR_IDS:
        raise ProtocolError(f"RMD motor id {motor_id!r} outside {MOTOR_IDS.start}..{MOTOR_IDS.stop - 1}")
    return RMD_BASE_ID + motor_id


def is_rmd_id(arbitration_id: int) -> bool:
    """True for the IDs 0x141–0x160 of RMD motors."""
    return arbitration_id - RMD_BASE_ID in MOTOR_IDS


def _where(motor_id: int) -> str:
    return f"0x{RMD_BASE_ID + motor_id:03X} RMD motor {motor_id}"


def _radps_to_cdps(speed_radps: float) -> int:
    return round(math.degrees(speed_radps) / SPEED_CMD_LSB_DPS)


def _cdps_to_radps(cdps: int) -> float:
    return math.radians(cdps * SPEED_CMD_LSB_DPS)


def _check_finite(motor_id: int, what: str, value: float) -> float:
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ProtocolError(f"{_where(motor_id)}: {what} must be a finite number, got {value!r}")
    return float(value)


def _check_id(motor_id: int) -> None:
    if not isinstance(motor_id, int) or motor_id not in MOTOR_IDS:
        raise ProtocolError(f"RMD motor id {motor_id!r} outside {MOTOR_IDS.start}..{MOTOR_IDS.stop - 1}")


@dataclass(frozen=True, slots=True)
class RmdRequest:
    """A request to motor ``motor_id``; ``speed_radps`` only for SPEED_CONTROL (quantised to 0.01 dps)."""

    motor_id: int
    command: RmdCommand
    speed_radps: float = 0.0

    def __post_init__(self) -> None:
        _check_id(self.motor_id)
        command = _COMMANDS.get(self.command)
        if command is None:
            raise ProtocolError(f"{_where(self.motor_id)}: unsupported command {self.command!r}")
        object.__setattr__(self, "command", command)
        speed = _check_finite(self.motor_id, "speed", self.speed_radps)
        if command is not RmdCommand.SPEED_CONTROL:
            if speed != 0.0:
                raise ProtocolError(f"{_where(self.motor_id)}: only SPEED_CONTROL carries a speed")
            return
        cdps = _radps_to_cdps(speed)
        if not _INT32[0] <= cdps <= _INT32[1]:
            raise ProtocolError(f"{_where(self.motor_id)}: speed {speed!r} rad/s does not fit the int32 command")
        object.__setattr__(self, "speed_radps", _cdps_to_radps(cdps))

    def encode(self) -> can.Message:
        if self.command is RmdCommand.SPEED_CONTROL:
            data = _S_SPEED.pack(self.command, _radps_to_cdps(self.speed_radps))
        else:
            data = bytes((self.command, 0, 0, 0, 0, 0, 0, 0))
        return can.Message(arbitration_id=RMD_BASE_ID + self.motor_id, data=bytearray(data), is_extended_id=False,
                           check=False)

    @classmethod
    def decode(cls, msg: can.Message) -> RmdRequest:
        motor_id, data = _checked(msg)
        command = _command(motor_id, data)
        if command is RmdCommand.SPEED_CONTROL:
            return _make_request(motor_id, command, _cdps_to_radps(_S_SPEED.unpack(data)[1]))
        return _make_request(motor_id, command, 0.0)

    def fields(self) -> dict[str, Any]:
        out: dict[str, Any] = {"motor": self.motor_id, "command": self.command.name}
        if self.command is RmdCommand.SPEED_CONTROL:
            out["speed_radps"] = self.speed_radps
        return out


@dataclass(frozen=True, slots=True)
class AckReply:
    """The echo a motor sends for MOTOR_OFF, MOTOR_STOP and MOTOR_RUN."""

    motor_id: int
    command: RmdCommand

    def __post_init__(self) -> None:
        _check_id(self.motor_id)
        if _COMMANDS.get(self.command) not in _ECHO:
            raise ProtocolError(f"{_where(self.motor_id)}: {self.command!r} is not answered by an echo")
        object.__setattr__(self, "command", _COMMANDS[self.command])

    def encode(self) -> can.Message:
        return can.Message(arbitration_id=RMD_BASE_ID + self.motor_id,
                           data=bytearray((self.command, 0, 0, 0, 0, 0, 0, 0)), is_extended_id=False, check=False)

    def fields(self) -> dict[str, Any]:
        return {"motor": self.motor_id, "command": self.command.name}


@dataclass(frozen=True, slots=True)
class Status1Reply:
    """Answer to READ_STATUS_1 and CLEAR_ERRORS: temperature (1 °C), supply voltage (0.1 V), error flags."""

    motor_id: int
    command: RmdCommand
    temperature_c: int
    voltage_v: float
    errors: MotorErrorFlags

    def __post_init__(self) -> None:
        _check_id(self.motor_id)
        if _COMMANDS.get(self.command) not in _STATUS1:
            raise ProtocolError(f"{_where(self.motor_id)}: {self.command!r} is not answered with status 1")
        object.__setattr__(self, "command", _COMMANDS[self.command])
        object.__setattr__(self, "temperature_c", _int8_temperature(self.motor_id, self.temperature_c))
        volts = _check_finite(self.motor_id, "voltage", self.voltage_v)
        raw = round(volts / VOLTAGE_LSB_V)
        if not 0 <= raw <= 0xFFFF:
            raise ProtocolError(f"{_where(self.motor_id)}: voltage {volts!r} V outside 0..6553.5 V")
        object.__setattr__(self, "voltage_v", raw * VOLTAGE_LSB_V)
        if not isinstance(self.errors, int) or not 0 <= self.errors <= 0xFF:
            raise ProtocolError(f"{_where(self.motor_id)}: error flags {self.errors!r} do not fit in a byte")
        object.__setattr__(self, "errors", MotorErrorFlags(self.errors))

    def encode(self) -> can.Message:
        data = _S_STATUS1.pack(self.command, self.temperature_c, 0, round(self.voltage_v / VOLTAGE_LSB_V), 0, 0,
                               self.errors)
        return can.Message(arbitration_id=RMD_BASE_ID + self.motor_id, data=bytearray(data), is_extended_id=False,
                           check=False)

    def fields(self) -> dict[str, Any]:
        return {"motor": self.motor_id, "command": self.command.name, "temperature_c": self.temperature_c,
                "voltage_v": round(self.voltage_v, 1), "errors": _flag_names(self.errors)}


@dataclass(frozen=True, slots=True)
class Status2Reply:
    """Answer to READ_STATUS_2 and SPEED_CONTROL: temperature, torque current, speed (1 dps), encoder."""

    motor_id: int
    command: RmdCommand
    temperature_c: int
    current_a: float
    speed_radps: float
    encoder: int

    def __post_init__(self) -> None:
        _check_id(self.motor_id)
        if _COMMANDS.get(self.command) not in _STATUS2:
            raise ProtocolError(f"{_where(self.motor_id)}: {self.command!r} is not answered with status 2")
        object.__setattr__(self, "command", _COMMANDS[self.command])
        object.__setattr__(self, "temperature_c", _int8_temperature(self.motor_id, self.temperature_c))
        iq = round(_check_finite(self.motor_id, "current", self.current_a) / IQ_LSB_A)
        if not -IQ_LIMIT <= iq <= IQ_LIMIT:
            raise ProtocolError(f"{_where(self.motor_id)}: torque current {self.current_a!r} A outside ±33 A")
        object.__setattr__(self, "current_a", iq * IQ_LSB_A)
        dps = round(math.degrees(_check_finite(self.motor_id, "speed", self.speed_radps)))
        if not -0x8000 <= dps <= 0x7FFF:
            raise ProtocolError(f"{_where(self.motor_id)}: speed {self.speed_radps!r} rad/s outside the int16 reply")
        object.__setattr__(self, "speed_radps", math.radians(dps))
        if not isinstance(self.encoder, int) or not 0 <= self.encoder <= 0xFFFF:
            raise ProtocolError(f"{_where(self.motor_id)}: encoder {self.encoder!r} outside 0..65535")

    def encode(self) -> can.Message:
        data = _S_STATUS2.pack(self.command, self.temperature_c, round(self.current_a / IQ_LSB_A),
                               round(math.degrees(self.speed_radps)), self.encoder)
        return can.Message(arbitration_id=RMD_BASE_ID + self.motor_id, data=bytearray(data), is_extended_id=False,
                           check=False)

    def fields(self) -> dict[str, Any]:
        return {"motor": self.motor_id, "command": self.command.name, "temperature_c": self.temperature_c,
                "current_a": round(self.current_a, 3), "speed_radps": round(self.speed_radps, 4),
                "encoder": self.encoder}


RmdReply = AckReply | Status1Reply | Status2Reply
RmdFrame = RmdRequest | RmdReply

# Decoders build from wire values, which are in range and quantised by construction.
_make_request = trusted_constructor(RmdRequest, "motor_id", "command", "speed_radps")
_make_ack = trusted_constructor(AckReply, "motor_id", "command")
_make_status1 = trusted_constructor(Status1Reply, "motor_id", "command", "temperature_c", "voltage_v", "errors")
_make_status2 = trusted_constructor(Status2Reply, "motor_id", "command", "temperature_c", "current_a", "speed_radps",
                                    "encoder")
_FLAGS = [MotorErrorFlags(i) for i in range(256)]


def _flag_names(flags: MotorErrorFlags) -> str:
    if not flags:
        return "none"
    names = [f.name for f in MotorErrorFlags if f and f in flags and f.name]
    unknown = int(flags) & ~int(MotorErrorFlags.UNDER_VOLTAGE | MotorErrorFlags.OVER_TEMPERATURE)
    if unknown:
        names.append(f"0x{unknown:02X}")
    return "|".join(names)


def _int8_temperature(motor_id: int, value: int) -> int:
    if not isinstance(value, int) or not -128 <= value <= 127:
        raise ProtocolError(f"{_where(motor_id)}: temperature {value!r} °C outside the int8 range")
    return value


def _checked(msg: can.Message) -> tuple[int, bytes | bytearray]:
    """Motor id and data of an RMD frame, after checking ID, frame kind and length."""
    motor_id = msg.arbitration_id - RMD_BASE_ID
    if motor_id not in MOTOR_IDS:
        raise ProtocolError(f"0x{msg.arbitration_id:03X}: not an RMD motor ID (0x141-0x160)")
    if msg.is_extended_id:
        raise ProtocolError(f"{_where(motor_id)}: extended (29-bit) ID, RMD motors use standard IDs")
    if msg.is_remote_frame or msg.is_error_frame:
        raise ProtocolError(f"{_where(motor_id)}: remote or error frame, expected a data frame")
    data = msg.data if msg.data is not None else b""  # bytearray: read without a copy
    if len(data) != 8:
        raise ProtocolError(f"{_where(motor_id)}: wrong length {len(data)} bytes, expected 8")
    return motor_id, data


def _command(motor_id: int, data: bytes | bytearray) -> RmdCommand:
    command = _COMMANDS.get(data[0])
    if command is None:
        raise ProtocolError(f"{_where(motor_id)}: unknown command byte 0x{data[0]:02X}")
    return command


def decode_request(msg: can.Message) -> RmdRequest:
    """Decode a frame sent to a motor."""
    return RmdRequest.decode(msg)


def decode_reply(msg: can.Message) -> RmdReply:
    """Decode a frame a motor sent back."""
    motor_id, data = _checked(msg)
    command = _command(motor_id, data)
    if command in _ECHO:
        return _make_ack(motor_id, command)
    if command in _STATUS1:
        _, temperature, _, voltage, _, _, errors = _S_STATUS1.unpack(data)
        return _make_status1(motor_id, command, temperature, voltage * VOLTAGE_LSB_V, _FLAGS[errors])
    _, temperature, iq, dps, encoder = _S_STATUS2.unpack(data)
    if not -IQ_LIMIT <= iq <= IQ_LIMIT:
        raise ProtocolError(f"{_where(motor_id)}: torque current {iq} LSB outside ±{IQ_LIMIT}")
    return _make_status2(motor_id, command, temperature, iq * IQ_LSB_A, math.radians(dps), encoder)


def decode_any(msg: can.Message) -> RmdFrame:
    """Decode a frame seen on the bus without knowing who sent it (``atemr can decode``).

    Requests and replies share the ID, so this guesses: a frame whose bytes 1–3 are zero is a request
    (a real reply carries the temperature in byte 1, and a status-1 reply the voltage in bytes 3–4).
    """
    motor_id, data = _checked(msg)
    command = _command(motor_id, data)
    quiet = data[1:4] == b"\x00\x00\x00" and (command is RmdCommand.SPEED_CONTROL or data[4:] == bytes(4))
    if command in _ECHO or quiet:
        return RmdRequest.decode(msg)
    return decode_reply(msg)
