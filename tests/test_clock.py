import pytest

from atemr.clock import Clock, RealTimeSimClock, SimClock, WallClock, due


def test_sim_clock_moves_only_when_told():
    clock = SimClock()
    assert clock.now() == 0.0
    clock.advance(0.25)
    assert clock.now() == 0.25
    clock.sleep_until(1.0)
    assert clock.now() == 1.0
    clock.sleep_until(0.5)  # never backwards
    assert clock.now() == 1.0


def test_sim_clock_refuses_negative_advance():
    with pytest.raises(ValueError, match="backwards"):
        SimClock().advance(-1)


def test_wall_clock_is_monotonic_and_waits():
    clock = WallClock()
    t0 = clock.now()
    clock.sleep_until(t0 + 0.01)
    assert clock.now() >= t0 + 0.01


def test_clocks_satisfy_the_protocol():
    for clock in (SimClock(), WallClock(), RealTimeSimClock(speed=100.0)):
        assert isinstance(clock, Clock)


def test_realtime_sim_clock_lands_exactly_on_requested_times():
    clock = RealTimeSimClock(speed=1000.0)
    clock.sleep_until(0.5)  # 0.5 ms of real waiting
    assert clock.now() == 0.5


def test_realtime_sim_clock_rejects_bad_speed():
    with pytest.raises(ValueError):
        RealTimeSimClock(speed=0)


def test_due_meets_a_deadline_that_summed_ticks_miss_by_rounding():
    deadline = sum([0.1] * 3)  # three 0.1 s periods: 0.30000000000000004 ...
    assert deadline > 0.3
    assert due(0.3, deadline)  # ... yet the tick at 0.3 meets it
    assert due(deadline, 0.3) and due(1.0, 1.0)
    assert not due(0.99, 1.0) and not due(1.0 - 1e-6, 1.0)
