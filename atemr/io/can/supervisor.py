"""The receive side of the bus, watched: frames to listeners, and every way it can fail reported.

`BusSupervisor` is a scheduler component owning one Bus instance and a list of listeners (callables
taking a ``can.Message``). Two modes:

* polled (default, the simulation): `tick` drains ``recv(timeout=0)`` and calls the listeners, so a
  run stays deterministic;
* ``threaded=True`` (the real robot): a python-can `Notifier` thread delivers frames as they arrive,
  and `tick` checks that thread is alive.

Several consumers share the one receive side through `inbox`: each gets an `Inbox`, a ``BusABC`` whose
``recv`` returns the frames the supervisor delivered to it and whose ``send`` goes to the supervised
bus, so code written against a bus (the motor driver, the secondary-core link) needs no change. Polled,
an empty inbox first asks the supervisor to drain the bus, so a consumer reads exactly what it would
have read from a bus of its own, whatever the tick order.

Either way a listener that raises is caught (python-can's Notifier would otherwise stop delivering)
and the supervisor notices a dead receive side, an error from ``recv``, a listener that raised, bus-off
(``bus.state`` ERROR, or a SocketCAN error frame with `CAN_ERR_BUSOFF`: error frames are never traffic
and never reach the listeners), failed sends made through `send`, and (optionally) total silence for
``max_silence_s``. Each is latched as a `BusError`: `check` raises it, ``on_fault`` hears of it once,
from `tick`'s thread — "never silence". `recover` clears it once the cause is gone: frames arrive and no
error has been seen for ``settle_s`` (so a listener failing on a frame sent every 0.5 s holds the fault
instead of clearing and failing again between two such frames).

The fault is not critical (``critical=False``): by the time it is reported the motors are stopped (the
robot's safety stop, the RMD's own communication timeout, the secondary core's heartbeat watchdog), and
a bus-off controller comes back by itself (socketcan ``restart-ms``) or once a connector is reseated.
Powering the primary off would leave a telepresence robot unreachable for a fault that usually clears;
an operator expects it to stand still in Error, say why, and drive again when the bus carries frames.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable, Iterable
from typing import Self

import can

from atemr.errors import BusError, HardwareError

log = logging.getLogger(__name__)

FrameListener = Callable[[can.Message], object]
#: Frames handled per tick at most in polled mode, so a flooded bus cannot stall the scheduler; more than one
#: endpoint's `atemr.io.can.endpoint.MAX_FRAMES_PER_TICK` because the supervisor reads for every consumer.
SUPERVISED_FRAMES_PER_TICK = 1000
#: The controller's bus-off flag in a SocketCAN error frame's ID (Linux include/uapi/linux/can/error.h,
#: CAN_ERR_BUSOFF). python-can's socketcan bus reports no ``state``: bus-off reaches it as such a frame.
CAN_ERR_BUSOFF = 0x40
#: Frames an `Inbox` holds for a consumer that does not read; older ones are dropped (and counted).
INBOX_FRAMES = 1000


class SafeListener(can.Listener):
    """Calls ``listener`` for each frame and catches what it raises, so the Notifier keeps running."""

    def __init__(self, listener: FrameListener, on_error: Callable[[FrameListener, Exception], None]) -> None:
        self.listener = listener
        self.report = on_error

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_error_frame:
            return  # the controller's report, not traffic: the supervisor's probe reads it
        try:
            self.listener(msg)
        except Exception as exc:
            self.report(self.listener, exc)


class _ReceiveProbe(can.Listener):
    """Counts frames, failed listeners and ``recv`` errors, from whichever thread receives (under a lock)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.frames = 0
        self.listener_errors = 0
        self.receive_errors = 0
        #: Error frames with the bus-off flag (SocketCAN); error frames are not counted as traffic.
        self.bus_off_frames = 0
        self.error: Exception | None = None

    def on_message_received(self, msg: can.Message) -> None:
        with self.lock:
            self.count(msg)

    def count(self, msg: can.Message) -> None:
        """Count ``msg`` (the caller holds the lock): a data frame is traffic, an error frame may say bus-off."""
        if msg.is_error_frame:
            if msg.arbitration_id & CAN_ERR_BUSOFF:
                self.bus_off_frames += 1
        else:
            self.frames += 1

    def on_error(self, exc: Exception) -> None:
        with self.lock:
            self.receive_errors += 1
            if self.error is None:
                self.error = exc

    def counts(self) -> tuple[int, int, int]:
        """Frames, listener errors, receive errors so far."""
        with self.lock:
            return self.frames, self.listener_errors, self.receive_errors


class Inbox(can.BusABC):
    """One consumer's share of a supervised bus: ``recv`` returns what the supervisor delivered to it,
    ``send`` goes straight to the supervised bus (a failed send is the sender's to handle).

    `shutdown` closes only the inbox; the bus belongs to the supervisor.
    """

    def __init__(self, supervisor: BusSupervisor, consumer: str, *, maxlen: int = INBOX_FRAMES) -> None:
        super().__init__(channel=f"{supervisor.name}/{consumer}")
        self.supervisor = supervisor
        self.consumer = consumer
        self.dropped = 0
        self._frames: deque[can.Message] = deque()
        self._maxlen = maxlen
        self._ready = threading.Condition()

    def deliver(self, msg: can.Message) -> None:
        """Queue ``msg`` for the consumer (the supervisor's listener; any thread)."""
        with self._ready:
            if len(self._frames) >= self._maxlen:
                self._frames.popleft()
                self.dropped += 1
            self._frames.append(msg)
            self._ready.notify()

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        # A deque's popleft is atomic: a frame already there needs no lock (a polled robot reads its inboxes a few
        # hundred times a simulated second); only waiting for one does.
        frames = self._frames
        if not frames and not self.supervisor.threaded:
            self.supervisor.poll()  # polled: drain the bus now, as a bus of the consumer's own would be read
        elif not frames and timeout != 0:
            with self._ready:
                if not frames:
                    self._ready.wait(timeout)
        try:
            return frames.popleft(), False
        except IndexError:
            return None, False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.supervisor.bus.send(msg, timeout)

    @property
    def state(self) -> can.BusState:
        return self.supervisor.bus.state

    @state.setter
    def state(self, new_state: can.BusState) -> None:
        raise NotImplementedError("an inbox does not change the state of the bus it shares")


class BusSupervisor:
    """Receives from ``bus`` for ``listeners`` and reports what goes wrong; closes ``bus`` on `shutdown`
    when ``close_bus``."""

    def __init__(self, bus: can.BusABC, listeners: Iterable[FrameListener] = (), *, threaded: bool = False,
                 max_silence_s: float | None = None, name: str = "can_bus",
                 on_fault: Callable[[HardwareError], None] | None = None, close_bus: bool = True,
                 settle_s: float = 1.0) -> None:
        self.bus = bus
        self.name = name
        self.threaded = threaded
        self.max_silence_s = max_silence_s
        self.on_fault = on_fault
        self.close_bus = close_bus
        self.settle_s = settle_s
        self.fault: BusError | None = None
        #: What the latched fault is about, without the component prefix (for health reports).
        self.problem: str | None = None
        self.frames = 0
        self.listener_errors = 0
        self.last_listener_error: str | None = None
        self.send_failures = 0
        self.restarts = 0
        self._listeners: list[FrameListener] = list(listeners)
        self._inboxes: list[Inbox] = []
        self._probe = _ReceiveProbe()
        self._bus_off_frames_seen = 0
        self._notifier: can.Notifier | None = None
        self._last_activity_t: float | None = None
        self._reported_listener_errors = 0
        self._errors_seen = (0, 0)
        self._now = 0.0
        self._last_error_t = 0.0
        self._frames_at_fault = 0
        self._closed = False

    def add_listener(self, listener: FrameListener) -> None:
        """Deliver frames to ``listener`` too."""
        self._listeners.append(listener)
        if self._notifier is not None:
            self._notifier.add_listener(SafeListener(listener, self._listener_failed))

    def inbox(self, consumer: str) -> Inbox:
        """A bus-like share of the received frames for ``consumer`` (closed by `shutdown`)."""
        inbox = Inbox(self, consumer)
        self._inboxes.append(inbox)
        self.add_listener(inbox.deliver)
        return inbox

    def start(self) -> None:
        """Start the Notifier thread in threaded mode (nothing to do when polled)."""
        if self.threaded and self._notifier is None and not self._closed:
            wrapped: list[can.Listener] = [SafeListener(lis, self._listener_failed) for lis in self._listeners]
            self._notifier = can.Notifier(self.bus, [self._probe, *wrapped], timeout=0.1)

    # -- scheduler component --------------------------------------------------------------------
    def tick(self, now: float) -> None:
        """Deliver pending frames (polled) and check the receive side, listeners, the bus state and silence."""
        if self._closed:
            return
        self._now = now
        if self._last_activity_t is None:
            self._last_activity_t = now
        if self.threaded:
            self._check_thread()
        else:
            self.poll()
        frames, listener_errors, receive_errors = self._probe.counts()
        if frames != self.frames:
            self.frames = frames
            self._last_activity_t = now
        if (listener_errors, receive_errors) != self._errors_seen:
            self._errors_seen = (listener_errors, receive_errors)
            self._last_error_t = now
        if listener_errors != self._reported_listener_errors:
            self._reported_listener_errors = listener_errors
            self._fail(f"listener failed: {self.last_listener_error}")
        if self._bus_off():
            self._last_error_t = now
            self._fail("bus-off (bus state ERROR)")
        with self._probe.lock:
            bus_off_frames = self._probe.bus_off_frames
        if bus_off_frames != self._bus_off_frames_seen:
            self._bus_off_frames_seen = bus_off_frames
            self._last_error_t = now
            self._fail("bus-off (the controller's error frame)")
        if self.max_silence_s is not None and now - self._last_activity_t > self.max_silence_s:
            self._fail(f"no frame received for {now - self._last_activity_t:.2f} s")

    def poll(self) -> None:
        """Polled mode: deliver what the bus holds now (up to `SUPERVISED_FRAMES_PER_TICK`); a failing ``recv``
        is a fault. `tick` calls it, and so does an empty `Inbox` being read."""
        if self._closed:
            return
        for _ in range(SUPERVISED_FRAMES_PER_TICK):
            try:
                msg = self.bus.recv(timeout=0)
            except (can.CanError, OSError) as exc:
                with self._probe.lock:
                    self._probe.receive_errors += 1
                self._fail(f"receive failed: {exc}")
                return
            if msg is None:
                return
            with self._probe.lock:
                self._probe.count(msg)
            if msg.is_error_frame:
                continue
            for listener in self._listeners:
                try:
                    listener(msg)
                except Exception as exc:
                    self._listener_failed(listener, exc)

    def _bus_off(self) -> bool:
        try:
            return self.bus.state is can.BusState.ERROR
        except (NotImplementedError, can.CanError):
            return False

    def _receiving(self) -> bool:
        """Threaded: the Notifier runs, every reader thread is alive and none has hit an error."""
        if self._notifier is None or self._notifier.stopped:
            return False
        with self._probe.lock:
            if self._probe.error is not None:
                return False
        threads = [r for r in getattr(self._notifier, "_readers", []) if isinstance(r, threading.Thread)]
        return all(t.is_alive() for t in threads)

    def _check_thread(self) -> None:
        if self._notifier is None:
            self._fail("receive side not started")
            return
        with self._probe.lock:
            error = self._probe.error
        if error is not None:
            self._fail(f"receive thread failed: {error}")
            if not self._notifier.stopped:
                self._notifier.stop(timeout=1.0)  # the thread would otherwise retry the failing recv
            return
        if not self._notifier.stopped and not self._receiving():
            self._fail("receive thread is dead")

    # -- sending --------------------------------------------------------------------------------
    def send(self, msg: can.Message) -> None:
        """Send ``msg``; a failure is counted, latched as a fault and raised as `BusError`."""
        try:
            self.bus.send(msg)
        except (can.CanError, OSError) as exc:
            self.send_failures += 1
            self._fail(f"send of 0x{msg.arbitration_id:03X} failed: {exc}")
            assert self.fault is not None
            raise self.fault from exc

    def report_send_failure(self, exc: Exception) -> None:
        """For components that send on their own bus: record a failed send as a bus fault."""
        self.send_failures += 1
        self._fail(f"send failed: {exc}")

    # -- health ---------------------------------------------------------------------------------
    def check(self) -> None:
        """Raise the latched fault, if any."""
        if self.fault is not None:
            raise self.fault

    @property
    def healthy(self) -> bool:
        return self.fault is None

    def recover(self) -> str | None:
        """Clear the latched fault if its cause is gone: None when nothing stays latched, else why not yet.

        Gone means the bus is not off, the receive side runs, frames arrived since the fault, and `tick` has
        seen no ``recv`` error, failing listener or bus-off for ``settle_s``. A dead or failed receive thread
        is restarted here, so frames can arrive again. Called while the agent waits in Error (a `HealthBoard`
        recovery).
        """
        if self.fault is None:
            return None
        if self._bus_off():
            return "bus still off (bus state ERROR)"
        if self.threaded and not self._receiving():
            self._restart()
            return "receive thread restarted, waiting for frames"
        if self._probe.counts()[0] == self._frames_at_fault:
            return "no frame received since the fault"
        quiet_s = self._now - self._last_error_t
        if quiet_s < self.settle_s:
            return f"last error {quiet_s:.2f} s ago, waiting for {self.settle_s:.2f} s without one"
        self.reset_fault()
        log.info("%s: fault cleared: frames arrive again", self.name)
        return None

    def reset_fault(self) -> None:
        """Forget the fault (`recover` does it once the bus is back)."""
        self.fault = None
        self.problem = None
        self._last_activity_t = None
        with self._probe.lock:
            self._probe.error = None
            self._reported_listener_errors = self._probe.listener_errors

    def _restart(self) -> None:
        """Replace a stopped or dead Notifier with a new one (threaded mode)."""
        if self._notifier is not None:
            self._notifier.stop(timeout=1.0)
            self._notifier = None
        with self._probe.lock:
            self._probe.error = None
        self.restarts += 1
        log.warning("%s: restarting the receive thread", self.name)
        self.start()

    def _listener_failed(self, listener: FrameListener, exc: Exception) -> None:
        # May run on the Notifier's thread: count and remember here, `tick` reports it as a fault.
        text = f"{getattr(listener, '__qualname__', listener)!s}: {exc!r}"
        with self._probe.lock:
            self._probe.listener_errors += 1
            self.listener_errors = self._probe.listener_errors
            self.last_listener_error = text
        log.error("%s: listener %s", self.name, text)

    def _fail(self, problem: str) -> None:
        if self.fault is not None:
            return
        self.fault = BusError(problem, component=self.name, critical=False)
        self.problem = problem
        self._frames_at_fault = self._probe.counts()[0]
        self._last_error_t = self._now
        log.error("%s", self.fault)
        if self.on_fault is not None:
            self.on_fault(self.fault)

    def shutdown(self) -> None:
        """Stop the receive thread, close the inboxes and (``close_bus``) the bus; idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._notifier is not None:
            self._notifier.stop()
        for inbox in self._inboxes:
            inbox.shutdown()
        if self.close_bus:
            self.bus.shutdown()

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()
