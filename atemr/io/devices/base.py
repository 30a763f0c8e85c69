"""One interface for every sensor device, whatever drives it: the simulator, a serial port, a camera.

The robot reads its lidar, IMU and camera only through `Device`: the newest reading (``latest``),
subscriptions, a health probe, ``start``/``shutdown`` (open and close) and reconnection. A device is a
scheduler component: readings reach subscribers inside ``tick`` on the scheduler's thread, so the skills
that consume them (localization, mapping, the motion pipeline) stay single-threaded whatever the driver
does underneath.

`ThreadedDevice` is the base of the real drivers. Its reader thread owns the port: it opens it, reads and
decodes, stamps each reading with the robot's clock as it arrives, and hands it over through a bounded
queue; when the port fails (the device was unplugged) it closes it, reports why, and opens it again every
`REOPEN_S` until the device is back. A missing device is never an exception in the control loop: it is an
unhealthy device whose health says what is wrong and what to do about it.

The CAN devices answer to the same interface: the motor pair (`atemr.io.motors.driver.RmdDriver`: both
motors' latest replies) and the secondary core (`atemr.io.secondary_link.SecondaryLink`: its IR readings,
healthy while the heartbeat is answered). Their ``emulated`` drivers are the emulators on the robot's bus.
"""

from __future__ import annotations

import errno
import logging
import math
import os
import queue
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar, runtime_checkable

from atemr.domain.status import ComponentHealth

log = logging.getLogger(__name__)

R = TypeVar("R")
R_co = TypeVar("R_co", covariant=True)

#: How long a reader waits before opening a port that failed again, in seconds.
REOPEN_S = 0.25
#: Readings a reader thread may hand over before the scheduler drains them; older ones are dropped (the
#: default of `ThreadedDevice`'s ``queue_size``).
QUEUE_SIZE = 64


def fresh(t: float | None, now: float, max_age_s: float, what: str) -> ComponentHealth:
    """Healthy when a reading from time ``t`` is at most ``max_age_s`` old at ``now``."""
    if t is None:
        return ComponentHealth(False, f"no {what} yet")
    age = now - t
    if not math.isfinite(age) or age > max_age_s:
        return ComponentHealth(False, f"{what} silent for {age:.1f} s")
    return ComponentHealth(True)


def serial_port_hint(name: str, port: str, error: BaseException, *, device: str, udev_name: str) -> str:
    """What to do when the serial ``port`` of ``device`` (as a sentence names it: "the WT901") failed to open
    with ``error``: join the dialout group, plug the device in (``port`` is missing, or a link to a device
    that is gone; ``udev_name`` is the stable name a udev rule can give it), or free it from another
    program. ``name`` is the component's, which the hint starts with."""
    code = getattr(error, "errno", None)
    if code in (errno.EACCES, errno.EPERM) or isinstance(error, PermissionError):
        return (f"{name}: no permission to open {port}: add the user to the dialout group "
                f"(sudo usermod -aG dialout $USER, then log in again) ({error})")
    if not os.path.exists(port):
        dangling = " (a link to a device that is gone)" if os.path.lexists(port) else ""
        return (f"{name}: {port} does not exist{dangling}: is {device} plugged in? "
                f"(ls /dev/ttyUSB*; a udev rule can name it {udev_name})")
    return f"{name}: cannot open {port} ({error}): is another program using it?"


@dataclass(frozen=True)
class DeviceInfo:
    """What a device says about itself, for ``atemr hw check`` and the dashboard."""

    kind: str
    driver: str
    port: str | None = None
    model: str | None = None
    firmware: str | None = None
    serial_number: str | None = None


@runtime_checkable
class Device(Protocol[R_co]):
    """A lidar, an IMU or a camera, as the robot sees it (see the module docstring)."""

    name: str
    #: How often the robot ticks it (None: something else delivers its readings, as the simulator does).
    rate_hz: float | None

    @property
    def latest(self) -> R_co | None:
        """The newest reading, or None before the first."""
        ...

    @property
    def count(self) -> int:
        """Readings delivered since the start."""
        ...

    def subscribe(self, callback: Callable[[R_co], None]) -> None:
        """Call ``callback(reading)`` for every new reading, on the scheduler's thread."""
        ...

    def health(self, now: float) -> ComponentHealth:
        """Healthy while fresh readings arrive; otherwise why not, and what to do."""
        ...

    def info(self) -> DeviceInfo:
        """Driver, port, and the model or firmware where the device reports it."""
        ...

    def tick(self, now: float) -> None:
        """Deliver the readings that arrived since the last tick."""
        ...


class Subscribers(Generic[R]):
    """The latest reading and the callbacks that want each new one; a callback that raises is logged and
    does not stop the others (as a python-can listener must not stop a Notifier)."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.latest: R | None = None
        self.count = 0
        self._callbacks: list[Callable[[R], None]] = []

    def subscribe(self, callback: Callable[[R], None]) -> None:
        self._callbacks.append(callback)

    @property
    def listeners(self) -> int:
        """How many callbacks take every reading."""
        return len(self._callbacks)

    def publish(self, reading: R) -> None:
        self.latest = reading
        self.count += 1
        for callback in self._callbacks:
            try:
                callback(reading)
            except Exception:
                log.exception("%s: a subscriber failed", self.name)


class Publishes(Generic[R]):
    """A device's reading side of the interface (``latest``, ``count``, ``subscribe``) from its ``_out``."""

    _out: Subscribers[R]

    @property
    def latest(self) -> R | None:
        return self._out.latest

    @property
    def count(self) -> int:
        return self._out.count

    def subscribe(self, callback: Callable[[R], None]) -> None:
        self._out.subscribe(callback)


class ThreadedDevice(Publishes[R], ABC):
    """A device read by a thread of its own (serial ports, cameras); see the module docstring.

    Subclasses implement `_open` (open the port, configure the device, return a short description such as
    the model), `_read` (block briefly, return the readings decoded so far, raise `OSError` when the port
    fails) and `_close`. ``now`` is the robot's clock, used to stamp readings as they arrive; ``max_age_s``
    is how old the newest reading may be before the device counts as silent; ``queue_size`` is how many
    readings wait for the scheduler at most (when it stalls, the oldest are dropped and counted in
    ``dropped``): a device with large readings, such as a camera's frames, keeps fewer.
    """

    #: Readings are handed over on the scheduler's thread this often (a lidar revolution is 0.1 s).
    rate_hz: float | None = 50.0

    def __init__(self, name: str, *, now: Callable[[], float], max_age_s: float, port: str | None = None,
                 queue_size: int = QUEUE_SIZE) -> None:
        if queue_size < 1:
            raise ValueError(f"{name}: queue_size must be at least 1, got {queue_size}")
        self.name = name
        self.port = port
        self.max_age_s = max_age_s
        self._now = now
        self._out: Subscribers[R] = Subscribers(name)
        self.queue_size = queue_size
        self._queue: queue.Queue[R] = queue.Queue(maxsize=queue_size)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._connected = False
        self._problem: str | None = "not started"
        self._last_arrival: float | None = None
        self.dropped = 0
        self.reconnects = 0

    # -- the interface -------------------------------------------------------------------------------------
    @property
    def connected(self) -> bool:
        with self._lock:
            return self._connected

    def start(self) -> None:
        """Start the reader thread; it opens the device (and keeps trying while the device is missing)."""
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"atemr-{self.name}", daemon=True)
        self._thread.start()

    def tick(self, now: float) -> None:
        while True:
            try:
                reading = self._queue.get_nowait()
            except queue.Empty:
                return
            self._out.publish(reading)

    def health(self, now: float) -> ComponentHealth:
        with self._lock:
            connected, problem, last = self._connected, self._problem, self._last_arrival
        if not connected:
            return ComponentHealth(False, problem or f"{self.name} is not connected")
        return fresh(last, now, self.max_age_s, f"reading from {self.port}")

    def shutdown(self) -> None:
        """Stop the reader thread and close the device; idempotent."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout=2.0)
            if thread.is_alive():
                log.warning("%s: the reader thread did not stop within 2 s", self.name)

    # -- what a driver implements ---------------------------------------------------------------------------
    @abstractmethod
    def _open(self) -> None:
        """Open and configure the device; raise `OSError` (or `HardwareError`) with why when it is missing."""

    @abstractmethod
    def _read(self) -> list[R]:
        """Wait briefly (at most about 0.1 s) and return the readings decoded so far; raise `OSError` when the
        port fails."""

    @abstractmethod
    def _close(self) -> None:
        """Close the device; never raises."""

    def missing_hint(self, error: BaseException) -> str:
        """What to do when opening fails with ``error`` (drivers add their own advice)."""
        return str(error)

    # -- the reader thread ----------------------------------------------------------------------------------
    def _set_state(self, connected: bool, problem: str | None) -> None:
        with self._lock:
            self._connected = connected
            self._problem = problem

    def _run(self) -> None:
        first = True
        while not self._stop.is_set():
            try:
                self._open()
            except Exception as exc:  # a missing device is a state, not a crash
                self._close()  # whatever the failed open left half open
                self._set_state(False, self.missing_hint(exc))
                if first:
                    log.warning("%s", self.missing_hint(exc))
                    first = False
                self._stop.wait(REOPEN_S)
                continue
            if not first:
                self.reconnects += 1
                log.warning("%s: reconnected on %s", self.name, self.port)
            first = False
            self._set_state(True, None)
            try:
                while not self._stop.is_set():
                    for reading in self._read():
                        self._hand_over(reading)
            except Exception as exc:
                why = f"{self.name}: lost {self.port}: {exc}"
                log.warning("%s", why)
                self._set_state(False, why + " (unplugged? it is reopened when it comes back)")
            finally:
                self._close()
            self._stop.wait(REOPEN_S)
        self._set_state(False, "stopped")

    def _hand_over(self, reading: R) -> None:
        with self._lock:
            self._last_arrival = self._now()
        try:
            self._queue.put_nowait(reading)
        except queue.Full:  # the scheduler stalled: keep the newest
            try:
                self._queue.get_nowait()
                self.dropped += 1
            except queue.Empty:
                pass
            self._queue.put_nowait(reading)

    def stamp(self) -> float:
        """The robot's time now (for readings the driver builds)."""
        return self._now()
