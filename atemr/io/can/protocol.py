"""The primary ⇄ secondary core CAN protocol: IDs 0x150–0x157 as typed messages (thesis 3.6;
docs/can.md#the-inter-core-protocol-0x1500x157).

Every message is a small frozen value object with ``encode() -> can.Message`` and a class method
``decode(msg)``; `decode` dispatches any frame by its ID. Decoders check the ID, the frame kind
(standard data frame), the length and every value, and raise only `ProtocolError` naming the ID and the
problem, so a corrupted frame never reaches the agent as a plausible value.

Values are validated when a message is built, so an invalid message cannot be encoded either. Floats
are rounded to float32 on construction so that ``decode(m.encode()) == m`` holds exactly. The values the
bytes carry (state codes, status bits, the power handshake) are domain types, `atemr.domain.status`: the
agent speaks them without importing this codec.
"""

from __future__ import annotations

import ipaddress
import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any, ClassVar, Self

import can

from atemr.domain.status import AgentBits, HardwareBits, PowerRequest, PowerState, StateCode
from atemr.errors import ProtocolError
from atemr.io.can.trusted import trusted_constructor


class CanId(IntEnum):
    """The standard 11-bit IDs of the inter-core protocol."""

    POWER = 0x150
    IR_FRONT = 0x151
    IR_REAR = 0x152
    PRIMARY_STATUS = 0x153
    WIFI_SSID = 0x154
    WIFI_PASSWORD = 0x155
    IP_ADDRESS = 0x156
    HEARTBEAT = 0x157


#: Human names of the IDs, for error messages and the bus monitor.
ID_NAMES: dict[int, str] = {
    CanId.POWER: "power",
    CanId.IR_FRONT: "IR front",
    CanId.IR_REAR: "IR rear",
    CanId.PRIMARY_STATUS: "primary status",
    CanId.WIFI_SSID: "WiFi SSID",
    CanId.WIFI_PASSWORD: "WiFi password",
    CanId.IP_ADDRESS: "IP address",
    CanId.HEARTBEAT: "heartbeat",
}


_AGENT_USED = int(AgentBits.HEARTBEAT | AgentBits.HARDWARE | AgentBits.AUTO | AgentBits.CONNECTIVITY
                  | AgentBits.LOCALIZATION)
_F32 = struct.Struct("<f")
_F32X2 = struct.Struct("<ff")
_STATE_BY_CODE = {int(s): s for s in StateCode}
_POWER_STATE_BY_CODE = {int(s): s for s in PowerState}
_POWER_REQ_BY_CODE = {int(s): s for s in PowerRequest}


def id_name(arbitration_id: int) -> str:
    """``0x153 primary status`` for known IDs, ``0x123`` otherwise."""
    name = ID_NAMES.get(arbitration_id)
    return f"0x{arbitration_id:03X} {name}" if name else f"0x{arbitration_id:03X}"


def _error(arbitration_id: int, problem: str) -> ProtocolError:
    return ProtocolError(f"{id_name(arbitration_id)}: {problem}")


def _frame(arbitration_id: int, data: bytes) -> can.Message:
    # a bytearray is kept as is by can.Message; bytes would be copied into one
    return can.Message(arbitration_id=arbitration_id, data=bytearray(data), is_extended_id=False, check=False)


def _payload(msg: can.Message, arbitration_id: int, lengths: tuple[int, ...]) -> bytes | bytearray:
    """The frame's data after checking ID, frame kind and length."""
    if msg.arbitration_id != arbitration_id:
        raise _error(arbitration_id, f"got a frame with ID 0x{msg.arbitration_id:X}")
    if msg.is_extended_id:
        raise _error(arbitration_id, "extended (29-bit) ID, the protocol uses standard IDs")
    if msg.is_remote_frame or msg.is_error_frame:
        raise _error(arbitration_id, "remote or error frame, expected a data frame")
    data = msg.data if msg.data is not None else b""  # bytearray: struct and indexing read it without a copy
    if len(data) not in lengths:
        want = " or ".join(str(n) for n in lengths)
        raise _error(arbitration_id, f"wrong length {len(data)} bytes, expected {want}")
    return data


def _distance_cm(arbitration_id: int, what: str, value: float) -> float:
    """A float32-rounded, finite, non-negative distance."""
    try:
        rounded: float = _F32.unpack(_F32.pack(value))[0]
    except (struct.error, TypeError, OverflowError):
        raise _error(arbitration_id, f"{what} must be a float32 number, got {value!r}") from None
    if not (math.isfinite(rounded) and rounded >= 0.0):
        raise _error(arbitration_id, f"{what} must be a finite distance >= 0 cm, got {value!r}")
    return rounded


@dataclass(frozen=True, slots=True)
class Power:
    """0x150: power handshake. The primary writes ``state``, the secondary ``request``."""

    arbitration_id: ClassVar[int] = CanId.POWER
    state: PowerState = PowerState.INITIALISING
    request: PowerRequest = PowerRequest.NORMAL

    def __post_init__(self) -> None:
        state = _POWER_STATE_BY_CODE.get(self.state)
        if state is None:
            raise _error(self.arbitration_id, f"byte 0 power state {self.state!r} is not one of 0, 1, 2")
        request = _POWER_REQ_BY_CODE.get(self.request)
        if request is None:
            raise _error(self.arbitration_id, f"byte 1 power request {self.request!r} is not one of 0, 1")
        object.__setattr__(self, "state", state)
        object.__setattr__(self, "request", request)

    def encode(self) -> can.Message:
        return _frame(self.arbitration_id, bytes((self.state, self.request)))

    @classmethod
    def decode(cls, msg: can.Message) -> Power:
        data = _payload(msg, cls.arbitration_id, (2,))
        state = _POWER_STATE_BY_CODE.get(data[0])
        request = _POWER_REQ_BY_CODE.get(data[1])
        if state is None or request is None:
            return cls(data[0], data[1])  # type: ignore[arg-type]  # raises, naming the bad byte
        return _make_power(state, request)

    def fields(self) -> dict[str, Any]:
        return {"state": self.state.name, "request": self.request.name}


@dataclass(frozen=True, slots=True)
class IrFront:
    """0x151: the two front (cliff) IR distances, float32 little-endian, in cm."""

    arbitration_id: ClassVar[int] = CanId.IR_FRONT
    left_cm: float
    right_cm: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "left_cm", _distance_cm(self.arbitration_id, "left distance", self.left_cm))
        object.__setattr__(self, "right_cm", _distance_cm(self.arbitration_id, "right distance", self.right_cm))

    def encode(self) -> can.Message:
        return _frame(self.arbitration_id, _F32X2.pack(self.left_cm, self.right_cm))

    @classmethod
    def decode(cls, msg: can.Message) -> IrFront:
        left, right = _F32X2.unpack(_payload(msg, cls.arbitration_id, (8,)))
        if not (0.0 <= left < math.inf and 0.0 <= right < math.inf):  # also false for NaN
            return cls(left, right)  # raises, naming the bad value
        return _make_ir_front(left, right)

    def fields(self) -> dict[str, Any]:
        return {"left_cm": self.left_cm, "right_cm": self.right_cm}


@dataclass(frozen=True, slots=True)
class IrRear:
    """0x152: the rear (cliff) IR distance, float32 little-endian, in cm."""

    arbitration_id: ClassVar[int] = CanId.IR_REAR
    distance_cm: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "distance_cm", _distance_cm(self.arbitration_id, "distance", self.distance_cm))

    def encode(self) -> can.Message:
        return _frame(self.arbitration_id, _F32.pack(self.distance_cm))

    @classmethod
    def decode(cls, msg: can.Message) -> IrRear:
        distance = _F32.unpack(_payload(msg, cls.arbitration_id, (4,)))[0]
        if not 0.0 <= distance < math.inf:
            return cls(distance)  # raises, naming the bad value
        return _make_ir_rear(distance)

    def fields(self) -> dict[str, Any]:
        return {"distance_cm": self.distance_cm}


@dataclass(frozen=True, slots=True)
class PrimaryStatus:
    """0x153: what the primary core tells the secondary core's OPS screen.

    ``agent`` and ``hardware`` are flags (a set bit means OK; ``AgentBits.AUTO`` means auto mode),
    ``state`` the lifecycle state. Bits 5–7 of byte 0 are reserved and must be zero.
    """

    arbitration_id: ClassVar[int] = CanId.PRIMARY_STATUS
    agent: AgentBits = AgentBits.NONE
    hardware: HardwareBits = HardwareBits.NONE
    state: StateCode = StateCode.UNDEFINED

    def __post_init__(self) -> None:
        agent, hardware = int(self.agent), int(self.hardware)
        if not 0 <= agent <= 0xFF or agent & ~_AGENT_USED:
            raise _error(self.arbitration_id, f"byte 0 agent bits 0x{agent:X}: only bits 0-4 are defined")
        if not 0 <= hardware <= 0xFF:
            raise _error(self.arbitration_id, f"byte 1 hardware bits 0x{hardware:X} do not fit in a byte")
        state = _STATE_BY_CODE.get(self.state)
        if state is None:
            known = ", ".join(f"0x{s:02X} {s.name}" for s in StateCode)
            raise _error(self.arbitration_id, f"byte 2 state code {self.state!r} is not one of {known}")
        object.__setattr__(self, "agent", AgentBits(agent))
        object.__setattr__(self, "hardware", HardwareBits(hardware))
        object.__setattr__(self, "state", state)

    def encode(self) -> can.Message:
        return _frame(self.arbitration_id, bytes((self.agent, self.hardware, self.state)))

    @classmethod
    def decode(cls, msg: can.Message) -> PrimaryStatus:
        data = _payload(msg, cls.arbitration_id, (3,))
        state = _STATE_BY_CODE.get(data[2])
        if state is None or data[0] & ~_AGENT_USED:
            return cls(data[0], data[1], data[2])  # type: ignore[arg-type]  # raises, naming the bad byte
        return _make_status(_AGENT_FLAGS[data[0]], _HARDWARE_FLAGS[data[1]], state)

    @property
    def auto_mode(self) -> bool:
        """True in AUTO mode, False in MANUAL mode (bit 2 of byte 0)."""
        return AgentBits.AUTO in self.agent

    def agent_ok(self) -> dict[str, bool]:
        """Every agent bit by name (``{"HEARTBEAT": True, ...}``)."""
        return {str(b.name): b in self.agent for b in AgentBits if b}

    def hardware_ok(self) -> dict[str, bool]:
        """Every hardware bit by name (``{"LEFT_MOTOR": True, ...}``)."""
        return {str(b.name): b in self.hardware for b in HardwareBits if b}

    def fields(self) -> dict[str, Any]:
        return {**{f"agent.{k}": v for k, v in self.agent_ok().items()},
                **{f"hardware.{k}": v for k, v in self.hardware_ok().items()},
                "state": self.state.name}


#: Bit 7 of a segment's control byte: this is the transfer's last frame.
SEGMENT_LAST = 0x80
#: Data bytes per segment frame (one control byte + seven data bytes).
SEGMENT_DATA = 7
#: Highest frame index the 7-bit counter can carry.
SEGMENT_MAX_INDEX = 0x7F


@dataclass(frozen=True, slots=True)
class _Segment:
    """One frame of a segmented text transfer (0x154 SSID, 0x155 password): see `atemr.io.can.segmented`."""

    arbitration_id: ClassVar[int]
    index: int
    last: bool
    data: bytes = field(default=bytes(SEGMENT_DATA))

    def __post_init__(self) -> None:
        if not isinstance(self.index, int) or not 0 <= self.index <= SEGMENT_MAX_INDEX:
            raise _error(self.arbitration_id, f"segment index {self.index!r} outside 0..{SEGMENT_MAX_INDEX}")
        if not isinstance(self.data, (bytes, bytearray)) or len(self.data) != SEGMENT_DATA:
            raise _error(self.arbitration_id, f"segment data must be {SEGMENT_DATA} bytes, got {self.data!r}")
        object.__setattr__(self, "last", bool(self.last))
        object.__setattr__(self, "data", bytes(self.data))

    def encode(self) -> can.Message:
        control = self.index | (SEGMENT_LAST if self.last else 0)
        return _frame(self.arbitration_id, bytes((control,)) + self.data)

    @classmethod
    def decode(cls, msg: can.Message) -> Self:
        data = _payload(msg, cls.arbitration_id, (8,))
        return cls(data[0] & SEGMENT_MAX_INDEX, bool(data[0] & SEGMENT_LAST), bytes(data[1:]))

    def fields(self) -> dict[str, Any]:
        return {"index": self.index, "last": self.last, "data": self.data.hex()}


@dataclass(frozen=True, slots=True)
class WifiSsidSegment(_Segment):
    """0x154: one frame of the WiFi SSID transfer."""

    arbitration_id: ClassVar[int] = CanId.WIFI_SSID


@dataclass(frozen=True, slots=True)
class WifiPasswordSegment(_Segment):
    """0x155: one frame of the WiFi password transfer."""

    arbitration_id: ClassVar[int] = CanId.WIFI_PASSWORD


@dataclass(frozen=True, slots=True)
class IpRequest:
    """0x156 with no data: the secondary core asks for the primary core's IP address."""

    arbitration_id: ClassVar[int] = CanId.IP_ADDRESS

    def encode(self) -> can.Message:
        return _frame(self.arbitration_id, b"")

    @classmethod
    def decode(cls, msg: can.Message) -> IpRequest:
        _payload(msg, cls.arbitration_id, (0,))
        return cls()

    def fields(self) -> dict[str, Any]:
        return {}


@dataclass(frozen=True, slots=True)
class IpAddress:
    """0x156 with four bytes: the primary core's IPv4 address, first octet first."""

    arbitration_id: ClassVar[int] = CanId.IP_ADDRESS
    address: ipaddress.IPv4Address

    def __post_init__(self) -> None:
        try:
            address = ipaddress.IPv4Address(self.address)
        except (ValueError, TypeError) as exc:
            raise _error(self.arbitration_id, f"not an IPv4 address: {self.address!r} ({exc})") from None
        object.__setattr__(self, "address", address)

    def encode(self) -> can.Message:
        return _frame(self.arbitration_id, self.address.packed)

    @classmethod
    def decode(cls, msg: can.Message) -> IpAddress:
        return cls(ipaddress.IPv4Address(bytes(_payload(msg, cls.arbitration_id, (4,)))))

    def fields(self) -> dict[str, Any]:
        return {"address": str(self.address)}


@dataclass(frozen=True, slots=True)
class Heartbeat:
    """0x157: the primary sends 0x01 (``from_primary``), the secondary answers 0x00."""

    arbitration_id: ClassVar[int] = CanId.HEARTBEAT
    from_primary: bool

    def __post_init__(self) -> None:
        object.__setattr__(self, "from_primary", bool(self.from_primary))

    def encode(self) -> can.Message:
        return _frame(self.arbitration_id, b"\x01" if self.from_primary else b"\x00")

    @classmethod
    def decode(cls, msg: can.Message) -> Heartbeat:
        value = _payload(msg, cls.arbitration_id, (1,))[0]
        if value > 1:
            raise _error(cls.arbitration_id, f"value 0x{value:02X} is neither 0x01 (primary) nor 0x00 (secondary)")
        return _HEARTBEATS[value]

    def fields(self) -> dict[str, Any]:
        return {"from_primary": self.from_primary}


# Decoders build from checked wire values without validating twice (see atemr.io.can.trusted).
_make_power = trusted_constructor(Power, "state", "request")
_make_ir_front = trusted_constructor(IrFront, "left_cm", "right_cm")
_make_ir_rear = trusted_constructor(IrRear, "distance_cm")
_make_status = trusted_constructor(PrimaryStatus, "agent", "hardware", "state")
_AGENT_FLAGS = [AgentBits(i) for i in range(_AGENT_USED + 1)]
_HARDWARE_FLAGS = [HardwareBits(i) for i in range(256)]
_HEARTBEATS = (Heartbeat(False), Heartbeat(True))  # immutable, so shared

Message = Power | IrFront | IrRear | PrimaryStatus | WifiSsidSegment | WifiPasswordSegment | IpRequest | IpAddress \
    | Heartbeat
#: Every message class of the protocol, for contract tests and tools.
MESSAGE_TYPES: tuple[type, ...] = (
    Power, IrFront, IrRear, PrimaryStatus, WifiSsidSegment, WifiPasswordSegment, IpRequest, IpAddress, Heartbeat,
)


def _decode_ip(msg: can.Message) -> Message:
    data = msg.data
    return IpRequest.decode(msg) if data is None or len(data) == 0 else IpAddress.decode(msg)


_DECODERS: dict[int, Callable[[can.Message], Message]] = {
    CanId.POWER: Power.decode,
    CanId.IR_FRONT: IrFront.decode,
    CanId.IR_REAR: IrRear.decode,
    CanId.PRIMARY_STATUS: PrimaryStatus.decode,
    CanId.WIFI_SSID: WifiSsidSegment.decode,
    CanId.WIFI_PASSWORD: WifiPasswordSegment.decode,
    CanId.IP_ADDRESS: _decode_ip,
    CanId.HEARTBEAT: Heartbeat.decode,
}


def is_protocol_id(arbitration_id: int) -> bool:
    """True for the IDs 0x150–0x157 this module decodes."""
    return arbitration_id in _DECODERS


def decode(msg: can.Message) -> Message:
    """Decode any frame of the inter-core protocol; anything else raises `ProtocolError`."""
    decoder = _DECODERS.get(msg.arbitration_id)
    if decoder is None:
        raise ProtocolError(f"0x{msg.arbitration_id:03X}: not an ID of the inter-core protocol (0x150-0x157)")
    if msg.is_extended_id:  # 0x150 as a 29-bit ID is a different frame, not ours
        raise _error(msg.arbitration_id, "extended (29-bit) ID, the protocol uses standard IDs")
    return decoder(msg)
