"""The SLAMTEC RPLidar A2M8 on a USB serial port: one `LaserScan` per revolution.

Opening the device (`RplidarDriver._open`, run again after every reconnection) follows what the SDK does:

1. STOP whatever the device is doing (after a host crash it may still be streaming) and drain the line
   until it is quiet, so the next answer is not lost in old samples;
2. GET_HEALTH: a warning is logged and scanning goes on; an error status makes the driver send RESET and
   refuse to scan, and the device's health says so with the error code (opening is retried every
   `REOPEN_S`, so a device whose reset cleared the error comes back by itself);
3. GET_INFO: model, firmware, hardware and serial number, for `info`;
4. start the motor: on an A2 the USB adapter drives the motor from the DTR line (low: spin), and the
   accessory board takes MOTOR_PWM with the configured duty. A pseudo-terminal (the emulator) or an
   adapter without modem lines refuses the DTR ioctl; that is "no motor line", not an error;
5. SCAN (5-byte samples) or EXPRESS_SCAN (legacy capsules), as ``scan_mode`` says.

The reader then decodes the stream (`atemr.io.devices.rplidar_protocol`), cuts it into revolutions at the
start flags and bins each into a counter-clockwise `LaserScan` stamped with the robot's clock on arrival.
Corrupted bytes are skipped (the decoder resynchronises) and counted in ``bad_bytes``. A device that sends
no valid sample for `SILENCE_RESTART_S` (it reset itself, its motor stalled) is reopened, which restarts its
scan, and a port that fails (unplugged) is closed and reopened by `ThreadedDevice` until the device is back.
"""

from __future__ import annotations

import errno
import logging
import time
from collections.abc import Callable, Sequence

import serial

from atemr.errors import HardwareError, ProtocolError
from atemr.io.devices import rplidar_protocol as rp
from atemr.io.devices.base import DeviceInfo, ThreadedDevice, serial_port_hint
from atemr.io.devices.config import LidarDeviceConfig
from atemr.msgs import LaserScan, Pose2D

log = logging.getLogger(__name__)

#: How long one read waits for the first byte; bounds the reader thread's reaction to ``shutdown``.
READ_TIMEOUT_S = 0.05
#: How long a request waits for its answer.
ANSWER_TIMEOUT_S = 1.0
#: After STOP the line must stay quiet this long before a request (bytes in flight are dropped).
QUIET_S = 0.02
#: Draining after STOP gives up (the device keeps talking) after this long.
DRAIN_MAX_S = 0.5
#: How old the newest scan may be before the lidar counts as silent (five revolutions at 10 Hz).
MAX_AGE_S = 0.5
#: No scan sample for this long while scanning: the device is reopened and its scan restarted.
SILENCE_RESTART_S = 2.0
#: Errors of the DTR ioctl that mean "this port has no modem lines" (a pty, some adapters).
NO_MODEM_LINES = (errno.ENOTTY, errno.EINVAL)


class RplidarDriver(ThreadedDevice[LaserScan]):
    """An RPLidar A2M8 on a serial port (see the module docstring)."""

    def __init__(
        self,
        port: str,
        *,
        now: Callable[[], float],
        name: str = "lidar",
        baudrate: int = 115200,
        beams: int = 360,
        range_min_m: float = 0.15,
        range_max_m: float = 12.0,
        pose: Pose2D | Sequence[float] = (0.0, 0.0, 0.0),
        scan_mode: str = "standard",
        motor_pwm: int = 660,
        max_age_s: float = MAX_AGE_S,
    ) -> None:
        super().__init__(name, now=now, max_age_s=max_age_s, port=port)
        if scan_mode not in ("standard", "express"):
            raise ValueError(f"{name}: scan_mode must be 'standard' or 'express', got {scan_mode!r}")
        self.baudrate = baudrate
        self.beams = beams
        self.range_min_m = range_min_m
        self.range_max_m = range_max_m
        self.pose = pose if isinstance(pose, Pose2D) else Pose2D(*pose)
        self.scan_mode = scan_mode
        self.motor_pwm = motor_pwm
        self.lidar_info: rp.LidarInfo | None = None
        self.lidar_health: rp.LidarHealth | None = None
        self.motor_line: bool | None = None
        self._serial: serial.Serial | None = None
        self._decoder: rp.ScanDecoder | rp.ExpressScanDecoder = self._new_decoder()
        self._revolutions = rp.RevolutionAssembler()
        self._bad_before = 0
        self._last_data = 0.0
        self._rate_start = 0.0
        self._rate_samples = 0
        self.sample_rate_hz: float | None = None

    @classmethod
    def from_config(cls, cfg: LidarDeviceConfig, *, now: Callable[[], float], name: str = "lidar") -> RplidarDriver:
        """The driver the ``devices.lidar`` section describes."""
        return cls(cfg.port, now=now, name=name, baudrate=cfg.baudrate, beams=cfg.beams,
                   range_min_m=cfg.range_min_m, range_max_m=cfg.range_max_m, pose=Pose2D(*cfg.pose),
                   scan_mode=cfg.scan_mode, motor_pwm=cfg.motor_pwm)

    # -- what the robot reads ----------------------------------------------------------------------------------
    @property
    def bad_bytes(self) -> int:
        """Bytes skipped as corrupt since the start, over every connection (line noise, a wrong baud rate)."""
        return self._bad_before + self._decoder.bad_bytes

    def info(self) -> DeviceInfo:
        li = self.lidar_info
        if li is None:
            return DeviceInfo(kind="lidar", driver="rplidar", port=self.port)
        return DeviceInfo(kind="lidar", driver="rplidar", port=self.port,
                          model=f"RPLidar {li.model_name} (hardware {li.hardware})", firmware=li.firmware,
                          serial_number=li.serial_number)

    def missing_hint(self, error: BaseException) -> str:
        port = self.port or "?"
        if isinstance(error, HardwareError):  # names the component already
            return str(error)
        if isinstance(error, ProtocolError):
            return f"{self.name}: {error}"
        return serial_port_hint(self.name, port, error, device="the RPLidar's USB adapter", udev_name="/dev/rplidar")

    # -- the reader thread -----------------------------------------------------------------------------------
    def _open(self) -> None:
        port = serial.Serial(self.port, self.baudrate, timeout=READ_TIMEOUT_S, write_timeout=ANSWER_TIMEOUT_S)
        self._serial = port
        try:
            self._start(port)
        except BaseException:
            self._close()
            raise

    def _start(self, port: serial.Serial) -> None:
        port.write(rp.encode_request(rp.Command.STOP))
        self._drain(port)
        health = rp.parse_health(self._request(port, rp.Command.GET_HEALTH, rp.AnswerType.HEALTH, rp.HEALTH_LEN))
        self.lidar_health = health
        if health.status == rp.HealthStatus.ERROR:
            port.write(rp.encode_request(rp.Command.RESET))
            raise HardwareError(f"the RPLidar on {self.port} reports an error (health status 2, error code "
                                f"0x{health.error_code:04X}); it was reset and is checked again every few tenths "
                                "of a second; if the error stays, power-cycle it or see SLAMTEC support",
                                component=self.name)
        if health.status != rp.HealthStatus.GOOD:
            log.warning("%s: the RPLidar on %s reports %s (error code 0x%04X); scanning anyway", self.name,
                        self.port, health.status_name, health.error_code)
        self.lidar_info = rp.parse_info(self._request(port, rp.Command.GET_INFO, rp.AnswerType.INFO, rp.INFO_LEN))
        self._start_motor(port)
        self._start_scan(port)

    def _start_motor(self, port: serial.Serial) -> None:
        try:
            port.dtr = False  # the A2's USB adapter spins the motor while DTR is low
            self.motor_line = True
        except OSError as exc:
            if exc.errno not in NO_MODEM_LINES:
                raise
            self.motor_line = False
        port.write(rp.motor_pwm_request(self.motor_pwm))

    def _start_scan(self, port: serial.Serial) -> None:
        old = self._decoder
        self._bad_before += old.bad_bytes
        self._decoder = self._new_decoder()
        self._revolutions.clear()
        if self.scan_mode == "express":
            rest = self._request(port, rp.Command.EXPRESS_SCAN, rp.AnswerType.MEASUREMENT_CAPSULED, rp.CAPSULE_LEN,
                                 request=rp.express_scan_request(), stream=True)
        else:
            rest = self._request(port, rp.Command.SCAN, rp.AnswerType.MEASUREMENT, rp.SAMPLE_LEN, stream=True)
        self._revolutions.push(self._decoder.feed(rest))
        self._last_data = self._rate_start = time.monotonic()
        self._rate_samples = 0

    def _new_decoder(self) -> rp.ScanDecoder | rp.ExpressScanDecoder:
        return rp.ExpressScanDecoder() if self.scan_mode == "express" else rp.ScanDecoder()

    def _drain(self, port: serial.Serial) -> None:
        """Read and drop until the line has been quiet for `QUIET_S` (or `DRAIN_MAX_S` passed)."""
        deadline = time.monotonic() + DRAIN_MAX_S
        quiet_since = time.monotonic()
        while time.monotonic() < deadline:
            if port.in_waiting:
                port.read(port.in_waiting)
                quiet_since = time.monotonic()
            elif time.monotonic() - quiet_since >= QUIET_S:
                return
            else:
                time.sleep(0.002)
        log.warning("%s: %s kept sending for %.1f s after STOP", self.name, self.port, DRAIN_MAX_S)

    def _request(self, port: serial.Serial, cmd: rp.Command, answer: rp.AnswerType, length: int, *,
                 request: bytes | None = None, stream: bool = False) -> bytes:
        """Send ``cmd`` and wait for its descriptor; a single answer's data, or for a stream (``stream``) the
        bytes already received after the descriptor."""
        port.write(request if request is not None else rp.encode_request(cmd))
        buf = bytearray()
        deadline = time.monotonic() + ANSWER_TIMEOUT_S
        while True:
            at = rp.find_descriptor(buf)
            if at >= 0 and len(buf) - at >= rp.DESCRIPTOR_LEN:
                descriptor = rp.parse_descriptor(buf[at:at + rp.DESCRIPTOR_LEN])
                self._check_descriptor(cmd, descriptor, answer, length, stream)
                data = buf[at + rp.DESCRIPTOR_LEN:]
                if stream:
                    return bytes(data)
                if len(data) >= length:
                    return bytes(data[:length])
            if time.monotonic() > deadline:
                seen = f"got {len(buf)} bytes: {bytes(buf[:16]).hex(' ')}" if buf else "got nothing"
                raise ProtocolError(f"no answer to {cmd.name} within {ANSWER_TIMEOUT_S:.0f} s on "
                                    f"{self.port} ({seen}): is it an RPLidar, at {self.baudrate} baud?")
            buf += port.read(max(1, port.in_waiting))

    def _check_descriptor(self, cmd: rp.Command, d: rp.ResponseDescriptor, answer: rp.AnswerType, length: int,
                          stream: bool) -> None:
        mode = rp.SendMode.MULTIPLE if stream else rp.SendMode.SINGLE
        if d.data_type != answer or d.length != length or d.send_mode != mode:
            raise ProtocolError(f"{cmd.name} on {self.port} answered type 0x{d.data_type:02X}, "
                                f"{d.length} bytes, send mode {d.send_mode}; expected type 0x{answer:02X}, "
                                f"{length} bytes, send mode {mode}")

    def _read(self) -> list[LaserScan]:
        port = self._serial
        if port is None:
            raise OSError(f"{self.name}: {self.port} is not open")
        try:
            data = port.read(1)  # blocks up to READ_TIMEOUT_S; raises when the device is gone
            if data:
                data += port.read(port.in_waiting)
        except serial.SerialException as exc:  # already an OSError; say where
            raise OSError(f"reading {self.port}: {exc}") from exc
        clock = time.monotonic()
        samples = self._decoder.feed(data) if data else []
        if samples:
            self._last_data = clock
        elif clock - self._last_data > SILENCE_RESTART_S:
            raise TimeoutError(f"no scan sample for {SILENCE_RESTART_S:g} s (motor stalled? device reset? noise "
                               "only?); restarting the scan")
        self._count_rate(len(samples), clock)
        revolutions = self._revolutions.push(samples)
        if not revolutions:
            return []
        t = self.stamp()
        return [rp.revolution_to_scan(rev, t, beams=self.beams, range_min_m=self.range_min_m,
                                      range_max_m=self.range_max_m, pose=self.pose) for rev in revolutions]

    def _count_rate(self, n: int, clock: float) -> None:
        """Samples per second over windows of about a second (``sample_rate_hz``)."""
        self._rate_samples += n
        if clock - self._rate_start >= 1.0:
            self.sample_rate_hz = self._rate_samples / (clock - self._rate_start)
            self._rate_start, self._rate_samples = clock, 0

    def _close(self) -> None:
        port, self._serial = self._serial, None
        if port is None:
            return
        for what, action in (("STOP", lambda: port.write(rp.encode_request(rp.Command.STOP))),
                             ("MOTOR_PWM 0", lambda: port.write(rp.motor_pwm_request(0))),
                             ("DTR high", lambda: setattr(port, "dtr", True))):
            try:
                action()
            except Exception as exc:  # the device may be gone: closing goes on
                log.debug("%s: %s on %s: %s", self.name, what, self.port, exc)
        try:
            port.close()
        except Exception as exc:  # closing a port whose device vanished may fail; it is closed all the same
            log.debug("%s: closing %s: %s", self.name, self.port, exc)
