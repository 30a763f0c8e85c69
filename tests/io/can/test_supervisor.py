"""The supervised receive side: listeners isolated, dead receivers, bus-off, send failures, silence, inboxes
and recovery."""

from __future__ import annotations

import itertools
import threading

import can
import pytest

from atemr.errors import BusError, HardwareError
from atemr.io.can.supervisor import INBOX_FRAMES, BusSupervisor

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


def test_polled_delivery_survives_a_failing_listener_which_is_a_fault() -> None:
    ch = channel()
    got: list[int] = []
    faults: list[HardwareError] = []

    def broken(m: can.Message) -> None:
        raise RuntimeError("listener bug")

    with can.Bus(interface="virtual", channel=ch) as tx, BusSupervisor(
        can.Bus(interface="virtual", channel=ch), [broken, lambda m: got.append(m.arbitration_id)],
        on_fault=faults.append,
    ) as sup:
        tx.send(msg(0x150))
        tx.send(msg(0x151))
        sup.tick(0.0)
        assert got == [0x150, 0x151]  # the other listener still got every frame
        assert sup.listener_errors == 2 and "listener bug" in (sup.last_listener_error or "")
        assert sup.frames == 2 and not sup.healthy
        assert faults == [sup.fault] and "listener failed" in str(sup.fault) and "broken" in str(sup.fault)


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
        assert got == [0x150, 0x151] and sup.listener_errors == 2
        assert "listener failed" in str(sup.fault)  # reported by tick, on the scheduler's thread


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
    assert isinstance(sup.fault, BusError) and "bus-off" in str(sup.fault) and not sup.fault.critical
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


# -- inboxes: one receive side shared by several consumers ------------------------------------------------------
def test_inboxes_each_get_every_frame_and_a_polled_read_drains_the_bus_first() -> None:
    ch = channel()
    with can.Bus(interface="virtual", channel=ch) as tx, BusSupervisor(can.Bus(interface="virtual", channel=ch)) as sup:
        motors, link = sup.inbox("motors"), sup.inbox("link")
        tx.send(msg(0x141))
        tx.send(msg(0x157))
        # no tick in between: reading an empty inbox drains the bus, as a bus of the consumer's own would be read
        assert [m.arbitration_id for m in iter(lambda: link.recv(timeout=0), None)] == [0x141, 0x157]
        assert [m.arbitration_id for m in iter(lambda: motors.recv(timeout=0), None)] == [0x141, 0x157]
        assert sup.frames == 0  # tick has not looked yet ...
        sup.tick(0.0)
        assert sup.frames == 2 and sup.healthy  # ... and counts what the reads delivered


def test_an_inbox_sends_on_the_supervised_bus_and_shares_its_state() -> None:
    ch = channel()
    with can.Bus(interface="virtual", channel=ch) as rx, BusSupervisor(can.Bus(interface="virtual", channel=ch)) as sup:
        inbox = sup.inbox("motors")
        inbox.send(msg(0x141))
        got = rx.recv(timeout=0)
        assert got is not None and got.arbitration_id == 0x141
        assert inbox.state is can.BusState.ACTIVE
    bus = StatefulBus()
    sup = BusSupervisor(bus)
    inbox = sup.inbox("motors")
    bus.state = can.BusState.ERROR
    assert inbox.state is can.BusState.ERROR
    inbox.shutdown()  # closing an inbox leaves the supervised bus to its owner
    assert not bus._is_shutdown
    sup.shutdown()
    assert bus._is_shutdown


def test_a_full_inbox_drops_its_oldest_frames_and_counts_them() -> None:
    sup = BusSupervisor(StatefulBus())
    inbox = sup.inbox("slow reader")
    for i in range(INBOX_FRAMES + 3):
        inbox.deliver(can.Message(arbitration_id=0x141, data=i.to_bytes(2, "little"), is_extended_id=False))
    first = inbox.recv(timeout=0)
    assert inbox.dropped == 3 and first is not None and int.from_bytes(first.data, "little") == 3
    sup.shutdown()


def test_threaded_inbox_recv_waits_for_a_frame() -> None:
    ch = channel()
    with can.Bus(interface="virtual", channel=ch) as tx, BusSupervisor(
        can.Bus(interface="virtual", channel=ch), threaded=True
    ) as sup:
        inbox = sup.inbox("link")
        tx.send(msg(0x157))
        got = inbox.recv(timeout=5.0)  # the Notifier thread delivers it; the timeout only bounds a failure
        assert got is not None and got.arbitration_id == 0x157


# -- recovery -----------------------------------------------------------------------------------------------------
class QueueBus(StatefulBus):
    """A stateful bus that receives the frames a test puts in ``pending`` (and fails while ``fail_recv``)."""

    def __init__(self) -> None:
        super().__init__()
        self.pending: list[can.Message] = []

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        super()._recv_internal(timeout)  # raises while fail_recv
        return (self.pending.pop(0) if self.pending else None), False


def test_bus_off_recovers_once_the_state_is_back_frames_arrive_and_it_settled() -> None:
    bus = QueueBus()
    sup = BusSupervisor(bus, settle_s=1.0)
    bus.state = can.BusState.ERROR
    sup.tick(0.0)
    assert sup.problem == "bus-off (bus state ERROR)"
    assert isinstance(sup.fault, BusError) and sup.fault.component == "can_bus" and not sup.fault.critical
    sup.tick(0.5)
    assert sup.recover() == "bus still off (bus state ERROR)"
    bus.state = can.BusState.ACTIVE
    assert sup.recover() == "no frame received since the fault"
    bus.pending.append(msg())
    sup.tick(1.0)
    assert sup.recover() == "last error 0.50 s ago, waiting for 1.00 s without one"
    sup.tick(1.5)
    assert sup.recover() is None and sup.healthy and sup.problem is None
    sup.shutdown()


def test_a_listener_that_keeps_failing_holds_the_fault() -> None:
    ch = channel()
    failing = [True]

    def tap(m: can.Message) -> None:
        if failing[0]:
            raise RuntimeError("tap bug")

    with can.Bus(interface="virtual", channel=ch) as tx, BusSupervisor(can.Bus(interface="virtual", channel=ch),
                                                                       [tap], settle_s=1.0) as sup:
        for t in (0.0, 0.5, 1.0, 1.5):  # a frame every 0.5 s, each one failing
            tx.send(msg())
            sup.tick(t)
            assert "tap bug" in str(sup.fault) and sup.recover() is not None, t
        failing[0] = False
        for t in (2.0, 2.4):
            tx.send(msg())
            sup.tick(t)
            assert sup.recover() is not None, t
        sup.tick(2.5)
        assert sup.recover() is None and sup.healthy
        sup.tick(2.6)
        assert sup.healthy  # the errors before the recovery are not reported again


def test_polled_receive_error_holds_until_recv_works_and_frames_arrive() -> None:
    bus = QueueBus()
    bus.fail_recv = True
    sup = BusSupervisor(bus, settle_s=1.0)
    for t in (0.0, 1.0, 2.0):
        sup.tick(t)
    assert "receive failed" in str(sup.fault)
    assert sup.recover() == "no frame received since the fault"
    bus.fail_recv = False
    sup.tick(2.5)
    assert sup.recover() == "no frame received since the fault"
    bus.pending.append(msg())
    sup.tick(3.0)
    assert sup.recover() is None and sup.frames == 1
    sup.shutdown()


class ThreadKilled(BaseException):
    """Not an `Exception`: python-can's Notifier does not catch it, so its receive thread dies."""


@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")
def test_a_dead_receive_thread_is_a_fault_and_recovery_restarts_it() -> None:
    ch = channel()
    done = threading.Event()
    faults: list[HardwareError] = []
    with can.Bus(interface="virtual", channel=ch) as tx, BusSupervisor(
        can.Bus(interface="virtual", channel=ch), [lambda m: done.set()], threaded=True, on_fault=faults.append,
        settle_s=0.5,
    ) as sup:
        bus = sup.bus
        receive = bus._recv_internal

        def die(timeout: float | None) -> tuple[can.Message | None, bool]:
            raise ThreadKilled

        bus._recv_internal = die  # type: ignore[method-assign]
        for _ in range(500):  # until the thread has died
            sup.tick(0.0)
            if sup.fault is not None:
                break
            threading.Event().wait(0.01)
        assert faults == [sup.fault] and "receive thread is dead" in str(sup.fault)
        bus._recv_internal = receive  # type: ignore[method-assign]
        assert sup.recover() == "receive thread restarted, waiting for frames" and sup.restarts == 1
        tx.send(msg())
        assert done.wait(5.0)  # the new thread delivers
        sup.tick(0.1)
        assert sup.recover() == "last error 0.10 s ago, waiting for 0.50 s without one"
        sup.tick(0.5)
        assert sup.recover() is None and sup.healthy


def error_frame(flags: int) -> can.Message:
    """A SocketCAN error frame as python-can delivers it (the error class in the ID)."""
    return can.Message(arbitration_id=flags, is_error_frame=True, data=bytes(8), is_extended_id=False)


@pytest.mark.parametrize("threaded", [False, True])
def test_a_bus_off_error_frame_is_a_fault_not_traffic(threaded: bool) -> None:
    # python-can's socketcan bus has no `state`: bus-off arrives as an error frame with CAN_ERR_BUSOFF (0x40).
    ch = channel()
    got: list[can.Message] = []
    with can.Bus(interface="virtual", channel=ch) as tx, BusSupervisor(
        can.Bus(interface="virtual", channel=ch), [got.append], threaded=threaded, settle_s=1.0
    ) as sup:
        tx.send(error_frame(0x04))  # a controller problem other than bus-off: not a fault by itself
        tx.send(error_frame(0x40))
        tx.send(msg(0x151))
        if threaded:
            for _ in range(500):  # the receive thread's pace, not a clock
                if sup._probe.counts()[0] == 1 and sup._probe.bus_off_frames == 1:
                    break
                threading.Event().wait(0.01)
        sup.tick(0.0)
        assert [m.arbitration_id for m in got] == [0x151], "error frames never reach the consumers"
        assert sup.frames == 1, "and they are not traffic"
        assert sup.problem == "bus-off (the controller's error frame)" and not sup.healthy
        tx.send(error_frame(0x40))  # still off: the error is refreshed
        tx.send(msg(0x151))
        if threaded:
            for _ in range(500):
                if sup._probe.bus_off_frames == 2 and sup._probe.counts()[0] == 2:
                    break
                threading.Event().wait(0.01)
        sup.tick(0.8)
        assert sup.recover() == "last error 0.00 s ago, waiting for 1.00 s without one"
