"""A WT901 on a pseudo-terminal: the bytes a real one streams, for the driver's tests and for bench runs.

`Wt901Emulator` opens a pty (``os.openpty``), puts its device side in raw mode and streams acceleration,
gyro and angle frames (0x51, 0x52, 0x53, in that order, as the device does) at a fixed rate, paced by
``time.monotonic`` in a daemon thread. A pty has no baud rate, so any rate works (the default, 50 Hz, is
the robot's configured WT901 rate). What it streams comes from ``feed()``, the simulator's latest
`ImuSample` in the base frame (None: the robot stands still); the emulator undoes the mounting rotation
it is given (so a driver configured with the same rotation recovers the base frame), adds gravity on the
base's z axis and a constant gyro bias, and integrates the yaw rate for the angle frame.

The driver opens ``port``, a symlink in a temporary directory to the pty's device side (`PluggablePty`), so
`unplug` (the pty is closed: the driver's reads fail, the path disappears) and `replug` (a new pty, the
link re-pointed atomically) behave like a USB adapter leaving and coming back at the same udev name.
`corrupt_next` flips a byte in the next frames, as line noise would.

A real device drops what nobody reads: so does this one (the pty's buffer full, a frame is lost), and it
reads and discards what the host writes (the driver sends nothing).
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from atemr.io.devices import wt901_protocol as wit
from atemr.io.devices.pty_port import PtyEmulator
from atemr.msgs import ImuSample

log = logging.getLogger(__name__)


class Wt901Emulator(PtyEmulator):
    """A WT901 streaming on a pty (see the module docstring)."""

    def __init__(
        self,
        feed: Callable[[], ImuSample | None] | None = None,
        *,
        rate_hz: float = 50.0,
        rotation: Sequence[float] = (0.0, 0.0, 0.0),
        gyro_bias_radps: Sequence[float] = (0.0, 0.0, 0.0),
        temperature_c: float = 25.0,
        directory: str | Path | None = None,
        link_name: str = "imu",
    ) -> None:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"Wt901Emulator: rate_hz must be > 0, got {rate_hz}")
        if len(rotation) != 3 or len(gyro_bias_radps) != 3:
            raise ValueError("Wt901Emulator: rotation and gyro_bias_radps take three numbers each")
        super().__init__(link_name, directory=directory, prefix="atemr-wt901-")
        self.feed = feed or (lambda: None)
        self.rate_hz = rate_hz
        roll, pitch, yaw = rotation
        self._mount = wit.rotation_matrix(roll, pitch, yaw)
        self.gyro_bias_radps = np.asarray(gyro_bias_radps, dtype=np.float64)
        self.temperature_c = temperature_c
        self._corrupt = 0
        self._yaw = 0.0
        self.frames_sent = 0
        self.frames_lost = 0
        self.bytes_received = 0
        try:
            self.replug()  # plugged in from the start
        except BaseException:
            self._pty.close()
            raise

    # -- the device's life (the rest is `PtyEmulator`'s) ------------------------------------------------------
    def start(self) -> None:
        """Start streaming (idempotent)."""
        self._start_thread("wt901-emulator")

    def _power_on(self) -> None:
        self._yaw = 0.0  # a restarted device integrates its yaw from zero

    def corrupt_next(self, n: int = 1) -> None:
        """Flip one byte in each of the next ``n`` frames (each then fails its checksum)."""
        with self._lock:
            self._corrupt += n

    # -- what it streams -------------------------------------------------------------------------------------
    def cycle(self, sample: ImuSample | None, dt: float) -> bytes:
        """One output cycle (0x51, 0x52, 0x53) for base-frame ``sample``, ``dt`` seconds after the last one
        (the yaw of the angle frame advances by the yaw rate times ``dt``)."""
        yaw_rate = sample.yaw_rate_radps if sample is not None else 0.0
        if sample is None:
            ax, ay, az = 0.0, 0.0, wit.STANDARD_GRAVITY
        else:
            ax, ay, az = sample.accel_x_mps2, sample.accel_y_mps2, sample.accel_z_mps2
        inverse = self._mount.T
        accel = inverse @ np.array([ax, ay, az])
        rate = inverse @ np.array([0.0, 0.0, yaw_rate]) + self.gyro_bias_radps
        self._yaw = math.remainder(self._yaw + yaw_rate * dt, 2.0 * math.pi)
        attitude = wit.euler_from_matrix(wit.rotation_matrix(0.0, 0.0, self._yaw) @ self._mount)
        extra = round(self.temperature_c * 100.0)
        return b"".join(
            (wit.accel_frame(accel, self.temperature_c), wit.gyro_frame(rate, extra), wit.angle_frame(attitude))
        )

    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        last = time.monotonic()
        due = last
        while not self._stop.is_set():
            now = time.monotonic()
            if now < due:
                self._stop.wait(due - now)
                continue
            try:
                sample = self.feed()
            except Exception:
                log.exception("wt901 emulator: the feed failed; streaming a robot at rest")
                sample = None
            self._emit(sample, now - last)
            last = now
            due += period
            if due < now:  # fell behind (a slow machine): no burst to catch up, as a real device
                due = now + period

    def _emit(self, sample: ImuSample | None, dt: float) -> None:
        with self._lock:
            master = self._pty.master
            if master is None:  # unplugged: nothing to power it
                return
            self._drain(master)
            for frame in _split(self.cycle(sample, dt)):
                if self._corrupt > 0:
                    self._corrupt -= 1
                    self._write(master, frame[:5] + bytes((frame[5] ^ 0xFF,)) + frame[6:])
                else:
                    self._write(master, frame)

    def _write(self, fd: int, frame: bytes) -> None:
        try:
            written = os.write(fd, frame)
        except BlockingIOError:  # nobody reads: the frame is lost, as on a real line
            self.frames_lost += 1
            return
        except OSError as exc:
            log.debug("wt901 emulator: write failed: %s", exc)
            self.frames_lost += 1
            return
        if written < len(frame):
            self.frames_lost += 1  # a partial frame: the host's decoder resynchronises on the next
        else:
            self.frames_sent += 1

    def _drain(self, fd: int) -> None:
        """Read and discard what the host wrote (commands this emulator does not act on)."""
        while True:
            try:
                data = os.read(fd, 4096)
            except (BlockingIOError, OSError):
                return
            if not data:
                return
            self.bytes_received += len(data)


def _split(cycle: bytes) -> list[bytes]:
    return [cycle[i : i + wit.FRAME_LEN] for i in range(0, len(cycle), wit.FRAME_LEN)]
