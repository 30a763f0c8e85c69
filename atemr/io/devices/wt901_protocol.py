"""The WitMotion standard ("WIT") serial protocol of the WT901 IMU: frames, a streaming decoder, SI units.

Pure code, no I/O, so the driver (`atemr.io.devices.wt901`) and the emulator
(`atemr.io.devices.wt901_emulator`) speak exactly the same bytes and the tests can check both against
frames built by hand.

On the wire the device streams 11-byte frames, without being asked::

    0x55  type  d0_lo d0_hi  d1_lo d1_hi  d2_lo d2_hi  d3_lo d3_hi  sum

four little-endian int16 values and ``sum``, the low byte of the sum of the first ten bytes. Types:
0x51 acceleration (x, y, z in units of 16 g / 32768, then the temperature in 0.01 °C), 0x52 angular
velocity (x, y, z in units of 2000 °/s / 32768, then the voltage or the temperature, by firmware), 0x53
angle (roll, pitch, yaw in units of 180° / 32768, then the firmware version); 0x50 time, 0x54 magnetic
field, 0x59 quaternion and others are configurable extras. The serial link has no framing of its own, so
a reader finds frames by their 0x55 header, a plausible type byte and the checksum, and resynchronises
one byte further on after a bad candidate (`FrameDecoder`).

The host configures the device by writing registers, ``0xFF 0xAA register value_lo value_hi``
(`register_write`): unlock first (`UNLOCK`), then e.g. the output rate (`REG_RATE`), then save (`SAVE`).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

from atemr.errors import ProtocolError

HEADER = 0x55
FRAME_LEN = 11
#: One g, to turn the device's readings in g into m/s².
STANDARD_GRAVITY = 9.80665
#: Full-scale raw value of every int16 reading.
FULL_SCALE = 32768.0
ACCEL_RANGE_G = 16.0
GYRO_RANGE_DPS = 2000.0
ANGLE_RANGE_DEG = 180.0

_PAYLOAD = struct.Struct("<4h")


class FrameType(IntEnum):
    """The type byte of the frames a WT901 streams (the others it may stream are still accepted)."""

    TIME = 0x50
    ACCEL = 0x51
    GYRO = 0x52
    ANGLE = 0x53
    MAGNETIC = 0x54
    QUATERNION = 0x59
    REGISTER = 0x5F  # the reply to a register read


def is_frame_type(value: int) -> bool:
    """Whether ``value`` can be the type byte of a WIT frame (0x50 to 0x5A, or 0x5F): anything else after a
    0x55 means that 0x55 is data, not a header."""
    return 0x50 <= value <= 0x5A or value == FrameType.REGISTER


@dataclass(frozen=True)
class Frame:
    """One decoded frame: its type byte and its four raw int16 values."""

    type: int
    values: tuple[int, int, int, int]


def checksum(data: bytes | bytearray | memoryview) -> int:
    """The WIT checksum: the low byte of the sum of ``data`` (a frame's first ten bytes)."""
    return sum(data) & 0xFF


def encode_frame(frame_type: int, values: Sequence[int]) -> bytes:
    """The 11 bytes of a frame of ``frame_type`` carrying four raw int16 ``values``."""
    if not is_frame_type(frame_type):
        raise ProtocolError(f"WT901 frame: type 0x{frame_type:02X} is not a WIT frame type (0x50-0x5A, 0x5F)")
    if len(values) != 4:
        raise ProtocolError(f"WT901 frame 0x{frame_type:02X}: needs 4 values, got {len(values)}")
    for i, value in enumerate(values):
        if not -32768 <= value <= 32767:
            raise ProtocolError(f"WT901 frame 0x{frame_type:02X}: value {i} = {value} does not fit an int16")
    body = bytes((HEADER, frame_type)) + _PAYLOAD.pack(*values)
    return body + bytes((checksum(body),))


def decode_frame(data: bytes | bytearray | memoryview) -> Frame:
    """Decode one complete frame; `ProtocolError` says what is wrong with it."""
    if len(data) != FRAME_LEN:
        raise ProtocolError(f"WT901 frame: {len(data)} bytes, expected {FRAME_LEN}")
    if data[0] != HEADER:
        raise ProtocolError(f"WT901 frame: header 0x{data[0]:02X}, expected 0x{HEADER:02X}")
    if not is_frame_type(data[1]):
        raise ProtocolError(f"WT901 frame: type 0x{data[1]:02X} is not a WIT frame type")
    expected = checksum(data[:10])
    if data[10] != expected:
        raise ProtocolError(f"WT901 frame 0x{data[1]:02X}: checksum 0x{data[10]:02X}, expected 0x{expected:02X}")
    a, b, c, d = _PAYLOAD.unpack_from(data, 2)
    return Frame(data[1], (a, b, c, d))


class FrameDecoder:
    """Turns a byte stream, cut anywhere, into frames.

    A candidate is a 0x55 followed by a frame type; a candidate whose checksum fails is counted in
    ``bad_frames`` and only its 0x55 is dropped, because the real frame may begin inside it (a flipped
    bit on the wire, or a read that began mid-frame). Bytes before a candidate are counted in
    ``skipped_bytes``. A corrupted frame that happens to pass the 8-bit checksum (one in 256) cannot be
    told from a good one: that is the protocol's limit.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.frames = 0
        self.bad_frames = 0
        self.skipped_bytes = 0
        self.bytes_seen = 0

    def clear(self) -> None:
        """Forget a partial frame (the port was reopened); the counters go on."""
        self._buffer.clear()

    def feed(self, data: bytes | bytearray) -> list[Frame]:
        """Add ``data`` and return the frames it completed, in order."""
        self.bytes_seen += len(data)
        buf = self._buffer
        buf.extend(data)
        frames: list[Frame] = []
        start = 0
        while True:
            header = buf.find(HEADER, start)
            if header < 0:
                self.skipped_bytes += len(buf) - start
                start = len(buf)
                break
            self.skipped_bytes += header - start
            start = header
            if len(buf) - start < 2:
                break
            if not is_frame_type(buf[start + 1]):
                self.skipped_bytes += 1
                start += 1
                continue
            if len(buf) - start < FRAME_LEN:
                break
            if buf[start + 10] != checksum(memoryview(buf)[start : start + 10]):
                self.bad_frames += 1
                start += 1
                continue
            a, b, c, d = _PAYLOAD.unpack_from(buf, start + 2)
            frames.append(Frame(buf[start + 1], (a, b, c, d)))
            self.frames += 1
            start += FRAME_LEN
        del buf[:start]
        return frames


# -- SI units --------------------------------------------------------------------------------------------------
Vector3 = tuple[float, float, float]


def accel_mps2(frame: Frame) -> Vector3:
    """Specific force of an acceleration frame (0x51) in m/s², sensor axes (at rest, +1 g up)."""
    k = ACCEL_RANGE_G * STANDARD_GRAVITY / FULL_SCALE
    return (frame.values[0] * k, frame.values[1] * k, frame.values[2] * k)


def temperature_c(frame: Frame) -> float:
    """The temperature an acceleration frame (0x51) carries, in °C."""
    return frame.values[3] / 100.0


def angular_velocity_radps(frame: Frame) -> Vector3:
    """Angular velocity of a gyro frame (0x52) in rad/s, sensor axes."""
    k = math.radians(GYRO_RANGE_DPS) / FULL_SCALE
    return (frame.values[0] * k, frame.values[1] * k, frame.values[2] * k)


def angles_rad(frame: Frame) -> Vector3:
    """Roll, pitch and yaw of an angle frame (0x53) in rad, each in [-π, π)."""
    k = math.pi / FULL_SCALE
    return (frame.values[0] * k, frame.values[1] * k, frame.values[2] * k)


def _raw(value: float, full_scale: float) -> int:
    """``value`` in raw units of ``full_scale`` / 32768, saturated at the int16 range as the sensor does."""
    return max(-32768, min(32767, round(value / full_scale * FULL_SCALE)))


def _wrap_pi(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def accel_frame(accel: Sequence[float], temperature: float = 25.0) -> bytes:
    """An acceleration frame (0x51) for a specific force in m/s² (sensor axes) and a temperature in °C."""
    g = ACCEL_RANGE_G * STANDARD_GRAVITY
    raw = [_raw(a, g) for a in accel[:3]]
    return encode_frame(FrameType.ACCEL, (*raw, max(-32768, min(32767, round(temperature * 100.0)))))


def gyro_frame(rate: Sequence[float], extra: int = 0) -> bytes:
    """A gyro frame (0x52) for an angular velocity in rad/s (sensor axes); ``extra`` is the fourth word."""
    raw = [_raw(math.degrees(w), GYRO_RANGE_DPS) for w in rate[:3]]
    return encode_frame(FrameType.GYRO, (*raw, extra))


def angle_frame(angles: Sequence[float], version: int = 0) -> bytes:
    """An angle frame (0x53) for roll, pitch, yaw in rad (wrapped to [-π, π)); ``version`` is the fourth word."""
    raw = [_raw(_wrap_pi(a), math.pi) for a in angles[:3]]
    return encode_frame(FrameType.ANGLE, (*raw, version))


# -- configuration commands ------------------------------------------------------------------------------------
REG_SAVE = 0x00
REG_RATE = 0x03
REG_BAUD = 0x04
REG_UNLOCK = 0x69
UNLOCK_KEY = 0xB588


def register_write(register: int, value: int) -> bytes:
    """The 5-byte command writing ``value`` (uint16) into ``register``."""
    if not (0 <= register <= 0xFF and 0 <= value <= 0xFFFF):
        raise ProtocolError(f"WT901 register write: register 0x{register:X} / value 0x{value:X} out of range")
    return bytes((0xFF, 0xAA, register, value & 0xFF, value >> 8))


#: Unlocks the configuration registers for the next writes (0xFF 0xAA 0x69 0x88 0xB5).
UNLOCK = register_write(REG_UNLOCK, UNLOCK_KEY)
#: Saves the configuration in the device's flash (0xFF 0xAA 0x00 0x00 0x00).
SAVE = register_write(REG_SAVE, 0)


# -- mounting --------------------------------------------------------------------------------------------------
def rotation_matrix(roll: float, pitch: float, yaw: float) -> NDArray[np.float64]:
    """The rotation R = Rz(yaw) Ry(pitch) Rx(roll) of a sensor mounted with those angles in the base frame
    (fixed-axis roll, then pitch, then yaw, as ROS's rpy): ``v_base = R @ v_sensor``."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ],
        dtype=np.float64,
    )


def euler_from_matrix(r: NDArray[np.float64]) -> Vector3:
    """Roll, pitch, yaw of a rotation matrix (the inverse of `rotation_matrix`, away from pitch ±90°)."""
    pitch = math.asin(max(-1.0, min(1.0, -float(r[2, 0]))))
    roll = math.atan2(float(r[2, 1]), float(r[2, 2]))
    yaw = math.atan2(float(r[1, 0]), float(r[0, 0]))
    return (roll, pitch, yaw)
