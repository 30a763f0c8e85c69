"""The SLAMTEC RPLidar serial protocol (A-series, as the A2M8 speaks it): bytes in, values out, no I/O.

Both directions are here, so the driver (`atemr.io.devices.rplidar`) and the emulator
(`atemr.io.devices.rplidar_emulator`) share one definition of the wire and cannot drift apart.

Requests (host to device) are ``0xA5, cmd`` and, for a command with bit 7 set, ``size, payload..., checksum``
where the checksum is the XOR of every byte before it (the 0xA5 included). Every answer starts with a
7-byte response descriptor: ``0xA5 0x5A``, a little-endian 32-bit word holding the data length (low 30 bits)
and the send mode (high 2 bits: 0 one answer, 1 an endless stream), and the data type. GET_INFO answers 20
bytes, GET_HEALTH 3, GET_SAMPLERATE 4; SCAN streams 5-byte samples and EXPRESS_SCAN 84-byte capsules.

A standard sample is ``quality<<2 | !S<<1 | S``, then the angle in 1/64 degree shifted left by one over a
check bit ``C = 1``, then the distance in 1/4 mm; ``S`` marks the first sample of a revolution, and a
distance of 0 means no return. Angles run clockwise (seen from above), from 0 to 360 degrees. The only
integrity checks are S != !S and C = 1, so `ScanDecoder` resynchronises byte by byte when they fail and
also rejects an angle at or beyond 360 degrees, which no device sends.

`revolution_to_scan` turns one revolution into the project's `LaserScan`: counter-clockwise radians,
evenly binned over [-pi, pi), metres, the nearest return of each bin (see its docstring).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from atemr.errors import ProtocolError
from atemr.msgs import LaserScan, Pose2D

SYNC = 0xA5
"""First byte of every request and of every response descriptor."""
ANSWER_SYNC2 = 0x5A
"""Second byte of a response descriptor."""
CMD_HAS_PAYLOAD = 0x80
"""Commands with this bit carry ``size, payload, checksum``."""
DESCRIPTOR_LEN = 7
SAMPLE_LEN = 5
CAPSULE_LEN = 84
CAPSULE_SAMPLES = 32
INFO_LEN = 20
HEALTH_LEN = 3
SAMPLERATE_LEN = 4
#: Angles in 1/64 degree at or beyond a full turn: a decoded sample with one is a false synchronisation.
FULL_TURN_Q6 = 360 * 64
HALF_TURN_Q6 = 180 * 64
#: The quality the SDK gives an express sample with a return (capsules carry no quality).
EXPRESS_QUALITY = 0x2F
#: A revolution with fewer samples is noise (the A2M8 makes hundreds per turn), not a scan: it is dropped.
MIN_REVOLUTION_SAMPLES = 32
#: A revolution longer than this (no start flag seen: motor stalled, flags lost) is dropped, not kept growing.
MAX_REVOLUTION_SAMPLES = 16_384


class Command(IntEnum):
    """Request codes (SDK ``sl_lidar_cmd.h``)."""

    STOP = 0x25
    SCAN = 0x20
    FORCE_SCAN = 0x21
    RESET = 0x40
    GET_INFO = 0x50
    GET_HEALTH = 0x52
    GET_SAMPLERATE = 0x59
    EXPRESS_SCAN = 0x82
    MOTOR_PWM = 0xF0


class AnswerType(IntEnum):
    """The data type byte of a response descriptor."""

    INFO = 0x04
    HEALTH = 0x06
    SAMPLERATE = 0x15
    MEASUREMENT = 0x81
    MEASUREMENT_CAPSULED = 0x82


class SendMode(IntEnum):
    """The descriptor's 2-bit send mode."""

    SINGLE = 0
    MULTIPLE = 1


class HealthStatus(IntEnum):
    """GET_HEALTH status: a warning still scans, an error needs a reset (or a repair)."""

    GOOD = 0
    WARNING = 1
    ERROR = 2


# -- requests -----------------------------------------------------------------------------------------------


class Request(NamedTuple):
    """One request as the device receives it."""

    cmd: int
    payload: bytes = b""


def encode_request(cmd: int, payload: bytes = b"") -> bytes:
    """The bytes of request ``cmd``; a command with bit 7 set carries ``payload``, its size and a checksum."""
    if not 0 <= cmd <= 0xFF:
        raise ProtocolError(f"RPLidar request: command 0x{cmd:X} does not fit in a byte")
    if not cmd & CMD_HAS_PAYLOAD:
        if payload:
            raise ProtocolError(f"RPLidar request 0x{cmd:02X}: this command takes no payload, got {len(payload)} "
                                "bytes")
        return bytes((SYNC, cmd))
    if len(payload) > 0xFF:
        raise ProtocolError(f"RPLidar request 0x{cmd:02X}: payload of {len(payload)} bytes, at most 255")
    body = bytes((SYNC, cmd, len(payload))) + payload
    return body + bytes((xor(body),))


def xor(data: bytes | bytearray) -> int:
    """XOR of all bytes (the request and capsule checksums)."""
    out = 0
    for b in data:
        out ^= b
    return out


def motor_pwm_request(pwm: int) -> bytes:
    """MOTOR_PWM with duty ``pwm`` (0 stops; the A2's nominal is 660)."""
    if not 0 <= pwm <= 0xFFFF:
        raise ProtocolError(f"RPLidar MOTOR_PWM: duty {pwm} outside 0..65535")
    return encode_request(Command.MOTOR_PWM, pwm.to_bytes(2, "little"))


def express_scan_request(working_mode: int = 0) -> bytes:
    """EXPRESS_SCAN in legacy capsule mode: working mode, 16-bit flags and 16-bit parameter, all 0."""
    return encode_request(Command.EXPRESS_SCAN, bytes((working_mode, 0, 0, 0, 0)))


class RequestParser:
    """Splits the host's byte stream into requests (the emulator's side of the wire).

    Bytes before a 0xA5 and requests with a wrong checksum are skipped and counted in ``bad_bytes`` and
    ``bad_requests``: a real device ignores them too.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.bad_bytes = 0
        self.bad_requests = 0

    def feed(self, data: bytes) -> list[Request]:
        """Take ``data``; return the requests it completes."""
        buf = self._buf
        buf += data
        out: list[Request] = []
        i = 0
        while i < len(buf):
            if buf[i] != SYNC:
                i += 1
                self.bad_bytes += 1
                continue
            if len(buf) - i < 2:
                break
            cmd = buf[i + 1]
            if not cmd & CMD_HAS_PAYLOAD:
                out.append(Request(cmd))
                i += 2
                continue
            if len(buf) - i < 3:
                break
            end = i + 3 + buf[i + 2] + 1
            if len(buf) < end:
                break
            if xor(buf[i:end - 1]) != buf[end - 1]:
                self.bad_requests += 1
                self.bad_bytes += 1
                i += 1
                continue
            out.append(Request(cmd, bytes(buf[i + 3:end - 1])))
            i = end
        del buf[:i]
        return out


# -- response descriptors -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class ResponseDescriptor:
    """What follows: ``length`` bytes (per answer, or per sample/capsule of a stream) of ``data_type``."""

    length: int
    send_mode: int
    data_type: int


def encode_descriptor(length: int, send_mode: int, data_type: int) -> bytes:
    """The 7 bytes announcing an answer."""
    if not (0 <= length < 1 << 30 and 0 <= send_mode < 4 and 0 <= data_type <= 0xFF):
        raise ProtocolError(f"RPLidar descriptor: length {length}, send mode {send_mode} or type {data_type} "
                            "out of range")
    word = length | send_mode << 30
    return bytes((SYNC, ANSWER_SYNC2)) + word.to_bytes(4, "little") + bytes((data_type,))


def parse_descriptor(data: bytes | bytearray) -> ResponseDescriptor:
    """Read a response descriptor from the first 7 bytes of ``data``."""
    if len(data) < DESCRIPTOR_LEN:
        raise ProtocolError(f"RPLidar descriptor: {len(data)} bytes, need {DESCRIPTOR_LEN}: {bytes(data).hex(' ')}")
    if data[0] != SYNC or data[1] != ANSWER_SYNC2:
        raise ProtocolError(f"RPLidar descriptor: starts {data[0]:02X} {data[1]:02X}, expected A5 5A")
    word = int.from_bytes(data[2:6], "little")
    return ResponseDescriptor(word & 0x3FFFFFFF, word >> 30, data[6])


def find_descriptor(buf: bytes | bytearray, start: int = 0) -> int:
    """Index of the next ``A5 5A`` in ``buf`` at or after ``start``, -1 if none."""
    return bytes(buf).find(bytes((SYNC, ANSWER_SYNC2)), start)


# -- GET_INFO, GET_HEALTH, GET_SAMPLERATE -----------------------------------------------------------------------


@dataclass(frozen=True)
class LidarInfo:
    """The GET_INFO answer: model byte (major series in the high nibble), firmware, hardware, serial."""

    model: int
    firmware_minor: int
    firmware_major: int
    hardware: int
    serial: bytes

    @property
    def model_name(self) -> str:
        """``A2M8`` for 0x28: the A series names its models by the two nibbles; others by the number."""
        major, sub = self.model >> 4, self.model & 0xF
        if 1 <= major <= 3:
            return f"A{major}M{sub}"
        return f"model 0x{self.model:02X}"

    @property
    def firmware(self) -> str:
        """As the SDK prints it: ``1.29``."""
        return f"{self.firmware_major}.{self.firmware_minor:02d}"

    @property
    def serial_number(self) -> str:
        """The 16 serial bytes in upper-case hexadecimal, as SLAMTEC's tools print them."""
        return self.serial.hex().upper()


def parse_info(data: bytes | bytearray) -> LidarInfo:
    """Decode the 20 data bytes of a GET_INFO answer."""
    if len(data) != INFO_LEN:
        raise ProtocolError(f"RPLidar GET_INFO: {len(data)} data bytes, expected {INFO_LEN}")
    return LidarInfo(data[0], data[1], data[2], data[3], bytes(data[4:20]))


def encode_info(info: LidarInfo) -> bytes:
    """The 20 data bytes of a GET_INFO answer."""
    if len(info.serial) != 16:
        raise ProtocolError(f"RPLidar GET_INFO: the serial number has 16 bytes, got {len(info.serial)}")
    return bytes((info.model, info.firmware_minor, info.firmware_major, info.hardware)) + info.serial


@dataclass(frozen=True)
class LidarHealth:
    """The GET_HEALTH answer: status (`HealthStatus`) and the device's error code."""

    status: int
    error_code: int

    @property
    def status_name(self) -> str:
        try:
            return HealthStatus(self.status).name.lower()
        except ValueError:
            return f"unknown status {self.status}"


def parse_health(data: bytes | bytearray) -> LidarHealth:
    """Decode the 3 data bytes of a GET_HEALTH answer."""
    if len(data) != HEALTH_LEN:
        raise ProtocolError(f"RPLidar GET_HEALTH: {len(data)} data bytes, expected {HEALTH_LEN}")
    return LidarHealth(data[0], data[1] | data[2] << 8)


def encode_health(health: LidarHealth) -> bytes:
    """The 3 data bytes of a GET_HEALTH answer."""
    return bytes((health.status,)) + health.error_code.to_bytes(2, "little")


@dataclass(frozen=True)
class SampleRate:
    """The GET_SAMPLERATE answer: microseconds per sample in SCAN and in EXPRESS_SCAN."""

    standard_us: int
    express_us: int


def parse_samplerate(data: bytes | bytearray) -> SampleRate:
    if len(data) != SAMPLERATE_LEN:
        raise ProtocolError(f"RPLidar GET_SAMPLERATE: {len(data)} data bytes, expected {SAMPLERATE_LEN}")
    return SampleRate(data[0] | data[1] << 8, data[2] | data[3] << 8)


def encode_samplerate(rate: SampleRate) -> bytes:
    return rate.standard_us.to_bytes(2, "little") + rate.express_us.to_bytes(2, "little")


# -- standard SCAN samples -----------------------------------------------------------------------------------


class ScanSample(NamedTuple):
    """One measurement: clockwise angle in degrees, distance in mm (0: no return), quality 0..63, and
    whether it starts a new revolution. A tuple, not a dataclass: thousands are made every second."""

    angle_deg: float
    distance_mm: float
    quality: int
    start: bool


def encode_sample(angle_deg: float, distance_mm: float, quality: int = 47, start: bool = False) -> bytes:
    """One 5-byte SCAN sample (angle rounded to 1/64 degree, distance to 1/4 mm)."""
    angle_q6 = round(angle_deg * 64) % FULL_TURN_Q6
    distance_q2 = round(distance_mm * 4)
    if not (0 <= distance_q2 <= 0xFFFF and 0 <= quality <= 63):
        raise ProtocolError(f"RPLidar sample: distance {distance_mm} mm or quality {quality} out of range")
    s = 1 if start else 0
    return bytes((quality << 2 | (s ^ 1) << 1 | s, (angle_q6 << 1 | 1) & 0xFF, angle_q6 >> 7,
                  distance_q2 & 0xFF, distance_q2 >> 8))


def encode_samples(angle_q6: NDArray[np.integer], distance_q2: NDArray[np.integer],
                   quality: NDArray[np.integer], start: NDArray[np.bool_]) -> bytes:
    """Many SCAN samples at once from already quantised values (the emulator's 8000 per second)."""
    n = len(angle_q6)
    out = np.empty((n, SAMPLE_LEN), dtype=np.uint8)
    s = np.asarray(start, dtype=np.uint8)
    a = np.asarray(angle_q6, dtype=np.uint32) << 1 | 1
    d = np.asarray(distance_q2, dtype=np.uint32)
    out[:, 0] = np.asarray(quality, dtype=np.uint32) << 2 | (s ^ 1) << 1 | s
    out[:, 1] = a & 0xFF
    out[:, 2] = a >> 8
    out[:, 3] = d & 0xFF
    out[:, 4] = d >> 8
    return out.tobytes()


class ScanDecoder:
    """Streaming decoder of SCAN samples: feed it bytes as they come, get whole samples.

    Where a 5-byte window fails the checks (S and !S equal, C clear, angle of a full turn or more) the
    first byte is skipped and counted in ``bad_bytes``, and the next byte is tried as a sample start: after
    line noise or a lost byte the stream realigns within a few samples.

    The checks are weak (random bytes pass them one time in eight), so a start flag is believed only where
    the angle wrapped, falling by more than half a turn since the sample before; otherwise a corrupted
    sample would cut a revolution in two. Such flags are cleared and counted in ``false_starts``.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._last_q6 = FULL_TURN_Q6  # as if the previous sample closed a revolution
        self.bad_bytes = 0
        self.false_starts = 0
        self.samples = 0

    def clear(self) -> None:
        """Forget a partial sample (a new scan starts)."""
        self._buf.clear()
        self._last_q6 = FULL_TURN_Q6

    def feed(self, data: bytes | bytearray) -> list[ScanSample]:
        buf = self._buf
        buf += data
        out: list[ScanSample] = []
        append = out.append
        i, end, bad = 0, len(buf) - SAMPLE_LEN, 0
        last = self._last_q6
        while i <= end:
            b0, b1 = buf[i], buf[i + 1]
            if (b0 ^ b0 >> 1) & 1 and b1 & 1:
                angle_q6 = (b1 | buf[i + 2] << 8) >> 1
                if angle_q6 < FULL_TURN_Q6:
                    start = bool(b0 & 1)
                    if start and last - angle_q6 < HALF_TURN_Q6:
                        start = False
                        self.false_starts += 1
                    append(ScanSample(angle_q6 / 64.0, (buf[i + 3] | buf[i + 4] << 8) / 4.0, b0 >> 2, start))
                    last = angle_q6
                    i += SAMPLE_LEN
                    continue
            i += 1
            bad += 1
        del buf[:i]
        self._last_q6 = last
        self.bad_bytes += bad
        self.samples += len(out)
        return out


# -- EXPRESS_SCAN legacy capsules --------------------------------------------------------------------------


def _offset_q3_to_deg(raw6: int) -> float:
    """The 6-bit angle compensation, a signed fixed-point q3 number of degrees (protocol document)."""
    return (raw6 - 64 if raw6 & 0x20 else raw6) / 8.0


def capsule_sample_angles(start_deg: float, next_start_deg: float, offsets_deg: Sequence[float]) -> list[float]:
    """The clockwise angles of a capsule's samples: sample k lies ``k/32`` of the way to the next capsule's
    start angle, less its compensation; wrapped to [0, 360)."""
    diff = (next_start_deg - start_deg) % 360.0
    return [(start_deg + diff * k / CAPSULE_SAMPLES - off) % 360.0 for k, off in enumerate(offsets_deg)]


def encode_capsule(start_angle_q6: int, distances_mm: Sequence[int], offsets_q3: Sequence[int],
                   new_scan: bool = False) -> bytes:
    """One 84-byte legacy express capsule: sync nibbles 0xA/0x5 over the checksum's nibbles, start angle
    (bit 15: the first capsule of a new scan), 16 cabins of two samples (14-bit mm distance, 6-bit signed
    q3 degree compensation each)."""
    if len(distances_mm) != CAPSULE_SAMPLES or len(offsets_q3) != CAPSULE_SAMPLES:
        raise ProtocolError(f"RPLidar capsule: {CAPSULE_SAMPLES} distances and offsets, got {len(distances_mm)}"
                            f" and {len(offsets_q3)}")
    body = bytearray((start_angle_q6 % FULL_TURN_Q6 | (0x8000 if new_scan else 0)).to_bytes(2, "little"))
    for j in range(0, CAPSULE_SAMPLES, 2):
        raw = []
        for k in (j, j + 1):
            if not (0 <= distances_mm[k] < 1 << 14 and -32 <= offsets_q3[k] < 32):
                raise ProtocolError(f"RPLidar capsule: sample {k}: distance {distances_mm[k]} mm or offset "
                                    f"{offsets_q3[k]}/8 degree out of range")
            raw.append(offsets_q3[k] & 0x3F)
        body += (distances_mm[j] << 2 | raw[0] >> 4).to_bytes(2, "little")
        body += (distances_mm[j + 1] << 2 | raw[1] >> 4).to_bytes(2, "little")
        body.append((raw[0] & 0xF) | (raw[1] & 0xF) << 4)
    checksum = xor(body)
    return bytes((0xA0 | checksum & 0xF, 0x50 | checksum >> 4)) + bytes(body)


class _Capsule(NamedTuple):
    start_deg: float
    distances_mm: list[int]
    offsets_deg: list[float]


class ExpressScanDecoder:
    """Streaming decoder of legacy express capsules, with `ScanDecoder`'s interface.

    A capsule's samples need the next capsule's start angle, so each capsule is emitted when the next one
    arrives. A byte that is not a capsule start (sync nibbles) and a capsule with a wrong checksum are
    skipped one byte at a time and counted in ``bad_bytes``; the capsule before a lost one is dropped (its
    angles cannot be known). A revolution starts where the nominal angle wraps past 360 degrees.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._prev: _Capsule | None = None
        self._last_nominal: float | None = None
        self.bad_bytes = 0
        self.bad_capsules = 0
        self.samples = 0

    def clear(self) -> None:
        self._buf.clear()
        self._prev = None
        self._last_nominal = None

    def feed(self, data: bytes | bytearray) -> list[ScanSample]:
        buf = self._buf
        buf += data
        out: list[ScanSample] = []
        i = 0
        while len(buf) - i >= CAPSULE_LEN:
            if buf[i] >> 4 != 0xA or buf[i + 1] >> 4 != 0x5:
                i += 1
                self.bad_bytes += 1
                continue
            body = buf[i + 2:i + CAPSULE_LEN]
            if xor(body) != (buf[i] & 0xF | (buf[i + 1] & 0xF) << 4):
                i += 1
                self.bad_bytes += 1
                self.bad_capsules += 1
                self._prev = None
                continue
            capsule, new_scan = self._parse(body)
            if new_scan:
                self._prev, self._last_nominal = None, None
            if self._prev is not None:
                out.extend(self._samples(self._prev, capsule.start_deg))
            self._prev = capsule
            i += CAPSULE_LEN
        del buf[:i]
        self.samples += len(out)
        return out

    @staticmethod
    def _parse(body: bytes | bytearray) -> tuple[_Capsule, bool]:
        word = body[0] | body[1] << 8
        distances: list[int] = []
        offsets: list[float] = []
        for c in range(2, len(body), 5):
            d1, d2, nib = body[c] | body[c + 1] << 8, body[c + 2] | body[c + 3] << 8, body[c + 4]
            distances += (d1 >> 2, d2 >> 2)
            offsets += (_offset_q3_to_deg((d1 & 3) << 4 | nib & 0xF), _offset_q3_to_deg((d2 & 3) << 4 | nib >> 4))
        return _Capsule((word & 0x7FFF) / 64.0, distances, offsets), bool(word & 0x8000)

    def _samples(self, capsule: _Capsule, next_start_deg: float) -> list[ScanSample]:
        diff = (next_start_deg - capsule.start_deg) % 360.0
        angles = capsule_sample_angles(capsule.start_deg, next_start_deg, capsule.offsets_deg)
        out = []
        for k, (angle, dist) in enumerate(zip(angles, capsule.distances_mm, strict=True)):
            nominal = (capsule.start_deg + diff * k / CAPSULE_SAMPLES) % 360.0
            start = self._last_nominal is not None and nominal < self._last_nominal
            self._last_nominal = nominal
            out.append(ScanSample(angle, float(dist), EXPRESS_QUALITY if dist else 0, start))
        return out


# -- revolutions --------------------------------------------------------------------------------------------


class RevolutionAssembler:
    """Groups samples into revolutions at the start flags.

    Samples before the first start flag belong to a revolution seen in part and are dropped; a revolution
    that grows past ``max_samples`` without a start flag is dropped and counted in ``overflows``, and one of
    fewer than ``min_samples`` (text a rebooting device prints, decoded as samples) in ``short``.
    """

    def __init__(self, min_samples: int = MIN_REVOLUTION_SAMPLES, max_samples: int = MAX_REVOLUTION_SAMPLES) -> None:
        self.min_samples = min_samples
        self.max_samples = max_samples
        self._current: list[ScanSample] | None = None
        self.overflows = 0
        self.short = 0

    def clear(self) -> None:
        self._current = None

    def push(self, samples: Sequence[ScanSample]) -> list[list[ScanSample]]:
        """Take ``samples``; return the revolutions they complete."""
        done: list[list[ScanSample]] = []
        for sample in samples:
            if sample.start:
                if self._current is not None:
                    if len(self._current) >= self.min_samples:
                        done.append(self._current)
                    else:
                        self.short += 1
                self._current = [sample]
            elif self._current is not None:
                self._current.append(sample)
                if len(self._current) > self.max_samples:
                    self._current = None
                    self.overflows += 1
        return done


def ccw_bin_index(angle_cw_deg: NDArray[np.float64], angle_min_rad: float, increment_rad: float,
                  beams: int) -> NDArray[np.intp]:
    """The beam of a scan (``angle_min_rad + i * increment_rad``, counter-clockwise) nearest to each clockwise
    angle: the one function both the driver (binning) and the emulator (looking a scan up) use, so the two
    agree on every boundary."""
    ccw_deg = -np.asarray(angle_cw_deg, dtype=np.float64)
    steps = (ccw_deg - math.degrees(angle_min_rad)) / math.degrees(increment_rad)
    return np.mod(np.round(steps).astype(np.intp), beams)


def revolution_to_scan(
    samples: Sequence[ScanSample],
    t: float,
    *,
    beams: int,
    range_min_m: float,
    range_max_m: float,
    pose: Pose2D,
) -> LaserScan:
    """One revolution of clockwise, unevenly spaced samples as an evenly binned counter-clockwise `LaserScan`.

    Bin ``i`` is centred on ``-pi + i * 2pi/beams`` (so 90 degrees clockwise, to the sensor's right, lands at
    -pi/2). A bin with several returns keeps the nearest in [range_min_m, range_max_m] (an obstacle is never
    hidden by a farther return). A bin whose returns all lie outside that interval is -inf when one was closer
    than ``range_min_m`` and +inf when beyond ``range_max_m``, as the simulator reports them (REP 117); a
    bin with no return at all (distance 0, or no sample) is NaN. ``pose`` is the sensor's mounting pose.
    """
    if beams < 1:
        raise ProtocolError(f"RPLidar scan: beams must be >= 1, got {beams}")
    increment = 2.0 * math.pi / beams
    ranges = np.full(beams, np.nan)
    if samples:
        data = np.array([(s.angle_deg, s.distance_mm) for s in samples], dtype=np.float64)
        metres = data[:, 1] / 1000.0
        idx = ccw_bin_index(data[:, 0], -math.pi, increment, beams)
        returned = data[:, 1] > 0
        inside = returned & (metres >= range_min_m) & (metres <= range_max_m)
        ranges[idx[returned & (metres > range_max_m)]] = np.inf
        ranges[idx[returned & (metres < range_min_m)]] = -np.inf
        nearest = np.full(beams, np.inf)
        np.minimum.at(nearest, idx[inside], metres[inside])
        hit = np.isfinite(nearest)
        ranges[hit] = nearest[hit]
    return LaserScan(t, ranges, -math.pi, increment, range_min_m, range_max_m, pose)


# -- for benchmarks -----------------------------------------------------------------------------------------


def synthetic_scan_bytes(n_samples: int, samples_per_revolution: int = 800, seed: int = 0) -> bytes:
    """``n_samples`` SCAN samples as a device streams them (revolutions of ``samples_per_revolution``,
    random distances up to 12 m, some without return): input for decoding benchmarks."""
    rng = np.random.default_rng(seed)
    k = np.arange(n_samples)
    pos = k % samples_per_revolution
    angle_q6 = np.minimum((pos * FULL_TURN_Q6) // samples_per_revolution, FULL_TURN_Q6 - 1)
    distance_q2 = rng.integers(600, 48_000, n_samples)
    distance_q2[rng.random(n_samples) < 0.05] = 0
    quality = np.where(distance_q2 > 0, 47, 0)
    return encode_samples(angle_q6, distance_q2, quality, pos == 0)


def decode_stream(data: bytes, chunk: int = 4096) -> int:
    """Decode ``data`` in ``chunk``-byte reads, as the driver does, into revolutions; the samples decoded.
    Benchmark: ``data = synthetic_scan_bytes(N)``, then time ``decode_stream(data)`` (the A2M8 streams at
    most 8000 samples/s)."""
    decoder, revolutions = ScanDecoder(), RevolutionAssembler()
    for i in range(0, len(data), chunk):
        revolutions.push(decoder.feed(data[i:i + chunk]))
    return decoder.samples
