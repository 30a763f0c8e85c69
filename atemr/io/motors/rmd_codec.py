"""MyActuator RMD CAN protocol V1.61, as the RMD-L series ships it (driver V1/V2), and what both versions share.

This module is the V1.61 codec (its API predates V4.2 support and keeps working unchanged); the V4.2
codec is `atemr.io.motors.rmd_v4`, and `atemr.io.motors.rmd_protocol` puts both behind one interface
(`RmdProtocol`) that the driver, the emulator and ``atemr can decode`` use. Shared here: the command
bytes (`RmdCommand`), requests (`RmdRequest`: both versions send the same bytes to the same ID), the
version-independent error flags (`MotorErrorFlags`) and the echo reply (`AckReply`).

V1.61: requests and replies travel on the same standard ID, ``0x140 + motor id``, with 8 data bytes and
the command byte first. The commands this robot uses:

=========  =====================  ================================================================
command    request                V1.61 reply
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

All multi-byte fields are little-endian. V1.61 error flags (byte 7): bit 0 under-voltage, bit 3
over-temperature. The API speaks SI (rad/s, A, V, °C); protocol units stay inside the codecs. Values are
quantised to the wire resolution on construction so ``decode(encode(x)) == x``.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum, IntFlag
from functools import lru_cache
from typing import Any

import can

from atemr.errors import ProtocolError
from atemr.io.can.trusted import trusted_constructor

#: Requests (both versions) and V1.61 replies of motor ``n`` use ID ``RMD_BASE_ID + n``.
RMD_BASE_ID = 0x140
#: Motor ids the RMD-L accepts (set with MyActuator's tool).
MOTOR_IDS = range(1, 33)
#: 0.01 degree per second per LSB of the speed command.
SPEED_CMD_LSB_DPS = 0.01
#: V1.61 torque current: ±2048 LSB is ±33 A.
IQ_LSB_A = 33.0 / 2048.0
IQ_LIMIT = 2048
VOLTAGE_LSB_V = 0.1

_S_STATUS1 = struct.Struct("<BbBHBBB")
_S_STATUS2 = struct.Struct("<BbhhH")
_S_SPEED = struct.Struct("<B3xi")
_INT32 = (-(1 << 31), (1 << 31) - 1)


class RmdCommand(IntEnum):
    """The command byte (byte 0) of requests and replies, of either version (`V1_COMMANDS`, `rmd_v4.V4_COMMANDS`)."""

    MOTOR_OFF = 0x80
    MOTOR_STOP = 0x81
    MOTOR_RUN = 0x88  # V1.61 only: in V4.2 the next speed command resumes
    READ_STATUS_1 = 0x9A
    CLEAR_ERRORS = 0x9B  # V1.61 only: V4.2 errors clear by themselves, or with SYSTEM_RESET
    READ_STATUS_2 = 0x9C
    SPEED_CONTROL = 0xA2
    SYSTEM_RESET = 0x76  # V4.2 only: the motor restarts and sends no reply


class MotorErrorFlags(IntFlag):
    """What a motor reports as wrong, whatever its protocol version: any set bit means it has switched its output off.

    The two V1.61 flags keep their wire values, so a V1.61 error byte (0x9A reply, byte 7) *is* its flags, and a
    bit V1.61 does not name stays set as itself. V4.2's uint16 error state maps bit by bit onto these names
    (`atemr.io.motors.rmd_v4`); a V4.2 bit its document does not name is kept shifted by `V4_UNKNOWN_SHIFT`.
    Either way an unnamed bit still counts as an error, and `flag_names` shows it.
    """

    NONE = 0
    UNDER_VOLTAGE = 0x01  # V1.61 bit 0, V4.2 0x0004 "low voltage"
    OVER_TEMPERATURE = 0x08  # V1.61 bit 3, V4.2 0x1000 "motor temperature over temperature"
    MOTOR_STALL = 0x100  # V4.2 0x0002
    OVER_VOLTAGE = 0x200  # V4.2 0x0008
    OVER_CURRENT = 0x400  # V4.2 0x0010
    POWER_OVERRUN = 0x800  # V4.2 0x0040
    CALIBRATION_WRITE_ERROR = 0x1000  # V4.2 0x0080 "calibration parameter writing error"
    SPEEDING = 0x2000  # V4.2 0x0100
    ENCODER_CALIBRATION_ERROR = 0x4000  # V4.2 0x2000


#: A V4.2 error bit without a name in `MotorErrorFlags` is kept as ``bit << V4_UNKNOWN_SHIFT``.
V4_UNKNOWN_SHIFT = 16
_NAMED = [f for f in MotorErrorFlags if f]
_NAMED_MASK = sum(int(f) for f in _NAMED)
#: The commands V1.61 knows, of those this robot uses.
V1_COMMANDS = frozenset(RmdCommand) - {RmdCommand.SYSTEM_RESET}
_COMMANDS = {int(c): c for c in RmdCommand}
_V1_COMMANDS = {int(c): c for c in V1_COMMANDS}
_ECHO = frozenset({RmdCommand.MOTOR_OFF, RmdCommand.MOTOR_STOP, RmdCommand.MOTOR_RUN})
_STATUS1 = frozenset({RmdCommand.READ_STATUS_1, RmdCommand.CLEAR_ERRORS})
_STATUS2 = frozenset({RmdCommand.READ_STATUS_2, RmdCommand.SPEED_CONTROL})


def flag_names(flags: int) -> str:
    """``UNDER_VOLTAGE|OVER_TEMPERATURE`` for log lines; ``none`` when clear, unnamed bits in hex.

    An unnamed bit below 0x100 is a V1.61 bit (shown as ``0x02``), one at `V4_UNKNOWN_SHIFT` and above a
    V4.2 bit (shown as ``V4.2 bit 0x0200``), so the message points at the right document.
    """
    flags = int(flags)
    if not flags:
        return "none"
    names = [str(f.name) for f in _NAMED if flags & f]
    v1_unknown = flags & 0xFF & ~_NAMED_MASK
    if v1_unknown:
        names.append(f"0x{v1_unknown:02X}")
    v4_unknown = flags >> V4_UNKNOWN_SHIFT
    if v4_unknown:
        names.append(f"V4.2 bit 0x{v4_unknown:04X}")
    return "|".join(names)


def motor_can_id(motor_id: int) -> int:
    """The CAN ID requests to motor ``motor_id`` use (in V1.61 also its replies)."""
    if motor_id not in MOTOR_IDS:
        raise ProtocolError(f"RMD motor id {motor_id!r} outside {MOTOR_IDS.start}..{MOTOR_IDS.stop - 1}")
    return RMD_BASE_ID + motor_id


def is_rmd_id(arbitration_id: int) -> bool:
    """True for the IDs 0x141–0x160 of RMD motor requests (and V1.61 replies)."""
    return arbitration_id - RMD_BASE_ID in MOTOR_IDS


@lru_cache(maxsize=64)
def _where(motor_id: int) -> str:
    """Where a frame's error lies: its ID and motor. Every frame names its motor before it is checked: the name is
    made once per motor, not on every frame."""
    return f"0x{RMD_BASE_ID + motor_id:03X} RMD motor {motor_id}"


def _radps_to_cdps(speed_radps: float) -> int:
    return round(math.degrees(speed_radps) / SPEED_CMD_LSB_DPS)


def _cdps_to_radps(cdps: int) -> float:
    return math.radians(cdps * SPEED_CMD_LSB_DPS)


def check_finite(where: str, what: str, value: float) -> float:
    """``value`` as a float, or a `ProtocolError` at ``where`` when it is not a finite number."""
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ProtocolError(f"{where}: {what} must be a finite number, got {value!r}")
    return float(value)


def check_motor_id(motor_id: int) -> None:
    """A `ProtocolError` unless ``motor_id`` is one the RMD-L accepts (1–32)."""
    if not isinstance(motor_id, int) or motor_id not in MOTOR_IDS:
        raise ProtocolError(f"RMD motor id {motor_id!r} outside {MOTOR_IDS.start}..{MOTOR_IDS.stop - 1}")


def int8_temperature(where: str, value: int) -> int:
    """``value`` if it fits the int8 °C both versions send, else a `ProtocolError` at ``where``."""
    if not isinstance(value, int) or not -128 <= value <= 127:
        raise ProtocolError(f"{where}: temperature {value!r} °C outside the int8 range")
    return value


@dataclass(frozen=True, slots=True)
class RmdRequest:
    """A request to motor ``motor_id``; ``speed_radps`` only for SPEED_CONTROL (quantised to 0.01 dps).

    Both protocol versions send a request as the same bytes on the same ID (``0x140 + id``); which commands
    a motor understands depends on its version (`V1_COMMANDS`, `rmd_v4.V4_COMMANDS`), which `RmdProtocol`
    checks.
    """

    motor_id: int
    command: RmdCommand
    speed_radps: float = 0.0

    def __post_init__(self) -> None:
        check_motor_id(self.motor_id)
        command = _COMMANDS.get(self.command)
        if command is None:
            raise ProtocolError(f"{_where(self.motor_id)}: unsupported command {self.command!r}")
        object.__setattr__(self, "command", command)
        speed = check_finite(_where(self.motor_id), "speed", self.speed_radps)
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
        """A request frame of either version (``RmdProtocol.decode_request`` also checks the version has it)."""
        motor_id, data = _checked(msg)
        return _request_from(motor_id, _command(motor_id, data, _COMMANDS), data)

    def fields(self) -> dict[str, Any]:
        out: dict[str, Any] = {"motor": self.motor_id, "command": self.command.name}
        if self.command is RmdCommand.SPEED_CONTROL:
            out["speed_radps"] = self.speed_radps
        return out


@dataclass(frozen=True, slots=True)
class AckReply:
    """The echo a motor sends for MOTOR_OFF, MOTOR_STOP and (V1.61) MOTOR_RUN; `encode` gives the V1.61 frame."""

    motor_id: int
    command: RmdCommand

    def __post_init__(self) -> None:
        check_motor_id(self.motor_id)
        if _COMMANDS.get(self.command) not in _ECHO:
            raise ProtocolError(f"{_where(self.motor_id)}: {self.command!r} is not answered by an echo")
        object.__setattr__(self, "command", _COMMANDS[self.command])

    def encode(self) -> can.Message:
        return self.encode_on(RMD_BASE_ID + self.motor_id)

    def encode_on(self, arbitration_id: int) -> can.Message:
        """The echo on ``arbitration_id`` (V1.61 replies on the request's ID, V4.2 on ``0x240 + id``)."""
        return can.Message(arbitration_id=arbitration_id, data=bytearray((self.command, 0, 0, 0, 0, 0, 0, 0)),
                           is_extended_id=False, check=False)

    def fields(self) -> dict[str, Any]:
        return {"motor": self.motor_id, "command": self.command.name}


@dataclass(frozen=True, slots=True)
class Status1Reply:
    """V1.61 answer to READ_STATUS_1 and CLEAR_ERRORS: temperature (1 °C), supply voltage (0.1 V), error flags.

    ``errors`` must fit V1.61's error byte: a flag only V4.2 reports (``MOTOR_STALL``, ...) is refused.
    """

    motor_id: int
    command: RmdCommand
    temperature_c: int
    voltage_v: float
    errors: MotorErrorFlags

    def __post_init__(self) -> None:
        check_motor_id(self.motor_id)
        where = _where(self.motor_id)
        if _COMMANDS.get(self.command) not in _STATUS1:
            raise ProtocolError(f"{where}: {self.command!r} is not answered with status 1")
        object.__setattr__(self, "command", _COMMANDS[self.command])
        object.__setattr__(self, "temperature_c", int8_temperature(where, self.temperature_c))
        volts = check_finite(where, "voltage", self.voltage_v)
        raw = round(volts / VOLTAGE_LSB_V)
        if not 0 <= raw <= 0xFFFF:
            raise ProtocolError(f"{where}: voltage {volts!r} V outside 0..6553.5 V")
        object.__setattr__(self, "voltage_v", raw * VOLTAGE_LSB_V)
        if not isinstance(self.errors, int) or not 0 <= self.errors <= 0xFF:
            shown = flag_names(self.errors) if isinstance(self.errors, int) and self.errors >= 0 else repr(self.errors)
            raise ProtocolError(f"{where}: error flags {shown} do not fit V1.61's error byte")
        object.__setattr__(self, "errors", MotorErrorFlags(self.errors))

    def encode(self) -> can.Message:
        data = _S_STATUS1.pack(self.command, self.temperature_c, 0, round(self.voltage_v / VOLTAGE_LSB_V), 0, 0,
                               self.errors)
        return can.Message(arbitration_id=RMD_BASE_ID + self.motor_id, data=bytearray(data), is_extended_id=False,
                           check=False)

    def fields(self) -> dict[str, Any]:
        return {"motor": self.motor_id, "command": self.command.name, "temperature_c": self.temperature_c,
                "voltage_v": round(self.voltage_v, 1), "errors": flag_names(self.errors)}


@dataclass(frozen=True, slots=True)
class Status2Reply:
    """V1.61 answer to READ_STATUS_2 and SPEED_CONTROL: temperature, torque current, speed (1 dps), encoder."""

    motor_id: int
    command: RmdCommand
    temperature_c: int
    current_a: float
    speed_radps: float
    encoder: int

    def __post_init__(self) -> None:
        check_motor_id(self.motor_id)
        where = _where(self.motor_id)
        if _COMMANDS.get(self.command) not in _STATUS2:
            raise ProtocolError(f"{where}: {self.command!r} is not answered with status 2")
        object.__setattr__(self, "command", _COMMANDS[self.command])
        object.__setattr__(self, "temperature_c", int8_temperature(where, self.temperature_c))
        iq = round(check_finite(where, "current", self.current_a) / IQ_LSB_A)
        if not -IQ_LIMIT <= iq <= IQ_LIMIT:
            raise ProtocolError(f"{where}: torque current {self.current_a!r} A outside ±33 A")
        object.__setattr__(self, "current_a", iq * IQ_LSB_A)
        dps = round(math.degrees(check_finite(where, "speed", self.speed_radps)))
        if not -0x8000 <= dps <= 0x7FFF:
            raise ProtocolError(f"{where}: speed {self.speed_radps!r} rad/s outside the int16 reply")
        object.__setattr__(self, "speed_radps", math.radians(dps))
        if not isinstance(self.encoder, int) or not 0 <= self.encoder <= 0xFFFF:
            raise ProtocolError(f"{where}: encoder {self.encoder!r} outside 0..65535")

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
make_ack = trusted_constructor(AckReply, "motor_id", "command")
_make_status1 = trusted_constructor(Status1Reply, "motor_id", "command", "temperature_c", "voltage_v", "errors")
_make_status2 = trusted_constructor(Status2Reply, "motor_id", "command", "temperature_c", "current_a", "speed_radps",
                                    "encoder")
_FLAGS = [MotorErrorFlags(i) for i in range(256)]


def check_frame(msg: can.Message, motor_id: int, where: str) -> bytes | bytearray:
    """The 8 data bytes of a motor frame whose ID gave ``motor_id``, after checking frame kind and length."""
    if msg.is_extended_id:
        raise ProtocolError(f"{where}: extended (29-bit) ID, RMD motors use standard IDs")
    if msg.is_remote_frame or msg.is_error_frame:
        raise ProtocolError(f"{where}: remote or error frame, expected a data frame")
    data = msg.data if msg.data is not None else b""  # bytearray: read without a copy
    if len(data) != 8:
        raise ProtocolError(f"{where}: wrong length {len(data)} bytes, expected 8")
    return data


def _checked(msg: can.Message) -> tuple[int, bytes | bytearray]:
    """Motor id and data of a frame on 0x141-0x160, after checking ID, frame kind and length."""
    motor_id = msg.arbitration_id - RMD_BASE_ID
    if motor_id not in MOTOR_IDS:
        raise ProtocolError(f"0x{msg.arbitration_id:03X}: not an RMD motor ID (0x141-0x160)")
    return motor_id, check_frame(msg, motor_id, _where(motor_id))


def _command(motor_id: int, data: bytes | bytearray, known: dict[int, RmdCommand]) -> RmdCommand:
    command = known.get(data[0])
    if command is None:
        version = "" if known is _COMMANDS else " for V1.61"
        raise ProtocolError(f"{_where(motor_id)}: unknown command byte 0x{data[0]:02X}{version}")
    return command


def _request_from(motor_id: int, command: RmdCommand, data: bytes | bytearray) -> RmdRequest:
    if command is RmdCommand.SPEED_CONTROL:
        return _make_request(motor_id, command, _cdps_to_radps(_S_SPEED.unpack(data)[1]))
    return _make_request(motor_id, command, 0.0)


def decode_request(msg: can.Message) -> RmdRequest:
    """Decode a frame sent to a motor (either version: requests share their bytes and ID)."""
    return RmdRequest.decode(msg)


def decode_v1_request(msg: can.Message) -> RmdRequest:
    """Decode a frame sent to a V1.61 motor: a command V1.61 does not have (0x76) is a `ProtocolError`."""
    motor_id, data = _checked(msg)
    return _request_from(motor_id, _command(motor_id, data, _V1_COMMANDS), data)


def decode_reply(msg: can.Message) -> RmdReply:
    """Decode a frame a V1.61 motor sent back."""
    motor_id, data = _checked(msg)
    command = _command(motor_id, data, _V1_COMMANDS)
    if command in _ECHO:
        return make_ack(motor_id, command)
    if command in _STATUS1:
        _, temperature, _, voltage, _, _, errors = _S_STATUS1.unpack(data)
        return _make_status1(motor_id, command, temperature, voltage * VOLTAGE_LSB_V, _FLAGS[errors])
    _, temperature, iq, dps, encoder = _S_STATUS2.unpack(data)
    if not -IQ_LIMIT <= iq <= IQ_LIMIT:
        raise ProtocolError(f"{_where(motor_id)}: torque current {iq} LSB outside ±{IQ_LIMIT}")
    return _make_status2(motor_id, command, temperature, iq * IQ_LSB_A, math.radians(dps), encoder)


def decode_any(msg: can.Message) -> RmdFrame:
    """Decode a V1.61 frame seen on the bus without knowing who sent it (``atemr can decode``).

    Requests and replies share the ID, so this guesses: a frame whose bytes 1–3 are zero is a request
    (a real reply carries the temperature in byte 1, and a status-1 reply the voltage in bytes 3–4).
    """
    motor_id, data = _checked(msg)
    command = _command(motor_id, data, _V1_COMMANDS)
    quiet = data[1:4] == b"\x00\x00\x00" and (command is RmdCommand.SPEED_CONTROL or data[4:] == bytes(4))
    if command in _ECHO or quiet:
        return _request_from(motor_id, command, data)
    return decode_reply(msg)
