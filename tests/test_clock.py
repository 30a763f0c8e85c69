import pytest

from atemr.clock import Clock, RealTimeSimClock, SimClock, WallClock


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
