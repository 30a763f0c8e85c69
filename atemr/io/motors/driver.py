"""The drive motors as one differential pair: commands out, feedback in, watchdog and fault handling.

`DriveMotors` is the template: it owns what every motor pair must do whatever the wire — the 0.5 s
command watchdog, the fault latch ("one motor silent or in error → both stop and the agent is told"),
idempotent shutdown and context management. `RmdDriver` owns the wire: MyActuator RMD-L frames on a
python-can bus, polled in `tick` (no threads, so a simulation stays deterministic), in either protocol
version the RMD-L ships with (``protocol``: ``v1`` = V1.61 or ``v4`` = V4.2, `atemr.io.motors.rmd_protocol`).

Units at this API are wheel speeds in rad/s, positive driving the robot forward on either side
(`atemr.msgs.WheelSpeeds`); each motor's mounting direction (``+1``/``-1``) is applied inside.
"""

from __future__ import annotations

import logging
import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Self

import can

from atemr.clock import due
from atemr.config import MotorsConfig
from atemr.domain.status import ComponentHealth
from atemr.errors import BusError, HardwareError, ProtocolError
from atemr.io.can.protocol import is_protocol_id
from atemr.io.devices.base import DeviceInfo, Publishes, Subscribers, fresh
from atemr.io.motors.rmd_codec import MotorErrorFlags, RmdCommand, RmdRequest, Status1Reply, Status2Reply
from atemr.io.motors.rmd_protocol import AnyReply, RmdProtocol, rmd_protocol
from atemr.io.motors.rmd_v4 import V4Status1Reply, V4Status2Reply
from atemr.msgs import WheelSpeeds

log = logging.getLogger(__name__)

SIDES = ("left", "right")


def check_motor_ids(motor_ids: tuple[int, ...], *, component: str, protocol: str | RmdProtocol = "v1") -> None:
    """Refuse motor ids whose request or reply ID (0x140 + id; V4.2 replies 0x240 + id) is one of the inter-core
    protocol's 0x150-0x157: the two would be taken for each other."""
    codec = rmd_protocol(protocol)
    for motor_id in motor_ids:
        try:
            can_ids = (codec.request_id(motor_id), codec.reply_id(motor_id))
        except ProtocolError as exc:
            raise HardwareError(str(exc), component=component) from None
        for can_id in can_ids:
            if is_protocol_id(can_id):
                raise HardwareError(f"motor id {motor_id} would use 0x{can_id:03X}, an ID of the inter-core "
                                    f"protocol; use 1-15 or 24-32", component=component)


def wheel_speeds_from_mps(left_mps: float, right_mps: float, wheel_radius_m: float) -> WheelSpeeds:
    """Wheel rim speeds in m/s → wheel speeds in rad/s for a wheel of ``wheel_radius_m``."""
    if not (math.isfinite(wheel_radius_m) and wheel_radius_m > 0):
        raise HardwareError(f"wheel radius must be a finite number > 0 m, got {wheel_radius_m!r}", component="motors")
    return WheelSpeeds(left_mps / wheel_radius_m, right_mps / wheel_radius_m)


def wheel_speeds_to_mps(speeds: WheelSpeeds, wheel_radius_m: float) -> tuple[float, float]:
    """Wheel speeds in rad/s → (left, right) rim speeds in m/s."""
    if not (math.isfinite(wheel_radius_m) and wheel_radius_m > 0):
        raise HardwareError(f"wheel radius must be a finite number > 0 m, got {wheel_radius_m!r}", component="motors")
    return speeds.left_radps * wheel_radius_m, speeds.right_radps * wheel_radius_m


@dataclass(frozen=True)
class MotorState:
    """What is known about one motor from its last replies (wheel frame: forward positive).

    Status 2 carries the shaft position as V1.61's 14-bit ``encoder`` or as V4.2's output-shaft ``angle_rad``
    (int16 degrees); the other stays at its default.
    """

    side: str
    motor_id: int
    speed_radps: float = 0.0
    encoder: int = 0
    angle_rad: float | None = None
    current_a: float = 0.0
    temperature_c: int = 0
    voltage_v: float = 0.0
    errors: MotorErrorFlags = MotorErrorFlags.NONE
    last_reply_t: float | None = None
    last_feedback_t: float | None = None


@dataclass(frozen=True)
class MotorsReading:
    """Both motors as their latest replies left them, at time ``t`` (the motors' reading as a device)."""

    t: float
    left: MotorState
    right: MotorState


@dataclass(frozen=True)
class WatchdogEvent:
    """The command watchdog tripped (``tripped``) or was satisfied again by a fresh command."""

    t: float
    tripped: bool
    age_s: float


class DriveMotors(ABC):
    """Base of a left/right motor pair; subclasses implement `_exchange` and `_stop_now`.

    ``command_timeout_s``: no fresh command for this long → command zero and report it (0.5 s, as
    ROS diff_drive_controller). ``silence_timeout_s``: a motor that has not answered for this long is
    silent → fault. A fault stops both motors at once and is latched: `check` and `set_speeds` raise
    it as `HardwareError` until `reset_fault`; ``on_fault`` (if given) is called once when it occurs.
    """

    name: str

    def __init__(self, *, command_timeout_s: float = 0.5, silence_timeout_s: float = 0.3,
                 on_fault: Callable[[HardwareError], None] | None = None,
                 on_watchdog: Callable[[WatchdogEvent], None] | None = None) -> None:
        if not command_timeout_s > 0 or not silence_timeout_s > 0:
            raise HardwareError("command and silence timeouts must be > 0", component="motors")
        self.command_timeout_s = command_timeout_s
        self.silence_timeout_s = silence_timeout_s
        self.on_fault = on_fault
        self.on_watchdog = on_watchdog
        self.fault: HardwareError | None = None
        self.watchdog_tripped = True  # nothing commanded yet: zero until the first command
        self.watchdog_trips = 0
        self._command = WheelSpeeds()
        self._command_t: float | None = None
        self._started_t: float | None = None
        self._closed = False

    # -- the agent's side -----------------------------------------------------------------------
    def set_speeds(self, speeds: WheelSpeeds, now: float) -> None:
        """Command wheel speeds (rad/s) at time ``now``; raises the latched fault if there is one."""
        self.check()
        for value in (speeds.left_radps, speeds.right_radps):
            if not math.isfinite(value):
                raise HardwareError(f"wheel speed must be finite, got {speeds}", component=self.name)
        self._command = speeds
        self._command_t = now

    def stop(self, now: float) -> None:
        """Command zero speed now (counts as a fresh command)."""
        self._command = WheelSpeeds()
        self._command_t = now

    def check(self) -> None:
        """Raise the latched fault, if any, as `HardwareError` (the agent's Monitor calls this)."""
        if self.fault is not None:
            raise self.fault

    def reset_fault(self) -> None:
        """Forget the fault (after the cause is fixed); the motors stay at zero until commanded."""
        self.fault = None
        self._command = WheelSpeeds()
        self._command_t = None

    @property
    def commanded(self) -> WheelSpeeds:
        """What is being sent now: zero when the watchdog has tripped or a fault is latched."""
        if self.fault is not None or self.watchdog_tripped:
            return WheelSpeeds()
        return self._command

    # -- scheduler component --------------------------------------------------------------------
    def tick(self, now: float) -> None:
        """Read replies, run the watchdog and the health checks, send this period's commands."""
        if self._closed:
            return
        if self._started_t is None:
            self._started_t = now
        step = "receive"  # a dead receive side must not be reported as a send failure
        try:
            self._receive(now)
            step = "send"
            self._watchdog(now)
            if self.fault is None:
                problem = self._health(now)
                if problem is not None:
                    self._raise_fault(problem, now)
            self._exchange(self.commanded, now)
        except can.CanError as exc:
            self._raise_fault(BusError(f"CAN {step} failed: {exc}", component=self.name, critical=True), now)

    def _watchdog(self, now: float) -> None:
        age = math.inf if self._command_t is None else now - self._command_t
        tripped = age > self.command_timeout_s
        if tripped != self.watchdog_tripped:
            self.watchdog_tripped = tripped
            if tripped:
                self.watchdog_trips += 1
                log.warning("%s: no speed command for %.2f s: commanding zero", self.name, age)
            event = WatchdogEvent(now, tripped, age)
            if self.on_watchdog is not None:
                self.on_watchdog(event)

    def _raise_fault(self, fault: HardwareError, now: float) -> None:
        try:
            self._stop_now(now)
        except can.CanError as exc:
            log.error("%s: could not send the stop: %s", self.name, exc)
        if self.fault is not None:
            return
        self.fault = fault
        log.error("%s: both motors stopped: %s", self.name, fault)
        if self.on_fault is not None:
            self.on_fault(fault)

    # -- what a wire implements -----------------------------------------------------------------
    @abstractmethod
    def _receive(self, now: float) -> None:
        """Take in every pending reply."""

    @abstractmethod
    def _health(self, now: float) -> HardwareError | None:
        """The problem with the motors at ``now``, if any."""

    @abstractmethod
    def _exchange(self, command: WheelSpeeds, now: float) -> None:
        """Send this period's frames for ``command``."""

    @abstractmethod
    def _stop_now(self, now: float) -> None:
        """Stop both motors immediately."""

    @abstractmethod
    def _close(self) -> None:
        """Release the wire."""

    def shutdown(self) -> None:
        """Stop both motors and release the wire; idempotent."""
        if self._closed:
            return
        try:
            self._stop_now(self._command_t or 0.0)
        except can.CanError as exc:
            log.error("%s: could not stop the motors on shutdown: %s", self.name, exc)
        finally:
            self._closed = True
            self._close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()


class RmdDriver(Publishes[MotorsReading], DriveMotors):
    """Two RMD-L-7015 on ``bus`` (its own Bus instance; closed by `shutdown` when ``close_bus``).

    Every tick sends a SPEED_CONTROL to each motor (its reply is status 2: speed, position, current) and
    every ``status_period_s`` a READ_STATUS_1 (temperature, voltage, error flags). Schedule it at
    ``rate_hz`` ≥ 20 so a silent motor is noticed within ``silence_timeout_s``.
    ``directions`` is the sign that turns a forward wheel speed into that motor's shaft speed.

    ``protocol`` (``v1`` or ``v4``, the ``devices.motors.protocol`` setting) is the version the motors speak:
    the driver listens for replies on that version's IDs (0x140 + id, or 0x240 + id) and sends only commands
    it has. V4.2 has no MOTOR_RUN (`motor_on` just lets the next speed command resume) and no CLEAR_ERRORS:
    its level-2 errors (under-voltage, over-temperature, ...) clear by themselves once the cause is gone, so
    the driver only polls status 1; its level-1 errors (stall, over-current) need the motor checked and
    restarted, which is an operator's decision (`system_reset`), never the driver's own.
    """

    def __init__(self, bus: can.BusABC, *, left_id: int = 1, right_id: int = 2,
                 directions: tuple[int, int] = (1, -1), status_period_s: float = 0.2,
                 command_timeout_s: float = 0.5, silence_timeout_s: float = 0.3,
                 on_fault: Callable[[HardwareError], None] | None = None,
                 on_watchdog: Callable[[WatchdogEvent], None] | None = None,
                 name: str = "motors", close_bus: bool = True, protocol: str | RmdProtocol = "v1") -> None:
        super().__init__(command_timeout_s=command_timeout_s, silence_timeout_s=silence_timeout_s,
                         on_fault=on_fault, on_watchdog=on_watchdog)
        if left_id == right_id:
            raise HardwareError(f"left and right motor share id {left_id}", component=name)
        self.protocol = rmd_protocol(protocol)
        check_motor_ids((left_id, right_id), component=name, protocol=self.protocol)
        if any(d not in (1, -1) for d in directions):
            raise HardwareError(f"directions must be +1 or -1, got {directions}", component=name)
        self.bus = bus
        self.name = name
        self.close_bus = close_bus
        self.status_period_s = status_period_s
        self.ids = {"left": left_id, "right": right_id}
        self.directions = dict(zip(SIDES, directions, strict=True))
        self._by_reply_id = {self.protocol.reply_id(mid): side for side, mid in self.ids.items()}
        self.states = {side: MotorState(side, mid) for side, mid in self.ids.items()}
        self.rate_hz: float | None = None  # the robot ticks it at motors.rate_hz (`from_config` sets it)
        self._out: Subscribers[MotorsReading] = Subscribers(name)
        self.bad_frames = 0
        self.output_off = False
        self._last_status1_t: float | None = None

    @classmethod
    def from_config(cls, bus: can.BusABC, config: MotorsConfig, *, protocol: str | RmdProtocol = "v1",
                    on_fault: Callable[[HardwareError], None] | None = None,
                    on_watchdog: Callable[[WatchdogEvent], None] | None = None) -> RmdDriver:
        """The driver described by the ``motors`` configuration section (schedule it at ``config.rate_hz``);
        ``protocol`` is ``devices.motors.protocol``, which lives in another section."""
        driver = cls(bus, left_id=config.left_id, right_id=config.right_id,
                     directions=(config.left_direction, config.right_direction),
                     status_period_s=config.status_period_s, command_timeout_s=config.command_timeout_s,
                     silence_timeout_s=config.silence_timeout_s, on_fault=on_fault, on_watchdog=on_watchdog,
                     protocol=protocol)
        driver.rate_hz = config.rate_hz
        return driver

    # -- readings -------------------------------------------------------------------------------
    def feedback(self) -> WheelSpeeds:
        """Measured wheel speeds (rad/s, forward positive) from the last status-2 replies."""
        return WheelSpeeds(self.states["left"].speed_radps, self.states["right"].speed_radps)

    # -- the device interface (`atemr.io.devices.base.Device`) -------------------------------------
    # ``latest`` (both motors after the latest replies), ``count`` and ``subscribe`` (called after every tick
    # that brought replies): `Publishes`.

    def side_health(self, side: str, now: float) -> ComponentHealth:
        """One motor's health (the 0x153 hardware bits are per motor): no latched fault, and a reply within
        twice ``silence_timeout_s``."""
        if self.fault is not None:
            return ComponentHealth(False, str(self.fault))
        return fresh(self.states[side].last_reply_t, now, 2 * self.silence_timeout_s, f"{side} motor reply")

    def health(self, now: float) -> ComponentHealth:
        """Both motors healthy, or the first problem."""
        for side in SIDES:
            health = self.side_health(side, now)
            if not health.ok:
                return health
        return ComponentHealth(True)

    def info(self) -> DeviceInfo:
        channel = getattr(self.bus, "channel_info", None)
        return DeviceInfo(kind="motors", driver="rmd", port=str(channel) if channel else None,
                          model=f"2 x RMD-L-7015 (ids {self.ids['left']}, {self.ids['right']})",
                          firmware=f"protocol {self.protocol.version}")

    @property
    def answering(self) -> bool:
        """Both motors have answered recently (the StartUp check)."""
        return all(s.last_reply_t is not None for s in self.states.values()) and self.fault is None

    # -- wire -----------------------------------------------------------------------------------
    def start(self) -> None:
        """Ask both motors for status 1 so the first tick already has an answer to read."""
        self._send_both(RmdCommand.READ_STATUS_1)

    def _send(self, motor_id: int, command: RmdCommand, speed_radps: float = 0.0) -> None:
        """One request, refused (`ProtocolError`) if the motors' protocol version has no such command."""
        self.bus.send(self.protocol.encode_request(_request(motor_id, command, speed_radps)))

    def _send_both(self, command: RmdCommand) -> None:
        for side in SIDES:
            self._send(self.ids[side], command)

    def _receive(self, now: float) -> None:
        replies = 0
        while (msg := self.bus.recv(timeout=0)) is not None:
            side = self._by_reply_id.get(msg.arbitration_id)
            if side is None or msg.is_extended_id:
                continue
            try:
                reply = self.protocol.decode_reply(msg)
            except ProtocolError as exc:
                self.bad_frames += 1
                log.warning("%s: bad reply from the %s motor: %s", self.name, side, exc)
                continue
            self.states[side] = _updated(self.states[side], reply, self.directions[side], now)
            replies += 1
        if replies:
            self._out.publish(MotorsReading(now, self.states["left"], self.states["right"]))

    def _health(self, now: float) -> HardwareError | None:
        assert self._started_t is not None
        for side, state in self.states.items():
            since = state.last_reply_t if state.last_reply_t is not None else self._started_t
            if now - since > self.silence_timeout_s:
                return HardwareError(f"{side} motor (id {state.motor_id}) silent for {now - since:.2f} s",
                                     component=self.name, critical=True)
            if state.errors:
                return HardwareError(f"{side} motor (id {state.motor_id}) reports "
                                     f"{self.protocol.error_text(state.errors)}", component=self.name, critical=True)
        return None

    def _exchange(self, command: WheelSpeeds, now: float) -> None:
        speeds = {"left": command.left_radps, "right": command.right_radps}
        for side in SIDES:
            if self.fault is None and not self.output_off:
                self._send(self.ids[side], RmdCommand.SPEED_CONTROL, self.directions[side] * speeds[side])
            else:  # no speed commands after a fault or motor_off; status 2 keeps the feedback (odometry) fresh
                self._send(self.ids[side], RmdCommand.READ_STATUS_2)
        if self._last_status1_t is None or due(now, self._last_status1_t + self.status_period_s):
            self._last_status1_t = now
            for side in SIDES:
                if self.fault is not None:  # repeat the stop: the first one may have been lost with the link
                    self._send(self.ids[side], RmdCommand.MOTOR_STOP)
                self._send(self.ids[side], RmdCommand.READ_STATUS_1)

    def _stop_now(self, now: float) -> None:
        self._send_both(RmdCommand.MOTOR_STOP)

    def brake(self, now: float) -> None:
        """Emergency stop: MOTOR_STOP to both motors at once (no ramp) and zero as the command."""
        self.stop(now)
        self._stop_now(now)

    def motor_on(self) -> None:
        """Speed commands again (after `motor_off`, or a MOTOR_STOP from another node): V1.61 motors are sent
        MOTOR_RUN first; V4.2 has no such command, its next speed command resumes."""
        self.output_off = False
        if self.protocol.run_command is not None:
            self._send_both(self.protocol.run_command)

    def motor_off(self) -> None:
        """MOTOR_OFF to both motors: output off, the wheels coast (power-off, after the robot has stopped).

        No speed command is sent until `motor_on` (a speed command would switch a motor back on).
        """
        self.output_off = True
        self._send_both(RmdCommand.MOTOR_OFF)

    def request_error_clear(self) -> None:
        """Ask both motors to clear their error flags but keep the fault latched; the status-1 replies show what
        remains (`clear_motor_errors` also resets the fault).

        V1.61: CLEAR_ERRORS, and a motor drops the flags whose cause is gone. V4.2 has no such command (its
        level-2 errors clear by themselves), so this asks for status 1 to see them go.
        """
        self._send_both(self.protocol.clear_command or RmdCommand.READ_STATUS_1)

    def system_reset(self) -> None:
        """SYSTEM_RESET (0x76) to both V4.2 motors: they restart, the only way to clear a level-1 error (stall,
        over-current) short of a power cycle. An operator's decision once the cause is checked; the driver never
        sends it by itself. V1.61 has no such command: `HardwareError`."""
        if RmdCommand.SYSTEM_RESET not in self.protocol.commands:
            raise HardwareError(f"the motors speak {self.protocol.title}, which has no system reset; "
                                f"clear_motor_errors sends {RmdCommand.CLEAR_ERRORS.name}", component=self.name)
        self._send_both(RmdCommand.SYSTEM_RESET)

    def recover(self, now: float) -> str | None:
        """Clear the latched fault once its cause is gone (the agent's Error state calls this every tick while it
        waits): None when nothing is latched any more, else why not yet.

        The fault is reset only once both motors have answered within ``silence_timeout_s`` (the driver keeps
        polling them while faulted) and report no error flag; a motor still reporting a flag is asked to clear
        it (`request_error_clear`: a flag whose cause is gone clears, and its next status-1 reply shows what
        remains). A V4.2 level-1 error never clears this way: the reason says it needs `system_reset`.
        """
        if self.fault is None:
            return None
        for side, state in self.states.items():
            if state.last_reply_t is None or now - state.last_reply_t > self.silence_timeout_s:
                return f"{side} motor (id {state.motor_id}) not answering"
        flagged = [self._why_flagged(side, state.errors) for side, state in self.states.items() if state.errors]
        if flagged:
            self.request_error_clear()
            return "; ".join(flagged)
        self.clear_motor_errors()
        return None

    def _why_flagged(self, side: str, errors: MotorErrorFlags) -> str:
        why = f"{side} motor reports {self.protocol.error_text(errors)}"
        if self.protocol.clear_command is None and errors & ~self.protocol.self_clearing(errors):
            why += ", which needs a check and then a system reset (0x76) or a power cycle"
        return why

    def clear_motor_errors(self) -> None:
        """Ask both motors to clear their error flags (`request_error_clear`), forget the flags they reported
        (their next status-1 replies refresh them), then `reset_fault`."""
        self.request_error_clear()
        for side in SIDES:
            self.states[side] = replace(self.states[side], errors=MotorErrorFlags.NONE)
        self.reset_fault()

    def reset_fault(self) -> None:
        """Forget the fault; silence is measured afresh from the next tick."""
        super().reset_fault()
        self._started_t = None
        for side in SIDES:
            self.states[side] = replace(self.states[side], last_reply_t=None)

    def _close(self) -> None:
        if self.close_bus:
            self.bus.shutdown()


#: A request is an immutable value, and a driver holding a speed (or zero) sends the same one every tick: each is
#: built (and checked) once per distinct value.
_request = lru_cache(maxsize=64)(RmdRequest)


def _updated(state: MotorState, reply: AnyReply, sign: int, now: float) -> MotorState:
    """``state`` with the reply's time and what ``reply`` (of either protocol version) says; speeds and currents
    signed by ``sign``. One copy of the state per reply: the driver reads about 200 replies a second, so the copy is
    built field by field (`dataclasses.replace` costs twice as much)."""
    s = state
    if isinstance(reply, Status2Reply):
        return MotorState(s.side, s.motor_id, sign * reply.speed_radps, reply.encoder, s.angle_rad,
                          sign * reply.current_a, reply.temperature_c, s.voltage_v, s.errors, now, now)
    if isinstance(reply, V4Status2Reply):
        return MotorState(s.side, s.motor_id, sign * reply.speed_radps, s.encoder, sign * reply.angle_rad,
                          sign * reply.current_a, reply.temperature_c, s.voltage_v, s.errors, now, now)
    if isinstance(reply, Status1Reply | V4Status1Reply):
        return MotorState(s.side, s.motor_id, s.speed_radps, s.encoder, s.angle_rad, s.current_a, reply.temperature_c,
                          reply.voltage_v, reply.errors, now, s.last_feedback_t)
    return MotorState(s.side, s.motor_id, s.speed_radps, s.encoder, s.angle_rad, s.current_a, s.temperature_c,
                      s.voltage_v, s.errors, now, s.last_feedback_t)
