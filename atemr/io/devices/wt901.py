"""The WitMotion WT901 IMU on a USB serial port: yaw rate and planar acceleration in the base frame.

The device streams WIT frames by itself (`atemr.io.devices.wt901_protocol`); this driver only listens and
sends nothing, so it can never misconfigure a device another tool set up. Its output rate (10 Hz at 9600
baud out of the box; the robot's is set to 50 Hz) is WitMotion's configuration, done once.

Every gyro frame (0x52) that follows an acceleration frame (0x51) makes one `ImuSample`: both vectors are
rotated from the sensor's axes into the base frame with the configured mounting rotation, so a sensor
mounted upside down or sideways still reports the base's yaw rate with the right sign. Gravity then lies
on the base's z axis alone (the robot drives on level floors), which the sample does not carry: x and y
are the robot's own acceleration.

The gyro's turn-on bias is measured after every (re)connection (a re-plugged WT901 has restarted): for the
first ``bias_s`` seconds the angular velocity of the readings taken standing still is averaged
(`GyroBiasEstimator`), and subtracted from then on. Samples are published during that window too, with the
mean gathered so far: withholding them would make the IMU look silent (unhealthy) at every start and
reconnection, and blind localization on a reconnection while the robot drives, for an error bounded by
the stillness threshold that the running mean shrinks within a few samples. ``bias_settled`` tells a
consumer that wants to wait.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Callable, Sequence

import numpy as np
import serial

from atemr.domain.status import ComponentHealth
from atemr.io.devices import wt901_protocol as wit
from atemr.io.devices.base import DeviceInfo, ThreadedDevice, serial_port_hint
from atemr.io.devices.config import ImuDeviceConfig
from atemr.msgs import ImuSample

log = logging.getLogger(__name__)

#: Angular speed below which the robot counts as standing still while the gyro bias is measured.
STILL_RADPS = math.radians(2.0)
#: How old the newest sample may be before the IMU counts as silent (five periods at the default 10 Hz).
MAX_AGE_S = 0.5
#: How long one read waits for the first byte; bounds the reader thread's reaction to ``shutdown``.
READ_TIMEOUT_S = 0.05
#: A mean specific force at rest this far from (0, 0, g) in the base frame means the rotation is wrong.
GRAVITY_TOLERANCE_MPS2 = 0.25 * wit.STANDARD_GRAVITY


class GyroBiasEstimator:
    """The mean angular velocity (sensor axes) of the still readings of the first ``window_s`` seconds.

    Readings whose angular speed reaches ``still_radps`` are left out: the robot was moving. At the end of
    the window the result is logged, with a warning when the robot moved or no still reading came (the
    bias then stays zero). Optionally the base-frame specific force of the still readings is averaged too,
    to warn when the mounting rotation does not put gravity on the base's z axis.
    """

    def __init__(self, window_s: float, still_radps: float = STILL_RADPS, name: str = "imu") -> None:
        self.window_s = window_s
        self.still_radps = still_radps
        self.name = name
        self.reset()

    def reset(self) -> None:
        """Start a new window at the next reading (after a (re)connection)."""
        self._start: float | None = None
        self._sum = np.zeros(3)
        self._accel_sum = np.zeros(3)
        self._accel_n = 0
        self._still = 0
        self._moving = 0
        self.settled = self.window_s <= 0.0
        self.bias: wit.Vector3 = (0.0, 0.0, 0.0)

    def update(self, t: float, rate: wit.Vector3, accel_base: Sequence[float] | None = None) -> None:
        """Take reading ``rate`` (rad/s, sensor axes) at time ``t`` into the window, if it is still open."""
        if self.settled:
            return
        if self._start is None:
            self._start = t
        if t - self._start >= self.window_s:
            self._settle()
            return
        if math.hypot(*rate) < self.still_radps:
            self._still += 1
            self._sum += rate
            if accel_base is not None:
                self._accel_sum += accel_base
                self._accel_n += 1
            b = self._sum / self._still
            self.bias = (float(b[0]), float(b[1]), float(b[2]))
        else:
            self._moving += 1

    def _settle(self) -> None:
        self.settled = True
        deg = ", ".join(f"{math.degrees(b):.3f}" for b in self.bias)
        if self._still == 0:
            log.warning("%s: the robot moved during the %.1f s of gyro bias measurement; no bias is subtracted",
                        self.name, self.window_s)
            return
        if self._moving:
            log.warning("%s: the robot moved during the gyro bias measurement; bias (%s) °/s from the %d still "
                        "readings of %d", self.name, deg, self._still, self._still + self._moving)
        else:
            log.info("%s: gyro bias (%s) °/s from %d readings", self.name, deg, self._still)
        if self._accel_n == 0:
            return
        mean = self._accel_sum / self._accel_n
        if float(np.linalg.norm(mean - (0.0, 0.0, wit.STANDARD_GRAVITY))) > GRAVITY_TOLERANCE_MPS2:
            log.warning("%s: at rest the base-frame acceleration is (%.2f, %.2f, %.2f) m/s², not (0, 0, 9.81): is "
                        "the IMU's mounting rotation in the configuration right?", self.name, *mean)


class SampleAssembler:
    """Pairs each gyro frame with the acceleration frame before it into a base-frame `ImuSample`.

    Frames of other types (time, angle, magnetic field, quaternion) are skipped. A gyro frame without a new
    acceleration frame since the last sample (it was lost on the wire) makes no sample.
    """

    def __init__(self, rotation: Sequence[float], bias: GyroBiasEstimator, rate_window: int = 50) -> None:
        roll, pitch, yaw = rotation
        self.rotation = wit.rotation_matrix(roll, pitch, yaw)
        self.bias = bias
        self._accel: wit.Vector3 | None = None
        self._times: deque[float] = deque(maxlen=rate_window)
        self.incomplete = 0

    def reset(self) -> None:
        """Forget the pending frame and restart the bias window (after a (re)connection)."""
        self._accel = None
        self._times.clear()
        self.bias.reset()

    def add(self, frame: wit.Frame, t: float) -> ImuSample | None:
        """Take ``frame``, arrived at ``t``; return the sample it completes, if any."""
        if frame.type == wit.FrameType.ACCEL:
            self._accel = wit.accel_mps2(frame)
            return None
        if frame.type != wit.FrameType.GYRO:
            return None
        if self._accel is None:
            self.incomplete += 1
            return None
        accel = self.rotation @ np.asarray(self._accel)
        rate = wit.angular_velocity_radps(frame)
        self._accel = None
        self.bias.update(t, rate, accel)
        yaw_rate = float(self.rotation[2] @ (np.asarray(rate) - self.bias.bias))
        self._times.append(t)
        # z as the accelerometer reads it in the base frame (+g on a level floor), like the simulator's
        return ImuSample(t, yaw_rate, float(accel[0]), float(accel[1]), float(accel[2]))

    @property
    def rate_hz(self) -> float | None:
        """Samples per second over the last ones, None before two."""
        if len(self._times) < 2 or self._times[-1] <= self._times[0]:
            return None
        return (len(self._times) - 1) / (self._times[-1] - self._times[0])


class Wt901Driver(ThreadedDevice[ImuSample]):
    """A WT901 on a serial port (see the module docstring)."""

    def __init__(
        self,
        port: str,
        *,
        now: Callable[[], float],
        baudrate: int = 9600,
        rotation: Sequence[float] = (0.0, 0.0, 0.0),
        bias_s: float = 1.0,
        name: str = "imu",
        max_age_s: float = MAX_AGE_S,
        still_radps: float = STILL_RADPS,
    ) -> None:
        if len(rotation) != 3:
            raise ValueError(f"{name}: rotation must be [roll_rad, pitch_rad, yaw_rad], got {list(rotation)}")
        super().__init__(name, now=now, max_age_s=max_age_s, port=port)
        self.baudrate = baudrate
        self._serial: serial.Serial | None = None
        self._decoder = wit.FrameDecoder()
        self._frames_at_open = 0
        self._bytes_at_open = 0
        self._assembler = SampleAssembler(rotation, GyroBiasEstimator(bias_s, still_radps, name))

    @classmethod
    def from_config(cls, cfg: ImuDeviceConfig, *, now: Callable[[], float], name: str = "imu") -> Wt901Driver:
        """The driver the ``devices.imu`` section describes."""
        return cls(cfg.port, now=now, baudrate=cfg.baudrate, rotation=cfg.rotation, bias_s=cfg.bias_s, name=name)

    # -- what the robot reads ----------------------------------------------------------------------------------
    @property
    def bad_frames(self) -> int:
        """Frames dropped for a bad checksum since the start (noise on the line, or a wrong baud rate)."""
        return self._decoder.bad_frames

    @property
    def sample_rate_hz(self) -> float | None:
        """Samples per second measured over the last 50, None before two."""
        return self._assembler.rate_hz

    @property
    def gyro_bias_radps(self) -> wit.Vector3:
        """The gyro bias subtracted now (sensor axes), measured after the last (re)connection."""
        return self._assembler.bias.bias

    @property
    def bias_settled(self) -> bool:
        """Whether the bias measurement window after the last (re)connection has ended."""
        return self._assembler.bias.settled

    def info(self) -> DeviceInfo:
        return DeviceInfo(kind="imu", driver="wt901", port=self.port, model="WT901")

    def health(self, now: float) -> ComponentHealth:
        """As the base's, plus a hint when bytes arrive but never a frame: a wrong baud rate looks so."""
        status = super().health(now)
        if status.ok or not self.connected:
            return status
        if self._decoder.frames == self._frames_at_open and self._decoder.bytes_seen > self._bytes_at_open:
            return ComponentHealth(False, f"{status.detail}; bytes arrive but no valid WT901 frame: is the baud "
                                          f"rate {self.baudrate} the device's (WT901 default 9600)?")
        return status

    def missing_hint(self, error: BaseException) -> str:
        return serial_port_hint(self.name, self.port or "?", error, device="the WT901", udev_name="/dev/imu")

    # -- the reader thread -----------------------------------------------------------------------------------
    def _open(self) -> None:
        port = serial.Serial(self.port, self.baudrate, timeout=READ_TIMEOUT_S)
        try:
            port.reset_input_buffer()  # bytes from before this connection belong to no sample of it
        except Exception:
            port.close()
            raise
        self._serial = port
        self._decoder.clear()
        self._frames_at_open = self._decoder.frames
        self._bytes_at_open = self._decoder.bytes_seen
        self._assembler.reset()

    def _read(self) -> list[ImuSample]:
        port = self._serial
        if port is None:
            raise OSError(f"{self.name}: {self.port} is not open")
        data = port.read(1)  # blocks up to READ_TIMEOUT_S; raises when the device is gone
        if not data:
            return []
        data += port.read(port.in_waiting)
        t = self.stamp()
        samples = []
        for frame in self._decoder.feed(data):
            sample = self._assembler.add(frame, t)
            if sample is not None:
                samples.append(sample)
        return samples

    def _close(self) -> None:
        port, self._serial = self._serial, None
        if port is None:
            return
        try:
            port.close()
        except Exception as exc:  # closing a port whose device vanished may fail; it is closed all the same
            log.debug("%s: closing %s: %s", self.name, self.port, exc)
