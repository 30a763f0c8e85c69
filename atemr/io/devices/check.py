"""Open every configured device, watch it for a moment, and say what answers and what to do about what
does not: ``atemr hw check``, and the start-up check of ``atemr run`` on the real robot.

Each device is built with the same driver the robot would use and read for ``seconds`` (2 s by default):
one `CheckRow` per device with its driver, port, model or firmware where the device reports them, the
rate measured over that window, its health and, when it is missing, the hint its driver gives (the port,
the ``dialout`` group, ``ip link set can0 up type can bitrate 1000000``). Devices driven by the simulator
(``sim``, ``emulated``) live inside the robot's process and are listed as such, not opened.
"""

from __future__ import annotations

import time
from contextlib import suppress
from dataclasses import asdict, dataclass
from typing import Any

from atemr.clock import WallClock
from atemr.config import Config
from atemr.errors import AtemrError
from atemr.io.devices.base import Device
from atemr.io.devices.config import SIMULATED_DRIVERS
from atemr.io.devices.drivers import DeviceContext, build_device, driver_name

#: Devices without which the robot must not start (the camera is not one: the robot drives without it).
CRITICAL = ("lidar", "imu", "motors", "secondary")
#: What to do when the CAN bus cannot be opened.
CAN_HINT = ("bring the bus up: sudo ip link set {channel} up type can bitrate {bitrate} (and check the "
            "adapter is plugged in: ip -details link show {channel})")


@dataclass(frozen=True)
class CheckRow:
    """One device's answer."""

    device: str
    driver: str
    port: str | None
    model: str | None
    rate_hz: float | None
    ok: bool
    detail: str
    critical: bool

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def line(self) -> str:
        """One human line: ``lidar  rplidar  /dev/ttyUSB0  A2M8 fw 1.29  10.0 Hz  OK``."""
        rate = "" if self.rate_hz is None else f"{self.rate_hz:.1f} Hz"
        status = "OK" if self.ok else ("MISSING" if self.critical else "missing (not critical)")
        parts = [f"{self.device:<9}", f"{self.driver:<8}", f"{self.port or '-':<14}", f"{self.model or '-':<22}",
                 f"{rate:>9}", status]
        text = "  ".join(parts)
        return f"{text}: {self.detail}" if self.detail else text


def check_devices(config: Config, *, seconds: float = 2.0, until_healthy: bool = False,
                  kinds: tuple[str, ...] = ("lidar", "imu", "camera", "depth", "motors", "secondary"),
                  ) -> list[CheckRow]:
    """Open the configured devices, read them for ``seconds``, and report each (see the module docstring).

    ``until_healthy`` ends the window early once every device answers (the start-up check: a present device
    answers in well under a second, a missing one is reported when the window ends).
    """
    clock = WallClock()
    rows: dict[str, CheckRow] = {}
    sensors: dict[str, Device[Any]] = {}
    can_parts: dict[str, Any] = {}
    context = DeviceContext(config, clock.now)  # one for every device: a D415's two streams share its pipeline
    try:
        for kind in kinds:
            driver = driver_name(config, kind)
            if driver in SIMULATED_DRIVERS:
                rows[kind] = CheckRow(kind, driver, None, "simulated, in the robot's process", None, True,
                                      "not opened: it runs inside the robot", kind in CRITICAL)
            elif kind in ("motors", "secondary"):
                can_parts[kind] = driver
            else:
                try:
                    device = build_device(context, kind)
                except AtemrError as exc:
                    rows[kind] = CheckRow(kind, driver, None, None, None, False, str(exc), kind in CRITICAL)
                    continue
                if device is None:
                    rows[kind] = CheckRow(kind, driver, None, None, None, True, "no device configured", False)
                    continue
                sensors[kind] = device
        _watch(config, clock, sensors, can_parts, rows, seconds=seconds, until_healthy=until_healthy)
    finally:
        for device in sensors.values():
            stop = getattr(device, "shutdown", None)
            if stop is not None:
                with suppress(Exception):
                    stop()
    return [rows[k] for k in kinds if k in rows]


def _watch(config: Config, clock: WallClock, sensors: dict[str, Device[Any]], can_parts: dict[str, str],
           rows: dict[str, CheckRow], *, seconds: float, until_healthy: bool) -> None:
    """Read the opened devices for the window and fill ``rows``."""
    can = _CanCheck(config, clock, can_parts, rows) if can_parts else None
    for device in sensors.values():
        start = getattr(device, "start", None)
        if start is not None:
            start()
    t0 = clock.now()
    counts0 = {k: d.count for k, d in sensors.items()}
    first: dict[str, float] = {}
    try:
        while True:
            now = clock.now()
            for kind, device in sensors.items():
                device.tick(now)
                if kind not in first and device.count > counts0[kind]:
                    first[kind] = now
            if can is not None:
                can.tick(now)
            done = now - t0 >= seconds
            if until_healthy and not done:
                done = all(d.health(now).ok for d in sensors.values()) and (can is None or can.all_ok(now))
            if done:
                break
            time.sleep(0.01)
        now = clock.now()
        for kind, device in sensors.items():
            health = device.health(now)
            info = device.info()
            since = first.get(kind)
            n = device.count - counts0[kind]
            rate = (n - 1) / (now - since) if since is not None and n > 1 and now > since else None
            model = " ".join(p for p in (info.model, f"fw {info.firmware}" if info.firmware else None) if p)
            rows[kind] = CheckRow(kind, info.driver, info.port, model or None, rate, health.ok,
                                  "" if health.ok else health.detail, kind in CRITICAL)
        if can is not None:
            can.report(now)
    finally:
        if can is not None:
            can.close()


class _CanCheck:
    """The motors and the secondary core on the configured CAN bus: the motor driver polls both motors and
    the link exchanges heartbeats, as on the robot, for the check's window."""

    def __init__(self, config: Config, clock: WallClock, parts: dict[str, str], rows: dict[str, CheckRow]) -> None:
        from atemr.io.can.bus import open_bus

        self.config = config
        self.parts = parts
        self.rows = rows
        self.bus: Any = None
        self.driver: Any = None
        self.link: Any = None
        port = f"{config.can.interface}:{config.can.channel}"
        try:
            self.bus = open_bus(config.can)
        except AtemrError as exc:
            hint = CAN_HINT.format(channel=config.can.channel, bitrate=config.can.bitrate)
            for kind, driver in parts.items():
                rows[kind] = CheckRow(kind, driver, port, None, None, False, f"{exc}; {hint}", kind in CRITICAL)
            return
        self._open_parts(clock.now())

    def _open_parts(self, now: float) -> None:
        from atemr.io.can.supervisor import BusSupervisor
        from atemr.io.motors.driver import RmdDriver
        from atemr.io.secondary_link import build_secondary_link

        self.supervisor = BusSupervisor(self.bus, threaded=True, name="can_check", close_bus=False)
        self.supervisor.start()
        if "motors" in self.parts:
            self.driver = RmdDriver.from_config(self.supervisor.inbox("motors"), self.config.motors,
                                                protocol=self.config.devices.motors.protocol)
            self.driver.start()
        if "secondary" in self.parts:
            self.link = build_secondary_link(self.config, self.supervisor.inbox("secondary_link"))
            self.link.start()

    def tick(self, now: float) -> None:
        if self.bus is None:
            return
        self.supervisor.tick(now)
        if self.driver is not None:
            self.driver.tick(now)
        if self.link is not None:
            self.link.tick(now)

    def _motor_state(self, now: float) -> tuple[bool, str]:
        silent = [s.side for s in self.driver.states.values()
                  if s.last_reply_t is None or now - s.last_reply_t > 1.0]
        if silent:  # the cause to name, before the fault the driver latched for it
            ids = ", ".join(f"{side} (id {self.driver.ids[side]})" for side in silent)
            return False, (f"no reply from the {ids} motor on {self.config.can.channel}: check the motor's power, "
                           f"its id (motors.left_id/right_id) and the bus wiring and termination")
        if self.driver.fault is not None:
            return False, str(self.driver.fault)
        return True, ""

    def _link_state(self, now: float) -> tuple[bool, str]:
        health = self.link.health(now)
        if health.ok:
            return True, ""
        return False, f"{health.detail} on {self.config.can.channel}: is the ESP32 powered and on the bus?"

    def all_ok(self, now: float) -> bool:
        if self.bus is None:
            return True
        ok = True
        if self.driver is not None:
            ok = ok and self._motor_state(now)[0]
        if self.link is not None:
            ok = ok and self._link_state(now)[0] and self.link.count > 0  # an IR reading came too
        return ok

    def report(self, now: float) -> None:
        if self.bus is None:
            return
        port = f"{self.config.can.interface}:{self.config.can.channel}"
        if self.driver is not None:
            ok, detail = self._motor_state(now)
            states = self.driver.states.values()
            model = ", ".join(f"{s.side} {s.temperature_c:.0f} °C" for s in states
                              if getattr(s, "temperature_c", None) is not None) or None
            self.rows["motors"] = CheckRow("motors", self.parts["motors"], port, model,
                                           self.config.motors.rate_hz if ok else None, ok, detail, True)
        if self.link is not None:
            ok, detail = self._link_state(now)
            self.rows["secondary"] = CheckRow("secondary", self.parts["secondary"], port, None, None, ok, detail,
                                              True)

    def close(self) -> None:
        for part in (self.link, self.driver):
            if part is not None:
                with suppress(Exception):
                    part.shutdown()
        if self.bus is not None:
            with suppress(Exception):
                self.supervisor.shutdown()
            with suppress(Exception):
                self.bus.shutdown()


def missing_critical(rows: list[CheckRow]) -> list[CheckRow]:
    """The rows of critical devices that did not answer."""
    return [r for r in rows if r.critical and not r.ok]


