"""The primary core's side of its CAN link with the secondary core (docs/can.md, thesis 3.6).

`SecondaryLink` is a scheduler component that owns nothing but a python-can bus, polled with
``recv(timeout=0)`` in `SecondaryLink.tick`, so in simulation it is deterministic. Each tick it:

* sends the heartbeat 0x157 = 0x01 every 0.5 s and checks the 0x00 answers: no valid exchange for 2 s →
  `heartbeat_ok` turns False and ``on_heartbeat(False)`` fires, so the robot stops its motors;
* sends the status 0x153 (agent bits, hardware bits, state code set by the agent with `set_status`) at
  2 Hz and at once when it changes, and the power byte 0x150 byte 0 (`set_power_state`: initialising,
  running, power-off acknowledged) the same way;
* receives power-off requests (0x150 byte 1 = 1) → `power_off_requested`, ``on_power_off_request``;
* answers IP requests (empty 0x156) with the robot's address from the `NetworkBackend`;
* turns IR frames 0x151/0x152 (cm) into `CliffReadings` (m), see `latest_cliff`;
* reassembles WiFi credentials (0x154 SSID, 0x155 password) and applies them through the backend, off
  the loop when an ``executor`` is given (``nmcli`` can take 30 s), reporting each outcome as a
  `WifiResult`.
"""

from __future__ import annotations

import ipaddress
import logging
import math
import threading
from collections import deque
from collections.abc import Callable
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, TypeVar

import can

from atemr.clock import due
from atemr.config import Config
from atemr.domain.status import AgentBits, ComponentHealth, HardwareBits, PowerRequest, PowerState, StateCode
from atemr.errors import AtemrError, ProtocolError
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
    SegmentedReceiver,
    WifiPasswordSegment,
    WifiSsidSegment,
)
from atemr.io.can.endpoint import PolledCanEndpoint
from atemr.io.devices.base import DeviceInfo, Subscribers
from atemr.io.network import NetworkBackend, NmcliBackend, RecordingNetworkBackend, usable_ipv4
from atemr.msgs import CliffReadings

log = logging.getLogger(__name__)

#: Centimetres on 0x151/0x152 that mean "nothing within range" (the secondary core sends it for a sensor
#: that sees no floor); read back as ``inf`` metres, which the cliff check treats as a drop.
IR_OUT_OF_RANGE_CM = 999.0

T = TypeVar("T")


def ir_cm_to_m(distance_cm: float) -> float:
    """A distance from the wire (cm) in metres; the out-of-range marker becomes ``inf``."""
    if not math.isfinite(distance_cm) or distance_cm >= IR_OUT_OF_RANGE_CM:
        return math.inf
    return distance_cm / 100.0


def ir_m_to_cm(distance_m: float) -> float:
    """A cliff reading (m) as sent on the wire (cm); inf, NaN or negative → `IR_OUT_OF_RANGE_CM`."""
    if not math.isfinite(distance_m) or distance_m < 0:
        return IR_OUT_OF_RANGE_CM
    return min(distance_m * 100.0, IR_OUT_OF_RANGE_CM)


@dataclass(frozen=True)
class WifiResult:
    """What became of one set of WiFi credentials from the captive portal (for the dashboard)."""

    t: float
    ssid: str | None
    ok: bool
    error: str | None = None


class InlineExecutor(Executor):
    """Runs submitted work at once in the caller's thread: the simulation's choice, deterministic."""

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Future[T]:
        future: Future[T] = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:
            future.set_exception(exc)
        return future


class SecondaryLink(PolledCanEndpoint):
    """The primary's end of the inter-core link on ``bus``; tick it at 50 Hz.

    ``network`` applies WiFi credentials and tells the IP address. ``executor`` runs `NetworkBackend.connect`
    (default `InlineExecutor`; on the robot pass a one-thread ``ThreadPoolExecutor`` so joining a network
    never stalls the loop — results are collected on later ticks). The callbacks run inside `tick`.
    The bus belongs to the caller.
    """

    #: Ticked at 50 Hz (the heartbeat's 0.5 s period and the 2 Hz status need far less; IR frames come at 20 Hz).
    rate_hz: float | None = 50.0
    logger = log

    def __init__(
        self,
        bus: can.BusABC,
        network: NetworkBackend,
        *,
        name: str = "secondary_link",
        heartbeat_period_s: float = 0.5,
        heartbeat_timeout_s: float = 2.0,
        status_period_s: float = 0.5,
        credentials_pair_s: float = 2.0,
        executor: Executor | None = None,
        on_heartbeat: Callable[[bool], None] | None = None,
        on_power_off_request: Callable[[], None] | None = None,
        on_wifi_result: Callable[[WifiResult], None] | None = None,
    ) -> None:
        for what, value in (("heartbeat_period_s", heartbeat_period_s), ("heartbeat_timeout_s", heartbeat_timeout_s),
                            ("status_period_s", status_period_s), ("credentials_pair_s", credentials_pair_s)):
            if not (math.isfinite(value) and value > 0):
                raise ProtocolError(f"{name}: {what} must be a finite number of seconds > 0, got {value!r}")
        super().__init__(bus, name=name)
        self.network = network
        self.heartbeat_period_s = heartbeat_period_s
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.status_period_s = status_period_s
        self.credentials_pair_s = credentials_pair_s
        self.executor: Executor = executor or InlineExecutor()
        self.on_heartbeat = on_heartbeat
        self.on_power_off_request = on_power_off_request
        self.on_wifi_result = on_wifi_result

        self._lock = threading.Lock()
        self._status = PrimaryStatus()
        self._power = PowerState.INITIALISING
        self._sent_status: PrimaryStatus | None = None
        self._sent_power: PowerState | None = None
        self._next_status = 0.0
        self._next_power = 0.0
        self._next_ping: float | None = None
        self._first_tick: float | None = None
        self._last_ping: float | None = None
        self._last_exchange: float | None = None
        self._heartbeat_ok = False
        self.heartbeat_losses = 0
        self.power_off_requested = False
        self.now = 0.0

        self._front: tuple[float, float, float] | None = None  # t, left m, right m
        self._rear: tuple[float, float] | None = None  # t, rear m
        self._cliff: Subscribers[CliffReadings] = Subscribers(f"{name} IR")

        self._ssid_rx = SegmentedReceiver(SSID)
        self._password_rx = SegmentedReceiver(PASSWORD)
        self._ssid: tuple[float, str] | None = None
        self._wifi_frame_t: float | None = None
        self._applying: deque[tuple[str, Future[None]]] = deque()
        self.wifi_results: deque[WifiResult] = deque(maxlen=50)

    # -- the agent's side (any thread) --------------------------------------------------------
    def set_status(self, agent: AgentBits | int, hardware: HardwareBits | int, state: StateCode | int) -> None:
        """What 0x153 tells the secondary core; sent at once if it changed. Invalid values → `ProtocolError`."""
        status = PrimaryStatus(agent, hardware, state)  # type: ignore[arg-type]  # validated by the codec
        with self._lock:
            self._status = status

    def set_power_state(self, state: PowerState | int) -> None:
        """0x150 byte 0: INITIALISING at start-up, RUNNING once StartUp passed, POWER_OFF_ACK before stopping."""
        power = Power(state)  # type: ignore[arg-type]  # validated by the codec
        with self._lock:
            self._power = power.state
            if power.state is not PowerState.POWER_OFF_ACK:
                return
        self.power_off_requested = False

    def acknowledge_power_off(self) -> None:
        """Tell the secondary core the primary is shutting down (0x150 byte 0 = 2)."""
        self.set_power_state(PowerState.POWER_OFF_ACK)

    @property
    def status(self) -> PrimaryStatus:
        return self._status

    @property
    def power_state(self) -> PowerState:
        return self._power

    # -- what the agent reads -----------------------------------------------------------------
    @property
    def heartbeat_ok(self) -> bool:
        """A valid 0x157 exchange (our 0x01 answered with 0x00) within the last ``heartbeat_timeout_s``."""
        return self._heartbeat_ok

    @property
    def heartbeat_established(self) -> bool:
        """The secondary core has answered at least once (the StartUp check)."""
        return self._last_exchange is not None

    def latest_cliff(self) -> CliffReadings | None:
        """The latest cliff readings (metres; inf = no floor within range), stamped with the older of the two
        frames' arrival times, or None until both 0x151 and 0x152 have arrived."""
        front, rear = self._front, self._rear
        if front is None or rear is None:
            return None
        return CliffReadings(min(front[0], rear[0]), front[1], front[2], rear[1])

    # -- the device interface (`atemr.io.devices.base.Device`): the secondary core's readings are its IR
    # -- sensors; it is healthy while the heartbeat is answered
    @property
    def latest(self) -> CliffReadings | None:
        return self.latest_cliff()

    @property
    def count(self) -> int:
        return self._cliff.count

    def subscribe(self, callback: Callable[[CliffReadings], None]) -> None:
        """Call ``callback`` with every new pair of IR readings (inside `tick`)."""
        self._cliff.subscribe(callback)

    def health(self, now: float) -> ComponentHealth:
        """Healthy while the 0x157 heartbeat is answered."""
        if self._heartbeat_ok:
            return ComponentHealth(True)
        if self._last_exchange is None:
            return ComponentHealth(False, "no heartbeat answer from the secondary core yet")
        return ComponentHealth(False, f"no heartbeat answer for {now - self._last_exchange:.1f} s")

    def info(self) -> DeviceInfo:
        return DeviceInfo(kind="secondary", driver="esp32", port=str(getattr(self.bus, "channel_info", "")) or None,
                          model="ESP32 secondary core")

    # -- the bus counters, by the names the link had before they moved into `counters` -------
    @property
    def frames_in(self) -> int:
        return self.counters.frames_in

    @property
    def frames_out(self) -> int:
        return self.counters.frames_out

    @property
    def bad_frames(self) -> int:
        return self.counters.bad_frames

    @property
    def bus_errors(self) -> int:
        return self.counters.bus_errors

    @property
    def last_bad_frame(self) -> str | None:
        return self.counters.last_bad_frame

    def diagnostics(self) -> dict[str, Any]:
        """Plain data about the link for tests and tools: counters, heartbeat, power, the last WiFi join."""
        last = self.wifi_results[-1] if self.wifi_results else None
        c = self.counters
        return {
            "heartbeat_ok": self._heartbeat_ok, "heartbeat_established": self.heartbeat_established,
            "heartbeat_losses": self.heartbeat_losses, "power_off_requested": self.power_off_requested,
            "power_state": self._power.name, "frames_in": c.frames_in, "frames_out": c.frames_out,
            "bad_frames": c.bad_frames, "bus_errors": c.bus_errors, "last_bad_frame": c.last_bad_frame,
            "wifi": None if last is None else {"ssid": last.ssid, "ok": last.ok, "error": last.error, "t": last.t},
        }

    # -- scheduler component ------------------------------------------------------------------
    def start(self) -> None:
        """Nothing to open: the bus is the caller's. The first tick starts the heartbeat."""

    def shutdown(self) -> None:
        """Stop a WiFi join in progress from being waited for; the executor is shut down if it is not inline."""
        if not isinstance(self.executor, InlineExecutor):
            self.executor.shutdown(wait=False, cancel_futures=True)

    def tick(self, now: float) -> None:
        self.now = now
        if self._first_tick is None:
            self._first_tick = now
            self._next_ping = now
        self._receive(now)
        self._send_heartbeat(now)
        self._check_heartbeat(now)
        self._send_status(now)
        self._expire_wifi(now)
        self._collect_wifi(now)

    # -- internals ----------------------------------------------------------------------------
    def _publish_cliff(self) -> None:
        reading = self.latest_cliff()
        if reading is not None:
            self._cliff.publish(reading)

    def _send_heartbeat(self, now: float) -> None:
        assert self._next_ping is not None
        if due(now, self._next_ping):
            if self._send(Heartbeat(from_primary=True).encode()):
                self._last_ping = now
            self._next_ping += self.heartbeat_period_s
            if self._next_ping <= now:
                self._next_ping = now + self.heartbeat_period_s

    def _check_heartbeat(self, now: float) -> None:
        ok = self._last_exchange is not None and now - self._last_exchange < self.heartbeat_timeout_s
        if ok == self._heartbeat_ok:
            return
        self._heartbeat_ok = ok
        if ok:
            log.info("%s: heartbeat with the secondary core established", self.name)
        else:
            self.heartbeat_losses += 1
            log.warning("%s: heartbeat lost: no valid 0x157 exchange for %.1f s: motors must stop",
                        self.name, self.heartbeat_timeout_s)
        if self.on_heartbeat is not None:
            self.on_heartbeat(ok)

    def _send_status(self, now: float) -> None:
        with self._lock:
            status, power = self._status, self._power
        if status != self._sent_status or due(now, self._next_status):
            self._send(status.encode())  # a failed send is retried by the 2 Hz repeat, not every tick
            self._sent_status = status
            self._next_status = now + self.status_period_s
        if power != self._sent_power or due(now, self._next_power):
            self._send(Power(power, PowerRequest.NORMAL).encode())
            self._sent_power = power
            self._next_power = now + self.status_period_s

    def _on_bad_frame(self, frame: can.Message, now: float) -> None:
        if frame.arbitration_id == SSID.arbitration_id:
            self._ssid = None  # a broken SSID transfer must not pair with the next password

    def _on_message(self, msg: Message, now: float) -> None:
        if isinstance(msg, Heartbeat):
            if not msg.from_primary and self._last_ping is not None:
                self._last_exchange = now
        elif isinstance(msg, Power):
            requested = msg.request is PowerRequest.POWER_OFF and self._power is not PowerState.POWER_OFF_ACK
            if requested and not self.power_off_requested:
                self.power_off_requested = True
                log.info("%s: the secondary core requests power-off", self.name)
                if self.on_power_off_request is not None:
                    self.on_power_off_request()
        elif isinstance(msg, IpRequest):
            ip = self.network.ip_address()
            answer = ipaddress.IPv4Address(ip if ip is not None and usable_ipv4(ip) else "0.0.0.0")
            self._send(IpAddress(answer).encode())
        elif isinstance(msg, IrFront):
            self._front = (now, ir_cm_to_m(msg.left_cm), ir_cm_to_m(msg.right_cm))
            self._publish_cliff()
        elif isinstance(msg, IrRear):
            self._rear = (now, ir_cm_to_m(msg.distance_cm))
            self._publish_cliff()
        elif isinstance(msg, WifiSsidSegment):
            self._on_ssid_segment(msg, now)
        elif isinstance(msg, WifiPasswordSegment):
            self._on_password_segment(msg, now)

    def _expire_wifi(self, now: float) -> None:
        """Give up on a transfer whose last frame never came, and on an SSID no password followed, so the
        dashboard hears of the failure instead of waiting for ever."""
        waiting = self._ssid_rx.in_progress or self._password_rx.in_progress
        if waiting and self._wifi_frame_t is not None and now - self._wifi_frame_t > self._ssid_rx.max_gap_s:
            ssid = self._ssid[1] if self._ssid else None
            self._ssid_rx.reset()
            self._password_rx.reset()
            self._ssid = None
            self._refuse(now, ssid, "transfer incomplete: its last frame never arrived")
        elif self._ssid is not None and now - self._ssid[0] > self.credentials_pair_s:
            ssid = self._ssid[1]
            self._ssid = None
            self._refuse(now, ssid, "SSID received but no password followed")

    def _on_ssid_segment(self, seg: WifiSsidSegment, now: float) -> None:
        self._wifi_frame_t = now
        drops = self._ssid_rx.drops
        text = self._ssid_rx.feed(seg, now)
        if self._ssid_rx.drops != drops or seg.index == 0:
            self._ssid = None
        if self._ssid_rx.drops != drops:
            self._refuse(now, None, f"SSID transfer dropped: {self._ssid_rx.last_drop}")
        if text is not None:
            self._ssid = (now, text)

    def _on_password_segment(self, seg: WifiPasswordSegment, now: float) -> None:
        self._wifi_frame_t = now
        drops = self._password_rx.drops
        password = self._password_rx.feed(seg, now)
        ssid = self._ssid
        if self._password_rx.drops != drops:
            self._ssid = None
            self._refuse(now, ssid[1] if ssid else None,
                         f"password transfer dropped: {self._password_rx.last_drop}")
            return
        if password is None:
            return
        self._ssid = None
        if ssid is None or now - ssid[0] > self.credentials_pair_s:
            self._refuse(now, None, "password received without a complete SSID before it")
            return
        log.info("%s: applying WiFi credentials for '%s'", self.name, ssid[1])
        self._applying.append((ssid[1], self.executor.submit(self.network.connect, ssid[1], password)))
        self._collect_wifi(now)

    def _refuse(self, now: float, ssid: str | None, why: str) -> None:
        log.warning("%s: WiFi credentials refused, nothing applied: %s", self.name, why)
        self._report(WifiResult(now, ssid, ok=False, error=why))

    def _collect_wifi(self, now: float) -> None:
        while self._applying and self._applying[0][1].done():
            ssid, future = self._applying.popleft()
            try:
                future.result()
            except AtemrError as exc:
                self._report(WifiResult(now, ssid, ok=False, error=str(exc)))
            except Exception as exc:
                log.exception("%s: network backend failed unexpectedly", self.name)
                self._report(WifiResult(now, ssid, ok=False, error=f"{type(exc).__name__}: {exc}"))
            else:
                self._report(WifiResult(now, ssid, ok=True))

    def _report(self, result: WifiResult) -> None:
        self.wifi_results.append(result)
        if result.ok:
            log.info("%s: joined WiFi network '%s'", self.name, result.ssid)
        if self.on_wifi_result is not None:
            self.on_wifi_result(result)


def network_backend(config: Config) -> NetworkBackend:
    """The robot's network: NetworkManager on the real robot, the recording fake in simulation."""
    if config.simulation:
        return RecordingNetworkBackend()
    return NmcliBackend(ifname=config.secondary.wifi_interface)


def build_secondary_link(config: Config, bus: can.BusABC, **callbacks: Any) -> SecondaryLink:
    """The link as the robot wires it: on the real robot WiFi is joined in one worker thread, so nmcli
    never stalls the control loop; in simulation everything runs inline and deterministic.
    ``callbacks``: ``on_heartbeat``, ``on_power_off_request``, ``on_wifi_result``."""
    executor = None if config.simulation else ThreadPoolExecutor(max_workers=1, thread_name_prefix="wifi")
    return SecondaryLink(bus, network_backend(config), executor=executor, **callbacks)
