"""One interface over the two RMD protocol versions the RMD-L ships with: V1.61 and V4.2.

The robot's setting ``devices.motors.protocol`` (``v1`` or ``v4``) names the version its motors speak;
`rmd_protocol` turns it into an `RmdProtocol`, which the driver, the emulator and ``atemr can decode``
share, so none of them has an ``if version`` of its own. What differs:

=====================  ============================  ===========================================
                       v1 (V1.61, `rmd_codec`)       v4 (V4.2, `rmd_v4`)
=====================  ============================  ===========================================
requests               0x140 + id                    0x140 + id (same bytes)
replies                0x140 + id                    0x240 + id
status 1 (0x9A)        voltage [3:5], errors [7]     brake [3], voltage [4:6], errors [6:8]
status 2 (0x9C, 0xA2)  iq ±2048 = ±33 A, encoder     iq 0.01 A, output-shaft angle (degrees)
motor running          0x88                          none: the next speed command resumes
clearing errors        0x9B (flags whose cause       none: level-2 errors clear by themselves,
                       is gone are cleared)          level 1 needs 0x76 system reset
=====================  ============================  ===========================================

Replies decode to SI units (°C, V, A, rad/s, rad) and `MotorErrorFlags`, the same for both versions, so the
driver judges them alike: any flag is a fault, and `RmdProtocol.error_text` names it for the message.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import lru_cache
from typing import Final

import can

from atemr.errors import ProtocolError
from atemr.io.motors import rmd_codec as v1
from atemr.io.motors import rmd_v4 as v4
from atemr.io.motors.rmd_codec import (
    MOTOR_IDS,
    RMD_BASE_ID,
    AckReply,
    MotorErrorFlags,
    RmdCommand,
    RmdRequest,
    check_motor_id,
    flag_names,
)

#: The values of the ``devices.motors.protocol`` setting.
PROTOCOL_VERSIONS: Final = ("v1", "v4")

#: Any reply of either version, decoded.
AnyReply = v1.RmdReply | v4.V4Reply
AnyFrame = RmdRequest | AnyReply


@dataclass(frozen=True)
class MotorReading:
    """What a motor knows about itself, in SI units: what an emulator's reply is built from (`RmdProtocol.reply`).

    ``encoder`` is the 14-bit single-turn reading V1.61 sends, ``angle_rad`` the output-shaft angle V4.2 sends.
    """

    temperature_c: float
    voltage_v: float
    errors: MotorErrorFlags
    current_a: float
    speed_radps: float
    encoder: int
    angle_rad: float


class RmdProtocol(ABC):
    """One protocol version: its IDs, the commands it knows, and the codec of its frames.

    ``run_command`` is what switches a stopped motor back on (None: the next speed command does), and
    ``clear_command`` what clears its error flags (None: they clear by themselves, see `self_clearing`).
    """

    version: str
    title: str
    reply_base_id: int
    commands: frozenset[RmdCommand]
    run_command: RmdCommand | None
    clear_command: RmdCommand | None

    def request_id(self, motor_id: int) -> int:
        """The CAN ID requests to motor ``motor_id`` use (0x140 + id in both versions)."""
        check_motor_id(motor_id)
        return RMD_BASE_ID + motor_id

    def reply_id(self, motor_id: int) -> int:
        """The CAN ID motor ``motor_id`` answers on."""
        check_motor_id(motor_id)
        return self.reply_base_id + motor_id

    def motor_of(self, arbitration_id: int) -> int | None:
        """The motor whose requests or replies use ``arbitration_id``, or None for any other ID."""
        for base in (RMD_BASE_ID, self.reply_base_id):
            if arbitration_id - base in MOTOR_IDS:
                return arbitration_id - base
        return None

    def is_motor_id(self, arbitration_id: int) -> bool:
        """True when ``arbitration_id`` carries requests to or replies from a motor in this version."""
        return self.motor_of(arbitration_id) is not None

    def encode_request(self, request: RmdRequest) -> can.Message:
        """``request`` as a frame, refused when this version has no such command (0x88 in V4.2, 0x76 in V1.61)."""
        if request.command not in self.commands:
            raise ProtocolError(f"0x{RMD_BASE_ID + request.motor_id:03X} RMD motor {request.motor_id}: "
                                f"{request.command.name} (0x{request.command:02X}) is not a {self.title} command")
        return request.encode()

    @abstractmethod
    def decode_request(self, msg: can.Message) -> RmdRequest:
        """Decode a frame sent to a motor; a command this version does not know is a `ProtocolError`."""

    @abstractmethod
    def decode_reply(self, msg: can.Message) -> AnyReply:
        """Decode a frame a motor sent back."""

    @abstractmethod
    def decode_any(self, msg: can.Message) -> AnyFrame:
        """Decode a motor frame seen on the bus without knowing who sent it (``atemr can decode``)."""

    @abstractmethod
    def encode_reply(self, reply: AnyReply) -> can.Message:
        """The frame a motor of this version sends for ``reply``."""

    @abstractmethod
    def reply(self, motor_id: int, command: RmdCommand, reading: MotorReading) -> AnyReply | None:
        """The reply a motor of this version sends to ``command`` in the state ``reading`` (None: it sends none).

        Values beyond what the wire carries are saturated, as the motor's firmware would send them.
        """

    def self_clearing(self, errors: MotorErrorFlags) -> MotorErrorFlags:
        """Those of ``errors`` the motor clears by itself once their cause is gone (none in V1.61)."""
        return MotorErrorFlags.NONE

    def error_text(self, errors: MotorErrorFlags) -> str:
        """``errors`` named for a log line or a fault message."""
        return flag_names(errors)

    def __repr__(self) -> str:
        return f"<RMD protocol {self.version} ({self.title})>"


# A reply is an immutable value, and a motor that stands still answers each command with the same one tick after
# tick: each is built (and checked) once per distinct value, not a hundred times a second.
_ack = lru_cache(maxsize=64)(AckReply)
_v1_status1 = lru_cache(maxsize=64)(v1.Status1Reply)
_v1_status2 = lru_cache(maxsize=64)(v1.Status2Reply)
_v4_status1 = lru_cache(maxsize=64)(v4.V4Status1Reply)
_v4_status2 = lru_cache(maxsize=64)(v4.V4Status2Reply)


def _int8(value: float) -> int:
    return max(-128, min(127, round(value)))


def _clamp(value: float, limit: float) -> float:
    return max(-limit, min(limit, value))


class V1Protocol(RmdProtocol):
    """V1.61: requests and replies on ``0x140 + id`` (`atemr.io.motors.rmd_codec`)."""

    version = "v1"
    title = "V1.61"
    reply_base_id = RMD_BASE_ID
    commands = v1.V1_COMMANDS
    run_command = RmdCommand.MOTOR_RUN
    clear_command = RmdCommand.CLEAR_ERRORS

    def decode_request(self, msg: can.Message) -> RmdRequest:
        return v1.decode_v1_request(msg)

    def decode_reply(self, msg: can.Message) -> AnyReply:
        return v1.decode_reply(msg)

    def decode_any(self, msg: can.Message) -> AnyFrame:
        return v1.decode_any(msg)

    def encode_reply(self, reply: AnyReply) -> can.Message:
        if not isinstance(reply, v1.AckReply | v1.Status1Reply | v1.Status2Reply):
            raise ProtocolError(f"RMD motor {reply.motor_id}: {type(reply).__name__} is not a V1.61 reply")
        return reply.encode()

    def reply(self, motor_id: int, command: RmdCommand, reading: MotorReading) -> AnyReply | None:
        if command in (RmdCommand.MOTOR_OFF, RmdCommand.MOTOR_STOP, RmdCommand.MOTOR_RUN):
            return _ack(motor_id, command)
        temperature = _int8(reading.temperature_c)
        if command in (RmdCommand.READ_STATUS_1, RmdCommand.CLEAR_ERRORS):
            errors = MotorErrorFlags(int(reading.errors) & 0xFF)  # V1.61 has no bit for the others
            return _v1_status1(motor_id, command, temperature, max(0.0, min(6553.5, reading.voltage_v)), errors)
        if command in (RmdCommand.READ_STATUS_2, RmdCommand.SPEED_CONTROL):
            return _v1_status2(motor_id, command, temperature, _clamp(reading.current_a, 33.0), reading.speed_radps,
                               reading.encoder)
        return None


class V4Protocol(RmdProtocol):
    """V4.2: requests on ``0x140 + id``, replies on ``0x240 + id`` (`atemr.io.motors.rmd_v4`)."""

    version = "v4"
    title = "V4.2"
    reply_base_id = v4.RMD_V4_REPLY_BASE_ID
    commands = v4.V4_COMMANDS
    run_command = None
    clear_command = None

    def decode_request(self, msg: can.Message) -> RmdRequest:
        return v4.decode_v4_request(msg)

    def decode_reply(self, msg: can.Message) -> AnyReply:
        return v4.decode_v4_reply(msg)

    def decode_any(self, msg: can.Message) -> AnyFrame:
        return v4.decode_v4_any(msg)

    def encode_reply(self, reply: AnyReply) -> can.Message:
        if isinstance(reply, AckReply):
            return v4.encode_ack(reply)
        if not isinstance(reply, v4.V4Status1Reply | v4.V4Status2Reply):
            raise ProtocolError(f"RMD motor {reply.motor_id}: {type(reply).__name__} is not a V4.2 reply")
        return reply.encode()

    def reply(self, motor_id: int, command: RmdCommand, reading: MotorReading) -> AnyReply | None:
        if command in (RmdCommand.MOTOR_OFF, RmdCommand.MOTOR_STOP):
            return _ack(motor_id, command)
        temperature = _int8(reading.temperature_c)
        if command is RmdCommand.READ_STATUS_1:
            return _v4_status1(motor_id, command, temperature, max(0.0, min(6553.5, reading.voltage_v)), reading.errors)
        if command in (RmdCommand.READ_STATUS_2, RmdCommand.SPEED_CONTROL):
            return _v4_status2(motor_id, command, temperature, _clamp(reading.current_a, 327.67), reading.speed_radps,
                               _int16_angle(reading.angle_rad))
        return None  # SYSTEM_RESET: the motor restarts without a reply

    def self_clearing(self, errors: MotorErrorFlags) -> MotorErrorFlags:
        return errors & v4.V4_SELF_CLEARING

    def error_text(self, errors: MotorErrorFlags) -> str:
        return v4.error_text(errors)


def _int16_angle(angle_rad: float) -> float:
    """The angle an int16 degree counter shows: V4.2's ±32767° range wraps around like the counter it is.

    The document gives the range but not what happens beyond it; wrapping is this emulator's assumption.
    """
    degrees = round(math.degrees(angle_rad))
    wrapped = (degrees + 0x8000) % 0x10000 - 0x8000
    return math.radians(wrapped)


PROTOCOL_V1: Final = V1Protocol()
PROTOCOL_V4: Final = V4Protocol()
_BY_VERSION: dict[str, RmdProtocol] = {p.version: p for p in (PROTOCOL_V1, PROTOCOL_V4)}


def rmd_protocol(version: str | RmdProtocol) -> RmdProtocol:
    """The protocol named by ``version`` (``v1`` or ``v4``, the ``devices.motors.protocol`` setting)."""
    if isinstance(version, RmdProtocol):
        return version
    protocol = _BY_VERSION.get(version)
    if protocol is None:
        known = ", ".join(f"{p.version} ({p.title})" for p in _BY_VERSION.values())
        raise ProtocolError(f"unknown RMD protocol version {version!r}: expected one of {known}")
    return protocol
