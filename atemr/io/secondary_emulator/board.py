"""The secondary core's firmware logic (thesis 3.6.3, docs/can.md#the-secondary-core), as a scheduler component.

One `SecondaryCore` is the ESP32 board: its lifecycle machine (transitions), the power button, the
0x157 heartbeat check, the 0x150 power handshake, soft emergency (braking both motors over CAN), the IR
cliff sensors on 0x151/0x152, the WiFi credentials on 0x154/0x155, the IP request on 0x156, buzzer and
LED events and the 128×64 display. It owns no thread: `tick(now)` drains its own python-can bus with
``recv(timeout=0)`` and does everything due at ``now``, so a simulation is deterministic; standalone, the
same object runs on a wall clock (`secondary_core.cli`).

Board states and their screens::

    power_on_sequence --boot_s--> ready --hold 1 s--> power_on --0x150 byte 0 = 1--> ops <--short--> config
    ops/config/power_on --hold 5 s (0x150 byte 1 = 1)--> power_off --byte 0 = 2, +5 s--> shutdown
    config --120 s--> ops;  byte 0 = 2 from the primary (dashboard shutdown) also enters power_off

Soft emergency (MOTOR_STOP to motors 1 and 2, repeated every ``brake_period_s``) holds from power-up
until the primary reports running, whenever no valid heartbeat exchange happened for
``heartbeat_timeout_s`` (2 s), and after the primary acknowledged power-off. A motor follows any speed
command it gets after a MOTOR_STOP (that is the RMD protocol), so the brake is also a latch that does not
rely on the primary behaving: while the emergency holds, every frame seen on the bus that asks a braked
motor to move (a nonzero speed, MOTOR_RUN) is answered by a MOTOR_STOP to that motor in the same tick, and
the first one of an emergency is reported as an event.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import can
from transitions import Machine

from atemr.clock import due
from atemr.domain.status import PowerRequest, PowerState
from atemr.errors import ProtocolError
from atemr.io.can import (
    PASSWORD,
    SSID,
    Heartbeat,
    IpAddress,
    IpRequest,
    IrFront,
    IrRear,
    Message,
    Power,
    PrimaryStatus,
    encode_text,
)
from atemr.io.can.endpoint import EndpointCounters, PolledCanEndpoint
from atemr.io.motors.rmd_codec import RMD_BASE_ID, RmdCommand, RmdRequest
from atemr.io.network import credential_problems
from atemr.io.secondary_emulator.button import Button, ButtonEvent, Gesture
from atemr.io.secondary_emulator.display import Screen, render_png, render_text
from atemr.io.secondary_emulator.events import EventLog
from atemr.io.secondary_emulator.screens import SCREEN_NAMES, BoardView, build_screen
from atemr.io.secondary_link import ir_m_to_cm
from atemr.msgs import CliffReadings

log = logging.getLogger("secondary_core.board")  # the name it logged under before it moved here

STATES = list(SCREEN_NAMES)

_TRANSITIONS: list[dict[str, Any]] = [
    {"trigger": "booted", "source": "power_on_sequence", "dest": "ready"},
    {"trigger": "power_on_primary", "source": "ready", "dest": "power_on"},
    {"trigger": "primary_running", "source": ["ready", "power_on"], "dest": "ops"},
    {"trigger": "toggle", "source": "ops", "dest": "config"},
    {"trigger": "toggle", "source": "config", "dest": "ops"},
    {"trigger": "portal_timeout", "source": "config", "dest": "ops"},
    {"trigger": "request_power_off", "source": ["power_on", "ops", "config"], "dest": "power_off"},
    {"trigger": "primary_off", "source": ["ready", "power_on", "ops", "config"], "dest": "power_off"},
    {"trigger": "shutdown_due", "source": "power_off", "dest": "shutdown"},
    {"trigger": "power_cycle", "source": "*", "dest": "power_on_sequence"},
]


def mermaid_diagram() -> str:
    """The board's state machine as Mermaid ``stateDiagram-v2`` text (renders on GitHub; no Graphviz needed)."""
    lines = ["stateDiagram-v2", "    [*] --> power_on_sequence"]
    for t in _TRANSITIONS:
        sources = STATES if t["source"] == "*" else t["source"]
        for source in [sources] if isinstance(sources, str) else sources:
            if source != t["dest"]:
                lines.append(f"    {source} --> {t['dest']}: {t['trigger']}")
    return "\n".join(lines)


@dataclass(frozen=True)
class BoardConfig:
    """Timings and texts of the board; the defaults are the thesis' values (boot shortened from ~10 s)."""

    robot_name: str = "KAY"
    boot_s: float = 3.0
    primary_boot_estimate_s: float = 30.0
    heartbeat_timeout_s: float = 2.0
    portal_active_s: float = 120.0
    portal_close_delay_s: float = 3.0
    shutdown_delay_s: float = 5.0
    ir_period_s: float = 0.05
    brake_period_s: float = 0.1
    power_off_resend_s: float = 0.5
    motor_ids: tuple[int, ...] = (1, 2)
    ap_ssid: str = "ATEMR-Connect"
    ap_password: str = "123456789"
    portal_url: str = "http://192.168.4.1"

    def __post_init__(self) -> None:
        for name in ("boot_s", "primary_boot_estimate_s", "heartbeat_timeout_s", "portal_active_s",
                     "portal_close_delay_s", "shutdown_delay_s", "ir_period_s", "brake_period_s",
                     "power_off_resend_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ProtocolError(f"secondary core: {name} must be a finite number of seconds >= 0, got {value!r}")


CliffSource = Callable[[], CliffReadings | None]


def _next(t: float, period_s: float, now: float) -> float:
    """The next time of a periodic action: on its own grid, never in a burst after a pause."""
    t += period_s
    return t if t > now else now + period_s


@dataclass
class _Counters(EndpointCounters):
    heartbeats_answered: int = 0
    brake_frames: int = 0
    #: Frames asking a braked motor to move seen during a soft emergency (each braked again at once).
    overridden_brakes: int = 0
    wifi_sent: int = 0
    ip_requests: int = 0


@dataclass
class _Timers:
    entered_at: float = 0.0
    boot_started: float = 0.0
    portal_until: float | None = None
    ack_at: float | None = None
    last_heartbeat: float | None = None
    heartbeat_window_start: float | None = None
    next_ir: float = 0.0
    next_brake: float = 0.0
    next_power_off_request: float = 0.0
    pending_ops: list[str] = field(default_factory=list)


class SecondaryCore(PolledCanEndpoint):
    """The emulated secondary core on ``bus``; tick it at 50 Hz (every 20 ms) with the robot's clock.

    ``cliff_source`` gives the latest `CliffReadings` (metres) or None; without one the IR frames are not
    sent. Button input goes through `button` (any thread); the captive portal calls `send_wifi` and
    `request_ip` (any thread); both take effect at the next tick. The bus belongs to the caller.
    """

    # Set by transitions' Machine on the model.
    state: str
    trigger: Callable[..., bool]
    counters: _Counters
    logger = log

    def __init__(
        self,
        bus: can.BusABC,
        *,
        cliff_source: CliffSource | None = None,
        config: BoardConfig | None = None,
        name: str = "secondary_core",
    ) -> None:
        super().__init__(bus, name=name, counters=_Counters())
        self.config = config or BoardConfig()
        self.cliff_source = cliff_source
        self.button = Button()
        self.events = EventLog()
        self.status: PrimaryStatus | None = None
        self.primary_power = PowerState.INITIALISING
        self.robot_ip: str | None = None
        self.soft_emergency = True
        self.emergency_reason: str | None = "starting up"
        self.now = 0.0
        self._t = _Timers()
        self._started = False
        #: A drive command was braked again during the current soft emergency (reported once per emergency).
        self._overridden = False
        self._rebrake: set[int] = set()
        self._lock = threading.Lock()
        self._commands: deque[tuple[str, tuple[str, ...]]] = deque()
        self.machine = Machine(
            model=self, states=STATES, transitions=_TRANSITIONS, initial="power_on_sequence",
            auto_transitions=False, ignore_invalid_triggers=True, after_state_change="_after_state_change",
        )

    # -- inputs from other threads ------------------------------------------------------------
    def send_wifi(self, ssid: str, password: str) -> None:
        """Queue the WiFi credentials for the primary (0x154 then 0x155); `ProtocolError` if they are invalid.

        The captive portal checks the same rules first and shows them on the page; this check is the last
        line, so nothing invalid is ever put on the bus.
        """
        problems = credential_problems(ssid, password)
        if problems:
            raise ProtocolError("WiFi credentials refused: " + "; ".join(problems))
        with self._lock:
            self._commands.append(("wifi", (ssid, password)))

    def request_ip(self) -> None:
        """Queue an IP request to the primary (empty 0x156); the answer lands in `robot_ip`."""
        with self._lock:
            self._commands.append(("ip", ()))

    def reboot(self) -> None:
        """Flip the board's power switch off and on: back to the power-on sequence, everything forgotten."""
        with self._lock:
            self._commands.append(("reboot", ()))

    # -- what the board shows -------------------------------------------------------------------
    @property
    def screen_name(self) -> str:
        """The thesis' name of the current screen (``"OPS"``, ``"BOOT/READY"``, ...)."""
        return SCREEN_NAMES[self.state]

    @property
    def portal_active(self) -> bool:
        """Whether the captive portal is served (120 s after entering CONFIG, 3 s more after leaving it)."""
        return self._t.portal_until is not None and self.now < self._t.portal_until

    @property
    def portal_left_s(self) -> float | None:
        if not self.portal_active or self._t.portal_until is None:
            return None
        return self._t.portal_until - self.now

    @property
    def heartbeat_ok(self) -> bool:
        """A valid 0x157 exchange within the last ``heartbeat_timeout_s`` (counted from the primary's power-on)."""
        since = self._heartbeat_since()
        return since is not None and self.now - since < self.config.heartbeat_timeout_s

    @property
    def power_off_acknowledged(self) -> bool:
        return self._t.ack_at is not None

    def view(self) -> BoardView:
        """A snapshot of what the screens show."""
        c = self.config
        shutdown_in = 0.0
        if self._t.ack_at is not None:
            shutdown_in = self._t.ack_at + c.shutdown_delay_s - self.now
        return BoardView(
            state=self.state, robot_name=c.robot_name, in_state_s=self.now - self._t.entered_at, boot_s=c.boot_s,
            primary_boot_estimate_s=c.primary_boot_estimate_s, status=self.status, robot_ip=self.robot_ip,
            portal_left_s=self.portal_left_s, ap_ssid=c.ap_ssid, ap_password=c.ap_password, portal_url=c.portal_url,
            heartbeat_ok=self.heartbeat_ok, emergency_reason=self.emergency_reason if self.soft_emergency else None,
            power_off_acknowledged=self.power_off_acknowledged, shutdown_in_s=shutdown_in,
        )

    def screen(self) -> Screen:
        """What the display shows now."""
        return build_screen(self.view())

    def screen_text(self) -> str:
        return render_text(self.screen())

    def screen_png(self, *, scale: int = 1, color: bool = False) -> bytes:
        return render_png(self.screen(), scale=scale, color=color)

    def snapshot(self) -> dict[str, Any]:
        """Plain data for the dashboard's simulation panel and the CLI."""
        return {
            "state": self.state, "screen": self.screen_name, "screen_text": self.screen_text(),
            "soft_emergency": self.soft_emergency, "emergency_reason": self.emergency_reason,
            "heartbeat_ok": self.heartbeat_ok, "primary_power": self.primary_power.name,
            "portal_active": self.portal_active, "portal_left_s": self.portal_left_s, "robot_ip": self.robot_ip,
            "status": self.status.fields() if self.status else None,
            "button_pressed": self.button.is_pressed,
            "events": [str(e) for e in self.events.recent(20)],
        }

    # -- scheduler component ------------------------------------------------------------------
    def start(self) -> None:
        """Nothing to open (the bus is the caller's); the power-up time is the first tick's."""

    def shutdown(self) -> None:
        """Stop serving commands; the bus is closed by whoever opened it."""
        with self._lock:
            self._commands.clear()

    def tick(self, now: float) -> None:
        self.now = now
        if not self._started:
            self._power_up(now)
        self._receive(now)
        self._send_rebrakes()
        self._run_commands(now)
        for event in self.button.poll(now):
            self._on_button(event)
        self._run_timers(now)
        self._update_emergency(now)
        self._publish_ir(now)

    # -- internals ----------------------------------------------------------------------------
    def _power_up(self, now: float, *, announce: bool = True) -> None:
        self._started = True
        self._t = _Timers(entered_at=now, boot_started=now, next_ir=now, next_brake=now)
        self.status = None
        self.primary_power = PowerState.INITIALISING
        self.robot_ip = None
        self.soft_emergency = False
        if announce:
            self.events.emit(now, "screen", "POWER-ON SEQUENCE")

    def _after_state_change(self) -> None:
        now = self.now
        self._t.entered_at = now
        self.events.emit(now, "screen", self.screen_name)
        handler = getattr(self, f"_enter_{self.state}", None)
        if handler is not None:
            handler(now)

    def _enter_power_on(self, now: float) -> None:
        self.events.emit(now, "buzzer", "power-on alert")
        self.events.emit(now, "led", "green, fixed")

    def _enter_ops(self, now: float) -> None:
        if self._t.portal_until is not None and self._t.portal_until > now + self.config.portal_close_delay_s:
            self._t.portal_until = now + self.config.portal_close_delay_s
            self.events.emit(now, "portal", f"closing in {self.config.portal_close_delay_s:g} s")

    def _enter_config(self, now: float) -> None:
        self._t.portal_until = now + self.config.portal_active_s
        self.events.emit(now, "portal", f"captive portal active for {self.config.portal_active_s:g} s")
        self._send_ip_request(now)

    def _enter_power_off(self, now: float) -> None:
        self._t.portal_until = None
        if self._t.ack_at is None:
            self.events.emit(now, "buzzer", "power-off alert")
            self.events.emit(now, "led", "blinking: waiting for the primary core")
            self._t.next_power_off_request = now

    def _enter_shutdown(self, now: float) -> None:
        self.events.emit(now, "led", "off")
        self.events.emit(now, "buzzer", "shutdown tone")

    def _enter_power_on_sequence(self, now: float) -> None:
        self._power_up(now, announce=False)  # power cycle: the screen event was just emitted

    def _on_foreign_frame(self, frame: can.Message, now: float) -> None:
        if self.soft_emergency:
            self._hold_brake(frame, now)

    def _hold_brake(self, frame: can.Message, now: float) -> None:
        """Brake a motor again at once when a frame on its ID would set it driving (see the module docstring).

        A speed frame counts only when it asks for (or, as a reply, reports) motion: the primary holds its
        motors at zero speed with speed commands while it boots, and that is no reason to act. A motor's reply
        shares its request's ID and command byte, so bytes 4–5 are read, which are the low half of a request's
        speed (0.01 dps, nonzero for any speed below 655 dps) and a reply's speed (1 dps). MOTOR_RUN always
        counts; the motor's answer to MOTOR_STOP (0x81) never does.
        """
        motor_id = frame.arbitration_id - RMD_BASE_ID
        if motor_id not in self.config.motor_ids or len(frame.data) < 6:
            return
        command = frame.data[0]
        moving = command == RmdCommand.SPEED_CONTROL and (frame.data[4] or frame.data[5])
        if not (moving or command == RmdCommand.MOTOR_RUN):
            return
        self.counters.overridden_brakes += 1
        if not self._overridden:
            self._overridden = True
            self.events.emit(now, "emergency", f"motor {motor_id} commanded during the soft emergency: braked again")
        self._rebrake.add(motor_id)

    def _send_rebrakes(self) -> None:
        """One MOTOR_STOP per motor per tick, however many drive frames the tick read."""
        self._brake(sorted(self._rebrake))
        self._rebrake.clear()

    def _brake(self, motor_ids: Iterable[int]) -> None:
        """MOTOR_STOP to each of ``motor_ids``, counted."""
        for motor_id in motor_ids:
            if self._send(RmdRequest(motor_id, RmdCommand.MOTOR_STOP).encode()):
                self.counters.brake_frames += 1

    def _on_message(self, msg: Message, now: float) -> None:
        if isinstance(msg, Heartbeat):
            # Answered in every state: the primary's StartUp checks the heartbeat before it reports running.
            if msg.from_primary:
                if self._send(Heartbeat(from_primary=False).encode()):
                    self.counters.heartbeats_answered += 1
                self._t.last_heartbeat = now
        elif isinstance(msg, Power):
            self._on_power(msg.state, now)
        elif isinstance(msg, PrimaryStatus):
            self.status = msg
        elif isinstance(msg, IpAddress):
            ip = str(msg.address)
            if ip != self.robot_ip:
                self.events.emit(now, "wifi", f"robot IP address {ip}")
            self.robot_ip = ip

    def _on_power(self, state: PowerState, now: float) -> None:
        previous, self.primary_power = self.primary_power, state
        if state is PowerState.RUNNING:
            if previous is not PowerState.RUNNING:
                # The heartbeat check starts the moment the primary says it is powered on (thesis 3.6.3).
                self._t.heartbeat_window_start = now
            if self.state == "power_on_sequence":
                if "primary_running" not in self._t.pending_ops:
                    self._t.pending_ops.append("primary_running")
            elif self.state in ("ready", "power_on"):  # repeated 0x150 frames in OPS/CONFIG change nothing
                self.trigger("primary_running")
        elif state is PowerState.POWER_OFF_ACK and previous is not PowerState.POWER_OFF_ACK:
            self._t.ack_at = now
            self.events.emit(now, "buzzer", "power-off acknowledged")
            if self.state != "power_off":
                self.trigger("primary_off")

    def _run_commands(self, now: float) -> None:
        while True:
            with self._lock:
                if not self._commands:
                    return
                kind, args = self._commands.popleft()
            if kind == "wifi":
                self._send_wifi(now, args[0], args[1])
            elif kind == "ip":
                self._send_ip_request(now)
            elif kind == "reboot":
                self.trigger("power_cycle")

    def _send_wifi(self, now: float, ssid: str, password: str) -> None:
        frames = encode_text(SSID, ssid) + encode_text(PASSWORD, password)
        sent = sum(self._send(f) for f in frames)
        self.counters.wifi_sent += 1
        self.events.emit(now, "wifi", f"credentials for '{ssid}' sent to the primary ({sent}/{len(frames)} frames)")

    def _send_ip_request(self, now: float) -> None:
        if self._send(IpRequest().encode()):
            self.counters.ip_requests += 1

    def _on_button(self, event: ButtonEvent) -> None:
        t = event.t
        if event.gesture is None:
            self.events.emit(t, "buzzer", f"beep ({event.seconds_held} s held)")
            self.events.emit(t, "led", "flash")
            return
        self.events.emit(t, "button", f"{event.gesture.value} ({event.held_s:.2f} s) in {self.screen_name}")
        if event.gesture is Gesture.SHORT:
            self.trigger("toggle")
        elif event.gesture is Gesture.HOLD_1S:
            self.trigger("power_on_primary")
        elif event.gesture is Gesture.HOLD_5S and not self.trigger("request_power_off"):
            self.trigger("power_on_primary")  # in READY any long hold powers the primary on

    def _run_timers(self, now: float) -> None:
        c = self.config
        if self.state == "power_on_sequence" and now - self._t.boot_started >= c.boot_s:
            self.trigger("booted")
            for pending in self._t.pending_ops:
                self.trigger(pending)
            self._t.pending_ops.clear()
        if self.state == "config" and not self.portal_active:
            self.events.emit(now, "portal", "captive portal timed out")
            self.trigger("portal_timeout")
        if self._t.portal_until is not None and now >= self._t.portal_until:
            self._t.portal_until = None
            self.events.emit(now, "portal", "captive portal stopped")
        if self.state == "power_off":
            if self._t.ack_at is None and now >= self._t.next_power_off_request:
                # Repeated until acknowledged, so one lost frame cannot leave the robot half shut down.
                self._send(Power(self.primary_power, PowerRequest.POWER_OFF).encode())
                self._t.next_power_off_request = now + c.power_off_resend_s
            elif self._t.ack_at is not None and now - self._t.ack_at >= c.shutdown_delay_s:
                self.trigger("shutdown_due")

    def _heartbeat_since(self) -> float | None:
        candidates = [t for t in (self._t.last_heartbeat, self._t.heartbeat_window_start) if t is not None]
        return max(candidates) if candidates else None

    def _emergency_reason(self) -> str | None:
        if self.state == "power_on_sequence":
            return "starting up"
        if self.primary_power is PowerState.POWER_OFF_ACK:
            return "primary off"
        if self.primary_power is not PowerState.RUNNING:
            return "primary not running"
        if not self.heartbeat_ok:
            return "heartbeat lost"
        return None

    def _update_emergency(self, now: float) -> None:
        reason = self._emergency_reason()
        if (reason is not None) != self.soft_emergency or reason != self.emergency_reason:
            if reason is not None and not self.soft_emergency:
                self.events.emit(now, "emergency", f"soft emergency ON: {reason}")
                if reason == "heartbeat lost":
                    self.events.emit(now, "buzzer", "alarm: heartbeat lost")
                self._t.next_brake = now
            elif reason is None:
                self.events.emit(now, "emergency", f"soft emergency OFF (was: {self.emergency_reason})")
                self._overridden = False
            self.soft_emergency = reason is not None
            self.emergency_reason = reason
        if self.soft_emergency and due(now, self._t.next_brake):
            self._brake(self.config.motor_ids)
            self._t.next_brake = _next(self._t.next_brake, self.config.brake_period_s, now)

    def _publish_ir(self, now: float) -> None:
        if self.cliff_source is None or self.state in ("power_on_sequence", "shutdown"):
            return
        if not due(now, self._t.next_ir):
            return
        self._t.next_ir = _next(self._t.next_ir, self.config.ir_period_s, now)
        readings = self.cliff_source()
        if readings is None:
            return
        self._send(IrFront(ir_m_to_cm(readings.front_left_m), ir_m_to_cm(readings.front_right_m)).encode())
        self._send(IrRear(ir_m_to_cm(readings.rear_m)).encode())
