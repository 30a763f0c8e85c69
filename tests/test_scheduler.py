import random
from dataclasses import dataclass, field

import pytest

from atemr.clock import SimClock
from atemr.scheduler import Overrun, Scheduler


@dataclass
class Recorder:
    name: str
    log: list = field(default_factory=list)
    events: list | None = None

    def tick(self, now: float) -> None:
        self.log.append(now)

    def start(self) -> None:
        if self.events is not None:
            self.events.append(("start", self.name))

    def shutdown(self) -> None:
        if self.events is not None:
            self.events.append(("shutdown", self.name))


class FakeTimer:
    """A cost clock a test controls: each tick of a component 'takes' a set time."""

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def sleep_until(self, t: float) -> None:
        self.t = max(self.t, t)


def test_rates_are_respected_over_a_simulated_second():
    sched = Scheduler(SimClock())
    control, lidar, status = Recorder("control"), Recorder("lidar"), Recorder("status")
    sched.add(control, 50)
    sched.add(lidar, 10)
    sched.add(status, 2)
    sched.run(until=1.0)
    assert len(control.log) == 51  # t = 0, 0.02, ..., 1.0 inclusive
    assert len(lidar.log) == 11
    assert status.log == [0.0, 0.5, 1.0]
    assert sched.clock.now() == 1.0


def test_tick_times_do_not_drift():
    sched = Scheduler(SimClock())
    control = Recorder("control")
    sched.add(control, 50)
    sched.run(until=100.0)
    assert control.log[-1] == 100.0
    assert control.log[2500] == 50.0


def test_ties_run_in_the_order_components_were_added():
    sched = Scheduler(SimClock(), trace=True)
    for name in ("c", "a", "b"):
        sched.add(Recorder(name), 10)
    sched.run(until=0.1)
    assert [n for _, n in sched.traced] == ["c", "a", "b", "c", "a", "b"]


def _random_trace(seed: int) -> list:
    rng = random.Random(seed)
    sched = Scheduler(SimClock(), trace=True)
    for i in range(8):
        sched.add(Recorder(f"c{i}"), rng.choice([1, 2, 5, 10, 20, 50, 100, 7.5]), phase_s=rng.random() / 10)
    sched.run(until=10.0)
    return sched.traced


def test_same_seed_gives_identical_traces():
    assert _random_trace(42) == _random_trace(42)
    assert _random_trace(42) != _random_trace(43)


def test_overrun_is_reported_when_a_tick_exceeds_its_period():
    timer = FakeTimer()
    seen: list[Overrun] = []
    sched = Scheduler(SimClock(), timer=timer, on_overrun=seen.append)

    class Slow:
        name = "slow"

        def tick(self, now: float) -> None:
            timer.t += 0.03  # 30 ms of work in a 20 ms period

    sched.add(Slow(), 50)
    sched.add(Recorder("fast"), 50)
    sched.run(until=0.04)
    assert [o.component for o in seen] == ["slow", "slow", "slow"]
    assert seen[0].period_s == pytest.approx(0.02)
    assert seen[0].cost_s == pytest.approx(0.03)
    stats = {s.name: s for s in sched.stats()}
    assert stats["slow"].overruns == 3 and stats["fast"].overruns == 0


def test_late_ticks_are_skipped_and_reported_in_real_time():
    class LaggyClock(SimClock):
        """Lands 0.05 s after the requested time, as an overloaded machine would."""

        def sleep_until(self, t: float) -> None:
            super().sleep_until(t + 0.05)

    seen: list[Overrun] = []
    sched = Scheduler(LaggyClock(), timer=FakeTimer(), on_overrun=seen.append)
    rec = Recorder("control")
    sched.add(rec, 50)
    sched.step()
    assert seen and seen[0].skipped == 2
    sched.step()
    assert rec.log == [0.0, 0.06]  # ticks 0.02 and 0.04 were skipped, not burst


def test_start_in_order_shutdown_in_reverse():
    events: list = []
    sched = Scheduler(SimClock())
    for name in ("bus", "motors", "agent"):
        sched.add(Recorder(name, events=events), 10)
    sched.start()
    sched.shutdown()
    sched.shutdown()  # idempotent
    assert events == [
        ("start", "bus"), ("start", "motors"), ("start", "agent"),
        ("shutdown", "agent"), ("shutdown", "motors"), ("shutdown", "bus"),
    ]


def test_failed_start_undoes_what_started():
    events: list = []

    class Broken(Recorder):
        def start(self) -> None:
            raise RuntimeError("no lidar")

    sched = Scheduler(SimClock())
    sched.add(Recorder("bus", events=events), 10)
    sched.add(Broken("lidar"), 10)
    with pytest.raises(RuntimeError, match="no lidar"):
        sched.start()
    assert events == [("start", "bus"), ("shutdown", "bus")]


def test_tick_errors_go_to_the_handler_and_the_loop_goes_on():
    errors: list = []

    class Faulty(Recorder):
        def tick(self, now: float) -> None:
            super().tick(now)
            raise ValueError("bad frame")

    sched = Scheduler(SimClock(), on_error=lambda c, e: errors.append((c.name, str(e))))
    faulty = Faulty("faulty")
    sched.add(faulty, 10)
    sched.run(until=0.2)
    assert len(faulty.log) == 3
    assert errors == [("faulty", "bad frame")] * 3
    assert sched.stats()[0].errors == 3


def test_tick_errors_raise_without_a_handler():
    class Faulty(Recorder):
        def tick(self, now: float) -> None:
            raise ValueError("bad")

    sched = Scheduler(SimClock())
    sched.add(Faulty("f"), 10)
    with pytest.raises(ValueError):
        sched.run(until=1)


def test_stop_from_inside_a_tick():
    sched = Scheduler(SimClock())

    class Stopper(Recorder):
        def tick(self, now: float) -> None:
            super().tick(now)
            if now >= 0.3:
                sched.stop()

    s = Stopper("stopper")
    sched.add(s, 10)
    sched.run()
    assert s.log[-1] == pytest.approx(0.3)


def test_a_stop_asked_before_run_makes_it_return_at_once_and_is_used_up():
    """A SIGTERM between a robot's start and its run (``atemr run``) must not be lost."""
    sched = Scheduler(SimClock())
    r = Recorder("r")
    sched.add(r, 10)
    sched.stop()
    sched.run(until=5.0)  # returns at once, before its first tick
    assert r.log == []
    sched.run(until=0.2)  # the stop was used up: the next run runs
    assert r.log == pytest.approx([0.0, 0.1, 0.2])


def test_bad_rates_and_duplicate_names_are_refused():
    sched = Scheduler(SimClock())
    with pytest.raises(ValueError, match="rate"):
        sched.add(Recorder("x"), 0)
    sched.add(Recorder("x"), 1)
    with pytest.raises(ValueError, match="already"):
        sched.add(Recorder("x"), 1)


def test_run_needs_components():
    with pytest.raises(RuntimeError, match="nothing to run"):
        Scheduler(SimClock()).run(until=1)
