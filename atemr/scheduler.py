"""A deterministic scheduler: every component ticks at its own rate from one injected clock.

With a `SimClock` the run is as fast as the CPU allows and exactly repeatable: tick times are computed
as ``start + k / rate`` (no accumulated float drift) and ties are broken by the order components were
added. With a wall clock (or `RealTimeSimClock`) the same loop is locked to real time; a tick that
takes longer than its period, or that starts a whole period late, is reported as an overrun and the
missed ticks are skipped rather than burst, as a control loop must.
"""

from __future__ import annotations

import heapq
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from atemr.clock import Clock, WallClock

log = logging.getLogger(__name__)


@runtime_checkable
class Component(Protocol):
    """Anything the scheduler ticks. ``start``/``shutdown`` are optional (see `Scheduler.add`)."""

    name: str

    def tick(self, now: float) -> None:
        """Do one period of work at simulated/real time ``now``; must not block."""
        ...


@dataclass(frozen=True)
class Overrun:
    """A tick that did not fit in its period (``cost_s``) or started late (``late_s``)."""

    component: str
    due: float
    period_s: float
    cost_s: float
    late_s: float
    skipped: int


@dataclass
class _Entry:
    component: Component
    rate_hz: float
    order: int
    start: float
    k: int = 0
    ticks: int = 0
    errors: int = 0
    total_cost_s: float = 0.0
    max_cost_s: float = 0.0

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz

    def due(self) -> float:
        return self.start + self.k / self.rate_hz


@dataclass
class ComponentStats:
    """What the scheduler knows about one component, for health displays and benchmarks."""

    name: str
    rate_hz: float
    ticks: int
    errors: int
    overruns: int
    mean_cost_s: float
    max_cost_s: float


ErrorHandler = Callable[[Component, BaseException], None]


@dataclass
class Scheduler:
    """Ticks components in a stable order from ``clock``; ``timer`` measures how long ticks take.

    ``timer`` is separate from ``clock`` because in simulation the clock jumps, while the cost of a
    tick is always real CPU time. Keep ``trace=True`` to record ``(time, component)`` for every tick,
    which is how determinism is tested.
    """

    clock: Clock
    timer: Clock = field(default_factory=WallClock)
    on_error: ErrorHandler | None = None
    on_overrun: Callable[[Overrun], None] | None = None
    trace: bool = False
    #: False when the clock is simulated and not paced: an overrun then only means "this would not keep
    #: up in real time", so it is counted and logged at DEBUG instead of warned about.
    realtime: bool = True
    traced: list[tuple[float, str]] = field(default_factory=list)
    overruns: list[Overrun] = field(default_factory=list)
    max_overruns_kept: int = 1000

    def __post_init__(self) -> None:
        self._entries: list[_Entry] = []
        self._heap: list[tuple[float, int, _Entry]] = []
        self._started: list[Component] = []
        self._stop = threading.Event()
        self._overrun_counts: dict[str, int] = {}

    # -- composition ---------------------------------------------------------------------------
    def add(self, component: Component, rate_hz: float, *, phase_s: float = 0.0) -> None:
        """Tick ``component`` every ``1/rate_hz`` s, first at ``now + phase_s``.

        Components are started (``start()`` if they have one) in the order they are added and shut
        down in reverse order.
        """
        if not rate_hz > 0:
            raise ValueError(f"{component.name}: rate must be > 0 Hz, got {rate_hz}")
        if any(e.component.name == component.name for e in self._entries):
            raise ValueError(f"a component named '{component.name}' is already scheduled")
        entry = _Entry(component, float(rate_hz), len(self._entries), self.clock.now() + phase_s)
        self._entries.append(entry)
        heapq.heappush(self._heap, (entry.due(), entry.order, entry))

    @property
    def components(self) -> list[Component]:
        """The scheduled components in the order they were added."""
        return [e.component for e in self._entries]

    # -- lifecycle -----------------------------------------------------------------------------
    def start(self) -> None:
        """Call ``start()`` on every component that has one, in order; on failure undo what started.

        Every component, with or without ``start``, is then shut down by `shutdown` (if it has one).
        """
        for entry in self._entries:
            if entry.component in self._started:
                continue
            start = getattr(entry.component, "start", None)
            try:
                if start is not None:
                    start()
            except BaseException:
                self.shutdown()
                raise
            self._started.append(entry.component)  # shut down later even if it had no start()
            log.debug("started %s", entry.component.name)

    def shutdown(self) -> None:
        """Shut components down in reverse start order; one failing does not stop the others."""
        while self._started:
            comp = self._started.pop()
            stop = getattr(comp, "shutdown", None)
            if stop is None:
                continue
            try:
                stop()
                log.debug("shut down %s", comp.name)
            except Exception:
                log.exception("error while shutting down %s", comp.name)

    def stop(self) -> None:
        """Ask `run` to return after the current tick; safe from a signal handler or thread. A stop asked while
        nothing runs holds for the next `run`, which then returns at once: a SIGTERM that comes between a
        robot's start and its run is not lost."""
        self._stop.set()

    @property
    def stopping(self) -> bool:
        """A stop was asked and not yet used up by a `run` returning (False again once it has)."""
        return self._stop.is_set()

    # -- running -------------------------------------------------------------------------------
    def step(self) -> float:
        """Run the next due tick (waiting for it on the clock) and return its time."""
        due, _, entry = heapq.heappop(self._heap)
        self.clock.sleep_until(due)
        late = self.clock.now() - due
        skipped = 0
        if late >= entry.period_s:
            skipped = int(late // entry.period_s)
        t0 = self.timer.now()
        try:
            entry.component.tick(due)
        except Exception as exc:
            entry.errors += 1
            if self.on_error is None:
                raise
            self.on_error(entry.component, exc)
        finally:
            cost = self.timer.now() - t0
            entry.ticks += 1
            entry.total_cost_s += cost
            entry.max_cost_s = max(entry.max_cost_s, cost)
            if self.trace:
                self.traced.append((due, entry.component.name))
            if cost > entry.period_s or skipped:
                self._report_overrun(Overrun(entry.component.name, due, entry.period_s, cost, late, skipped))
            entry.k += 1 + skipped
            heapq.heappush(self._heap, (entry.due(), entry.order, entry))
        return due

    def run(self, *, until: float | None = None, duration: float | None = None) -> None:
        """Tick until ``stop()`` is called, or up to simulated/real time ``until`` (or now+``duration``).

        Ticks due exactly at ``until`` run; the clock ends at ``until``. A stop asked before this call makes it
        return at once; the stop is used up when it returns, so the next call runs again.
        """
        if until is not None and duration is not None:
            raise ValueError("give either until or duration, not both")
        if duration is not None:
            until = self.clock.now() + duration
        if not self._heap:
            raise RuntimeError("nothing to run: no component is scheduled")
        try:
            while not self._stop.is_set():
                if until is not None and self._heap[0][0] > until:
                    self.clock.sleep_until(until)
                    break
                self.step()
        finally:
            self._stop.clear()

    # -- reporting -----------------------------------------------------------------------------
    def _report_overrun(self, overrun: Overrun) -> None:
        self._overrun_counts[overrun.component] = self._overrun_counts.get(overrun.component, 0) + 1
        if len(self.overruns) < self.max_overruns_kept:
            self.overruns.append(overrun)
        log.log(
            logging.WARNING if self.realtime else logging.DEBUG,
            "overrun: %s took %.1f ms of a %.1f ms period, started %.1f ms late, skipped %d tick(s)",
            overrun.component, overrun.cost_s * 1e3, overrun.period_s * 1e3, overrun.late_s * 1e3,
            overrun.skipped,
        )
        if self.on_overrun is not None:
            self.on_overrun(overrun)

    def stats(self) -> list[ComponentStats]:
        """Per-component tick counts, errors, overruns and tick cost."""
        return [
            ComponentStats(
                e.component.name, e.rate_hz, e.ticks, e.errors, self._overrun_counts.get(e.component.name, 0),
                e.total_cost_s / e.ticks if e.ticks else 0.0, e.max_cost_s,
            )
            for e in self._entries
        ]
