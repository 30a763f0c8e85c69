"""The supervised receive side: listeners isolated, dead receivers, bus-off, send failures, silence."""

from __future__ import annotations

import itertools
import threading

import can
import pytest

from atemr.errors import BusError, HardwareError
from atemr.io.can.supervisor import BusSupervisor

_names = itertools.count()


def channel() -> str:
    return f"supervisor-{next(_names)}"


def msg(i: int = 0x157) -> can.Message:
    return can.Message(arbitration_id=i, data=b"\x01", is_extended_id=False)


class FailingBus(can.BusABC):
    """A bus whose recv/send raise like a bus that went off."""

    def __init__(self) -> None:
        super().__init__(channel="failing")
        self.fail_recv = False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        raise can.CanOperationError("transmit buffer full")

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if self.fail_recv:
            raise can.CanOperationError("controller in bus-off")
        return None, False


def test_polled_delivery_survives_a_failing_listener() -> None:
    ch = channel()
    got: list[int] = []

    def broken(m: can.Message) -> None:
        raise RuntimeError("listener bug")

    with can.Bus(interface="virtual", channel=ch) as tx, BusSupervisor(
        can.Bus(interface="virtual", channel=ch), [broken, lambda m: got.append(m.arbitration_id)]
    ) as sup:
        tx.send(msg(0x150))
        tx.send(msg(0x151))
        sup.tick(0.0)
        assert got == [0x150, 0x151]
        assert sup.listener_errors == 2 and "listener bug" in (sup.last_listener_error or "")
        assert sup.healthy and sup.frames == 2


def test_threaded_delivery_and_listener_isolation() -> None:
    ch = channel()
    done = threading.Event()
    got: list[int] = []

    def collect(m: can.Message) -> None:
        got.append(m.arbitration_id)
        if len(got) == 2:
            done.set()

    def broken(m: can.Message) -> None:
        raise RuntimeError("boom")

    with can.Bus(interface="virtual", channel=ch) as tx, BusSupervisor(
        can.Bus(interface="virtual", channel=ch), [broken, collect], threaded=True
    ) as sup:
        tx.send(msg(0x150))
        tx.send(msg(0x151))
        assert done.wait(5.0)  # waits for the receive thread, not on a clock
        sup.tick(0.0)
        assert got == [0x150, 0x151] and sup.listener_errors == 2 and sup.healthy


def test_threaded_receive_error_is_a_fault() -> None:
    bus = FailingBus()
    faults: list[HardwareError] = []
    sup = BusSupervisor(bus, threaded=True, on_fault=faults.append)
    sup.start()
    bus.fail_recv = True
    for _ in range(500):  # until the thread has hit the error
        sup.tick(0.0)
        if sup.fault is not None:
            break
        threading.Event().wait(0.01)
    assert isinstance(sup.fault, BusError) and "bus-off" in str(sup.fault) and sup.fault.critical
    assert faults == [sup.fault]
    sup.shutdown()


def test_not_started_threaded_supervisor_reports() -> None:
    sup = BusSupervisor(FailingBus(), threaded=True)
    sup.tick(0.0)
    assert "not started" in str(sup.fault)
    sup.shutdown()


def test_polled_receive_error_is_a_fault() -> None:
    bus = FailingBus()
    bus.fail_recv = True
    sup = BusSupervisor(bus)
    sup.tick(0.0)
    with pytest.raises(BusError, match="receive failed: controller in bus-off"):
        sup.check()
    sup.shutdown()


class StatefulBus(FailingBus):
    """Reports whatever bus state a test sets, as a controller reports bus-off."""

    def __init__(self) -> None:
        super().__init__()
        self._bus_state = can.BusState.ACTIVE

    @property
    def state(self) -> can.BusState:
        return self._bus_state

    @state.setter
    def state(self, new_state: can.BusState) -> None:
        self._bus_state = new_state


def test_bus_off_state() -> None:
    bus = StatefulBus()
    sup = BusSupervisor(bus)
    sup.tick(0.0)
    assert sup.healthy
    bus.state = can.BusState.ERROR
    sup.tick(0.1)
    assert "bus-off" in str(sup.fault)
    sup.shutdown()


def test_send_failures() -> None:
    sup = BusSupervisor(FailingBus())
    with pytest.raises(BusError, match="send of 0x157 failed: transmit buffer full"):
        sup.send(msg())
    assert sup.send_failures == 1 and not sup.healthy
    sup.reset_fault()
    sup.report_send_failure(can.CanOperationError("again"))
    assert sup.send_failures == 2 and "again" in str(sup.fault)
    sup.shutdown()


def test_silence_is_reported_on_the_injected_clock() -> None:
    ch = channel()
    with can.Bus(interface="virtual", channel=ch) as tx, BusSupervisor(
        can.Bus(interface="virtual", channel=ch), max_silence_s=1.0
    ) as sup:
        sup.tick(0.0)
        tx.send(msg())
        sup.tick(0.9)
        sup.tick(1.8)
        assert sup.healthy
        sup.tick(2.0)
        assert "no frame received for 1.10 s" in str(sup.fault)
