"""The receive side of the bus, watched: frames to listeners, and every way it can fail reported.

`BusSupervisor` is a scheduler component owning one Bus instance and a list of listeners (callables
taking a ``can.Message``). Two modes:

* polled (default, the simulation): `tick` drains ``recv(timeout=0)`` and calls the listeners, so a
  run stays deterministic;
* ``threaded=True`` (the real robot): a python-can `Notifier` thread delivers frames as they arrive,
  and `tick` checks that thread is alive.

Either way a listener that raises is caught and reported (python-can's Notifier would otherwise stop
delivering), and the supervisor notices a dead receive side, an error from ``recv``, bus-off
(``bus.state`` ERROR), failed sends made through `send`, and (optionally) total silence for
``max_silence_s``. Each is latched as a critical `BusError`: `check` raises it, ``on_fault`` hears
of it once — "never silence".
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterable
from typing import Self

import can

from atemr.errors import BusError, HardwareError

log = logging.getLogger(__name__)

FrameListener = Callable[[can.Message], object]
#: Frames handled per tick at most in polled mode, so a flooded bus cannot stall the scheduler.
MAX_FRAMES_PER_TICK = 1000


class SafeListener(can.Listener):
    """Calls ``listener`` for each frame and catches what it raises, so the Notifier keeps running."""

    def __init__(self, listener: FrameListener, on_error: Callable[[FrameListener, Exception], None]) -> None:
        self.listener = listener
        self.report = on_error

    def on_message_received(self, msg: can.Message) -> None:
        try:
            self.listener(msg)
        except Exception as exc:
            self.report(self.listener, exc)


class _ReceiveProbe(can.Listener):
    """Counts frames and records ``recv`` errors from the Notifier thread (read under a lock)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.frames = 0
        self.error: Exception | None = None

    def on_message_received(self, msg: can.Message) -> None:
        with self.lock:
            self.frames += 1

    def on_error(self, exc: Exception) -> None:
        with self.lock:
            if self.error is None:
                self.error = exc


class BusSupervisor:
    """Receives from ``bus`` for ``listeners`` and reports what goes wrong; closes ``bus`` on `shutdown`."""

    def __init__(self, bus: can.BusABC, listeners: Iterable[FrameListener] = (), *, threaded: bool = False,
                 max_silence_s: float | None = None, name: str = "can_bus",
                 on_fault: Callable[[HardwareError], None] | None = None, close_bus: bool = True) -> None:
        self.bus = bus
        self.name = name
        self.threaded = threaded
        self.max_silence_s = max_silence_s
        self.on_fault = on_fault
        self.close_bus = close_bus
        self.fault: BusError | None = None
        self.frames = 0
        self.listener_errors = 0
        self.last_listener_error: str | None = None
        self.send_failures = 0
        self._listeners: list[FrameListener] = list(listeners)
        self._probe = _ReceiveProbe()
        self._notifier: can.Notifier | None = None
        self._last_activity_t: float | None = None
        self._closed = False

    def add_listener(self, listener: FrameListener) -> None:
        """Deliver frames to ``listener`` too (before `start` in threaded mode)."""
        self._listeners.append(listener)
        if self._notifier is not None:
            self._notifier.add_listener(SafeListener(listener, self._listener_failed))

    def start(self) -> None:
        """Start the Notifier thread in threaded mode (nothing to do when polled)."""
        if self.threaded and self._notifier is None:
            wrapped: list[can.Listener] = [SafeListener(lis, self._listener_failed) for lis in self._listeners]
            self._notifier = can.Notifier(self.bus, [self._probe, *wrapped], timeout=0.1)

    # -- scheduler component --------------------------------------------------------------------
    def tick(self, now: float) -> None:
        """Deliver pending frames (polled) and check the receive side, the bus state and silence."""
        if self._closed:
            return
        if self._last_activity_t is None:
            self._last_activity_t = now
        if self.threaded:
            self._check_thread()
        else:
            self._poll()
        with self._probe.lock:
            frames = self._probe.frames
        if frames != self.frames:
            self.frames = frames
            self._last_activity_t = now
        try:
            state = self.bus.state
        except (NotImplementedError, can.CanError):
            state = can.BusState.ACTIVE
        if state is can.BusState.ERROR:
            self._fail("bus-off (bus state ERROR)")
        if self.max_silence_s is not None and now - self._last_activity_t > self.max_silence_s:
            self._fail(f"no frame received for {now - self._last_activity_t:.2f} s")

    def _poll(self) -> None:
        for _ in range(MAX_FRAMES_PER_TICK):
            try:
                msg = self.bus.recv(timeout=0)
            except (can.CanError, OSError) as exc:
                self._fail(f"receive failed: {exc}")
                return
            if msg is None:
                return
            with self._probe.lock:
                self._probe.frames += 1
            for listener in self._listeners:
                try:
                    listener(msg)
                except Exception as exc:
                    self._listener_failed(listener, exc)

    def _check_thread(self) -> None:
        if self._notifier is None:
            self._fail("receive side not started")
            return
        with self._probe.lock:
            error = self._probe.error
        if error is not None:
            self._fail(f"receive thread failed: {error}")
            self._notifier.stop(timeout=1.0)  # the thread would otherwise retry the failing recv
            return
        threads = [r for r in getattr(self._notifier, "_readers", []) if isinstance(r, threading.Thread)]
        if not self._notifier.stopped and not all(t.is_alive() for t in threads):
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

    def reset_fault(self) -> None:
        """Forget the fault once the bus is back (the agent's Error state decides when)."""
        self.fault = None
        self._last_activity_t = None
        with self._probe.lock:
            self._probe.error = None

    def _listener_failed(self, listener: FrameListener, exc: Exception) -> None:
        self.listener_errors += 1
        self.last_listener_error = f"{getattr(listener, '__qualname__', listener)!s}: {exc!r}"
        log.error("%s: listener %s", self.name, self.last_listener_error)

    def _fail(self, problem: str) -> None:
        if self.fault is not None:
            return
        self.fault = BusError(problem, component=self.name, critical=True)
        log.error("%s", self.fault)
        if self.on_fault is not None:
            self.on_fault(self.fault)

    def shutdown(self) -> None:
        """Stop the receive thread and close the bus; idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._notifier is not None:
            self._notifier.stop()
        if self.close_bus:
            self.bus.shutdown()

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()
