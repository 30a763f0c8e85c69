"""The fault-injection bus: seeded, repeatable drops, duplicates, delays, reorders, corruption, outages."""

from __future__ import annotations

import itertools

import can
import pytest

from atemr.clock import SimClock
from atemr.errors import ConfigError
from atemr.io.can.faults import FaultInjectionBus, FaultPlan

_names = itertools.count()


def pair(plan: FaultPlan, clock: SimClock, direction: str = "send") -> tuple[FaultInjectionBus, can.BusABC]:
    channel = f"faults-{next(_names)}"
    tx = FaultInjectionBus(can.Bus(interface="virtual", channel=channel), plan, clock,
                           direction=direction)  # type: ignore[arg-type]
    return tx, can.Bus(interface="virtual", channel=channel)


def frames(n: int) -> list[can.Message]:
    return [can.Message(arbitration_id=0x100, data=k.to_bytes(2, "little"), is_extended_id=False) for k in range(n)]


def run(plan: FaultPlan, n: int = 200, direction: str = "send") -> list[int]:
    clock = SimClock()
    tx, rx = pair(plan, clock, direction)
    out: list[int] = []
    with tx, rx:
        for msg in frames(n):
            tx.send(msg)
            clock.advance(0.01)
        clock.advance(10.0)
        tx.flush_due()
        if direction == "send":
            while (m := rx.recv(timeout=0)) is not None:
                out.append(int.from_bytes(m.data, "little"))
    return out


def test_clean_plan_passes_everything_in_order() -> None:
    assert run(FaultPlan()) == list(range(200))


def test_drops_are_seeded_and_repeatable() -> None:
    a, b = run(FaultPlan(drop=0.3, seed=7)), run(FaultPlan(drop=0.3, seed=7))
    assert a == b
    assert 100 < len(a) < 180
    assert a == sorted(a)
    assert run(FaultPlan(drop=0.3, seed=8)) != a


def test_duplicates() -> None:
    out = run(FaultPlan(duplicate=0.2, seed=1))
    assert len(out) > 200 and sorted(set(out)) == list(range(200))


def test_delays_reorder_against_later_frames_but_lose_nothing() -> None:
    out = run(FaultPlan(delay=0.2, delay_s=0.05, seed=2))
    assert sorted(out) == list(range(200)) and out != list(range(200))


def test_reorder_swaps_neighbours() -> None:
    out = run(FaultPlan(reorder=0.2, seed=3))
    assert sorted(out) == list(range(200)) and out != list(range(200))
    swapped = [i for i in range(199) if out[i] > out[i + 1]]
    assert swapped and all(out[i] == out[i + 1] + 1 for i in swapped)


def test_corruption_flips_bits() -> None:
    out = run(FaultPlan(corrupt=0.5, seed=4))
    assert len(out) == 200 and sum(v != k for k, v in enumerate(out)) > 50


def test_outage_windows_drop_everything_inside() -> None:
    out = run(FaultPlan(outages=((0.5, 1.0),)))
    assert out == [k for k in range(200) if not 0.5 <= k * 0.01 < 1.0]


def test_receive_side_faults() -> None:
    clock = SimClock()
    channel = f"faults-{next(_names)}"
    with can.Bus(interface="virtual", channel=channel) as tx, FaultInjectionBus(
        can.Bus(interface="virtual", channel=channel), FaultPlan(drop=0.5, seed=5), clock, direction="recv"
    ) as rx:
        for msg in frames(100):
            tx.send(msg)
        got = []
        while (m := rx.recv(timeout=0)) is not None:
            got.append(m)
        assert 20 < len(got) < 80 and rx.stats["recv"].dropped == 100 - len(got)


def test_link_switch() -> None:
    clock = SimClock()
    tx, rx = pair(FaultPlan(), clock)
    with tx, rx:
        tx.link_up = False
        tx.send(frames(1)[0])
        assert rx.recv(timeout=0) is None
        tx.link_up = True
        tx.send(frames(1)[0])
        assert rx.recv(timeout=0) is not None


def test_bad_plans() -> None:
    with pytest.raises(ConfigError, match="drop"):
        FaultPlan(drop=1.5)
    with pytest.raises(ConfigError, match="outage"):
        FaultPlan(outages=((2.0, 1.0),))
