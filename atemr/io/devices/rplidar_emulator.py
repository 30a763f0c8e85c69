"""An RPLidar A2M8 on a pseudo-terminal, byte for byte: for the driver's tests and for bench runs.

`RplidarEmulator` opens a pty (``os.openpty``), puts its device side in raw mode and answers the host's
requests as the device does (`atemr.io.devices.rplidar_protocol`): GET_INFO (model 0x28, A2M8, firmware
1.29, hardware 7, a fixed serial number), GET_HEALTH (status and error code as configured, `set_health`),
GET_SAMPLERATE, RESET (a text banner, as the device prints after booting), STOP, MOTOR_PWM, SCAN and
EXPRESS_SCAN (legacy capsules). A new request other than MOTOR_PWM ends a running scan, as on the device.

While the motor turns (MOTOR_PWM above 0: a pty has no DTR line to start it) a scan streams about
``samples_per_s`` samples per second, paced by ``time.monotonic`` in a daemon thread: revolutions of about
``samples_per_s / revolutions_per_s`` samples (800 at the defaults), clockwise from 0 degrees, unevenly
spaced (their number varies by a few per revolution, each angle jitters by a fifth of the spacing), the
first flagged as the start of the revolution. A pty has no baud rate: 8000 standard samples per second
(40 kB/s) pass although a real A2M8 at 115200 baud carries at most about 2300 of them.

The distances come from ``feed()``: the simulator's latest `LaserScan` (sensor frame, counter-clockwise
radians, metres), read once per revolution. Each sample takes the beam nearest to its (quantised) angle;
a beam that is not finite or lies outside the scan's [range_min_m, range_max_m] gives distance 0, no
return, as the device reports it. No feed, or a feed that returns None: no returns at all.

The host opens ``port``, a symlink in a temporary directory to the pty's device side (`PluggablePty`), so
`unplug` (the pty is closed: the host's reads fail, the path disappears) and `replug` (a new pty, the link
re-pointed atomically) behave like the USB adapter leaving and coming back at the same udev name. `inject`
puts raw bytes on the wire and `corrupt_next` zeroes the next bytes of the sample stream, as line noise
would; both act at a sample (or capsule) boundary. As a real device, it drops what nobody reads (the pty's
buffer full).
"""

from __future__ import annotations

import errno
import logging
import math
import os
import select
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from atemr.io.devices import rplidar_protocol as rp
from atemr.io.devices.pty_port import PtyEmulator
from atemr.msgs import LaserScan

log = logging.getLogger(__name__)

#: The A2M8's GET_INFO answer, with a fixed serial number that says it is this emulator.
A2M8_INFO = rp.LidarInfo(model=0x28, firmware_minor=29, firmware_major=1, hardware=7,
                         serial=bytes.fromhex("A7E3E1A2000000000000454D554C4154"))
#: What the device prints after a reset (its text is not part of the protocol; the host only skips it).
RESET_BANNER = b"RP LIDAR System.\r\nFirmware Ver 1.29 - emulated, HW Ver 7\r\nModel: 28\r\n"
#: Quality of a sample with a return (6 bits); the emulator varies it a little below this.
QUALITY = 47
#: Bytes kept for a host that does not read; beyond them output is dropped, as a UART would lose it.
MAX_PENDING = 64 * 1024
#: Largest express angle compensation the emulator sends, in 1/8 degree: small enough that consecutive
#: samples (0.45 degree apart at 800 per revolution) never leave a 1-degree bin without one.
MAX_OFFSET_Q3 = 3
#: Longest catch-up after a stall of the emulator's thread: it sends at most this much time's samples.
MAX_BURST_S = 0.1


#: Where a scan says "a return beyond the range" (+inf) without its distance, the device sends one this far
#: past the range; the driver turns it back into +inf.
BEYOND_RANGE_M = 1.0


def distances_mm(scan: LaserScan | None, angles_cw_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """What the device measures at clockwise ``angles_cw_deg``: the nearest beam of ``scan`` in millimetres;
    for a beam with a return beyond its range (+inf), a distance `BEYOND_RANGE_M` past ``range_max_m``; 0 (no
    return) for the rest (NaN, -inf, or a range below ``range_min_m``)."""
    if scan is None or len(scan.ranges_m) == 0:
        return np.zeros(len(angles_cw_deg))
    ranges = np.asarray(scan.ranges_m, dtype=np.float64)
    idx = rp.ccw_bin_index(angles_cw_deg, scan.angle_min_rad, scan.angle_increment_rad, len(ranges))
    r = ranges[idx]
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(r) & (r >= scan.range_min_m) & (r <= scan.range_max_m) & (r > 0)
    beyond = 1000.0 * (scan.range_max_m + BEYOND_RANGE_M)
    return np.where(valid, r * 1000.0, np.where(np.isposinf(r), beyond, 0.0))


class RplidarEmulator(PtyEmulator):
    """An RPLidar A2M8 on a pty (see the module docstring)."""

    def __init__(
        self,
        feed: Callable[[], LaserScan | None] | None = None,
        *,
        samples_per_s: float = 8000.0,
        revolutions_per_s: float = 10.0,
        health_status: int = rp.HealthStatus.GOOD,
        health_error_code: int = 0,
        info: rp.LidarInfo = A2M8_INFO,
        seed: int = 0,
        directory: str | Path | None = None,
        link_name: str = "rplidar",
    ) -> None:
        if not (math.isfinite(samples_per_s) and samples_per_s > 0):
            raise ValueError(f"RplidarEmulator: samples_per_s must be > 0, got {samples_per_s}")
        if not (math.isfinite(revolutions_per_s) and 0 < revolutions_per_s <= samples_per_s / 8):
            raise ValueError(f"RplidarEmulator: revolutions_per_s must be in (0, samples_per_s/8], got "
                             f"{revolutions_per_s}")
        super().__init__(link_name, directory=directory, prefix="atemr-rplidar-")
        self.directory = self._pty.directory
        self.feed = feed
        self.samples_per_s = samples_per_s
        self.revolutions_per_s = revolutions_per_s
        self.info = info
        self.health = rp.LidarHealth(health_status, health_error_code)
        self._rng = np.random.default_rng(seed)
        # what the host sees and did (for tests)
        self.commands: list[int] = []
        self.samples_sent = 0
        self.revolutions_sent = 0
        self.dropped_bytes = 0
        self._power_on()

    # -- life cycle (the rest is `PtyEmulator`'s) ---------------------------------------------------------------
    def start(self) -> RplidarEmulator:
        """Plug the device in and start answering; returns itself."""
        if self._thread is None:
            self.replug()
            self._start_thread("atemr-rplidar-emulator")
        return self

    # -- faults ------------------------------------------------------------------------------------------------
    def reboot(self) -> None:
        """The device resets by itself (a power glitch): it stops scanning and its motor, prints its banner,
        and the port stays open; the host sees the stream stop."""
        with self._lock:
            self._power_on()
            self._pending += RESET_BANNER

    def set_health(self, status: int, error_code: int = 0) -> None:
        """What GET_HEALTH answers from now on."""
        self.health = rp.LidarHealth(status, error_code)

    def inject(self, data: bytes) -> None:
        """Put ``data`` on the wire before the next sample (or capsule), or at once when not scanning."""
        with self._lock:
            self._inject += data

    def corrupt_next(self, n: int) -> None:
        """Zero the next ``n`` bytes of the scan stream, from the next sample (or capsule) boundary."""
        with self._lock:
            self._corrupt += n

    # -- observation -------------------------------------------------------------------------------------------
    @property
    def scanning(self) -> str | None:
        """``"standard"``, ``"express"`` or None."""
        return self._mode

    @property
    def motor_pwm(self) -> int:
        return self._motor_pwm

    # -- the device --------------------------------------------------------------------------------------------
    def _power_on(self) -> None:
        self._parser = rp.RequestParser()
        self._mode: str | None = None
        self._motor_pwm = 0
        self._pending = bytearray()
        self._inject = bytearray()
        self._corrupt = 0
        self._credit = 0.0
        self._last = time.monotonic()
        self._revolution = b""
        self._rev_pos = 0
        self._capsule_start_q6 = 0
        self._capsule_new_scan = False
        self._scan: LaserScan | None = None

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                master = self._pty.master
                if master is not None:
                    try:
                        self._step(master)
                    except Exception:  # an emulator bug must not hang the tests silently
                        log.exception("rplidar emulator: step failed")
            if master is None:
                self._stop.wait(0.01)

    def _step(self, master: int) -> None:
        timeout = 0.004 if self._mode else 0.01
        readable, _, _ = select.select([master], [], [], timeout)
        if readable:
            try:
                data = os.read(master, 4096)
            except BlockingIOError:
                data = b""
            for request in self._parser.feed(data):
                self._handle(request)
        self._stream()
        self._flush(master)

    def _handle(self, request: rp.Request) -> None:
        cmd = request.cmd
        self.commands.append(cmd)
        if cmd == rp.Command.MOTOR_PWM:
            if len(request.payload) == 2:
                self._motor_pwm = int.from_bytes(request.payload, "little")
            return
        self._mode = None
        if cmd == rp.Command.RESET:
            self._pending.clear()
            self._pending += RESET_BANNER
        elif cmd == rp.Command.GET_INFO:
            self._answer(rp.AnswerType.INFO, rp.encode_info(self.info))
        elif cmd == rp.Command.GET_HEALTH:
            self._answer(rp.AnswerType.HEALTH, rp.encode_health(self.health))
        elif cmd == rp.Command.GET_SAMPLERATE:
            us = round(1e6 / self.samples_per_s)
            self._answer(rp.AnswerType.SAMPLERATE, rp.encode_samplerate(rp.SampleRate(us, us)))
        elif cmd in (rp.Command.SCAN, rp.Command.FORCE_SCAN):
            self._pending += rp.encode_descriptor(rp.SAMPLE_LEN, rp.SendMode.MULTIPLE, rp.AnswerType.MEASUREMENT)
            self._begin_scan("standard")
        elif cmd == rp.Command.EXPRESS_SCAN:
            self._pending += rp.encode_descriptor(rp.CAPSULE_LEN, rp.SendMode.MULTIPLE,
                                                  rp.AnswerType.MEASUREMENT_CAPSULED)
            self._begin_scan("express")

    def _answer(self, answer: rp.AnswerType, data: bytes) -> None:
        self._pending += rp.encode_descriptor(len(data), rp.SendMode.SINGLE, answer) + data

    def _begin_scan(self, mode: str) -> None:
        self._mode = mode
        self._credit = 0.0
        self._last = time.monotonic()
        self._revolution, self._rev_pos = b"", 0
        self._capsule_start_q6 = round(self._rng.uniform(0.0, 360.0) * 64) % rp.FULL_TURN_Q6
        self._capsule_new_scan = True
        self._scan = self._read_feed()

    def _read_feed(self) -> LaserScan | None:
        if self.feed is None:
            return None
        try:
            return self.feed()
        except Exception:
            log.exception("rplidar emulator: the feed failed; this revolution has no returns")
            return None

    # -- the stream --------------------------------------------------------------------------------------------
    def _stream(self) -> None:
        now = time.monotonic()
        elapsed, self._last = now - self._last, now
        if self._mode is None or self._motor_pwm == 0:
            self._credit = 0.0
            self._pending += self._inject
            self._inject.clear()
            return
        self._credit = min(self._credit + elapsed * self.samples_per_s, MAX_BURST_S * self.samples_per_s)
        if self._mode == "standard":
            n = int(self._credit)
            self._credit -= n
            chunk = self._samples(n)
        else:
            n = int(self._credit // rp.CAPSULE_SAMPLES)
            self._credit -= n * rp.CAPSULE_SAMPLES
            chunk = b"".join(self._capsule() for _ in range(n))
        if not chunk:
            return
        self._pending += self._inject
        self._inject.clear()
        if self._corrupt:
            m = min(self._corrupt, len(chunk))
            chunk = bytes(m) + chunk[m:]
            self._corrupt -= m
        self._pending += chunk

    def _samples(self, n: int) -> bytes:
        out = []
        while n > 0:
            if self._rev_pos * rp.SAMPLE_LEN >= len(self._revolution):
                self._revolution, self._rev_pos = self._new_revolution(), 0
                self.revolutions_sent += 1
            take = min(n, len(self._revolution) // rp.SAMPLE_LEN - self._rev_pos)
            out.append(self._revolution[self._rev_pos * rp.SAMPLE_LEN:(self._rev_pos + take) * rp.SAMPLE_LEN])
            self._rev_pos += take
            n -= take
            self.samples_sent += take
        return b"".join(out)

    def _new_revolution(self) -> bytes:
        """One revolution of SCAN samples, with the feed read now."""
        rng = self._rng
        nominal = self.samples_per_s / self.revolutions_per_s
        n = max(8, round(nominal) + int(rng.integers(-3, 4)))
        step = 360.0 / n
        angles = (np.arange(n) + rng.uniform(-0.2, 0.2, n) + rng.uniform(0.2, 0.5)) * step
        angle_q6 = np.clip(np.round(angles * 64), 0, rp.FULL_TURN_Q6 - 1).astype(np.int64)
        self._scan = self._read_feed()
        distance_q2 = np.clip(np.round(distances_mm(self._scan, angle_q6 / 64.0) * 4), 0, 0xFFFF).astype(np.int64)
        quality = np.where(distance_q2 > 0, QUALITY - rng.integers(0, 8, n), 0)
        start = np.zeros(n, dtype=bool)
        start[0] = True
        return rp.encode_samples(angle_q6, distance_q2, quality, start)

    def _capsule(self) -> bytes:
        """The next express capsule: its samples' angles follow from its start angle, the next capsule's and
        the compensations, exactly as the host computes them."""
        rng = self._rng
        per_rev = self.samples_per_s / self.revolutions_per_s
        advance = 360.0 * rp.CAPSULE_SAMPLES / per_rev * (1.0 + rng.uniform(-0.01, 0.01))
        start_q6 = self._capsule_start_q6
        next_q6 = (start_q6 + round(advance * 64)) % rp.FULL_TURN_Q6
        if next_q6 < start_q6:  # a new revolution: read the feed again
            self._scan = self._read_feed()
            self.revolutions_sent += 1
        offsets_q3 = [int(v) for v in rng.integers(0, MAX_OFFSET_Q3 + 1, rp.CAPSULE_SAMPLES)]
        angles = rp.capsule_sample_angles(start_q6 / 64.0, next_q6 / 64.0, [o / 8.0 for o in offsets_q3])
        mm = np.clip(np.round(distances_mm(self._scan, np.array(angles))), 0, (1 << 14) - 1).astype(np.int64)
        capsule = rp.encode_capsule(start_q6, [int(d) for d in mm], offsets_q3, new_scan=self._capsule_new_scan)
        self._capsule_new_scan = False
        self._capsule_start_q6 = next_q6
        self.samples_sent += rp.CAPSULE_SAMPLES
        return capsule

    def _flush(self, master: int) -> None:
        if len(self._pending) > MAX_PENDING:  # nobody reads: the oldest bytes are lost on the wire
            drop = len(self._pending) - MAX_PENDING
            del self._pending[:drop]
            self.dropped_bytes += drop
        while self._pending:
            try:
                written = os.write(master, self._pending)
            except BlockingIOError:
                return
            except OSError as exc:
                if exc.errno == errno.EIO:  # no host side: the bytes are lost
                    self.dropped_bytes += len(self._pending)
                    self._pending.clear()
                    return
                raise
            del self._pending[:written]
