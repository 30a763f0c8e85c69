"""The primary's SecondaryLink alone, against a scripted secondary core on a virtual bus."""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

import can
import pytest

from atemr.domain.status import AgentBits, HardwareBits, PowerRequest, PowerState, StateCode
from atemr.errors import HardwareError, ProtocolError
from atemr.io.can import (
    PASSWORD,
    SSID,
    CanId,
    Heartbeat,
    IpAddress,
    IpRequest,
    IrFront,
    IrRear,
    Power,
    PrimaryStatus,
    encode_text,
)
from atemr.io.network import AppliedNetwork, RecordingNetworkBackend
from atemr.io.secondary_link import IR_OUT_OF_RANGE_CM, SecondaryLink, WifiResult, ir_cm_to_m, ir_m_to_cm
from secondary_core.harness import unique_channel

DT = 0.02


class Rig:
    """The link plus a raw bus playing the secondary core; ``step`` ticks the link and collects its frames."""

    def __init__(self, **kwargs: object) -> None:
        channel = unique_channel("link-test")
        self.link_bus = can.Bus(interface="virtual", channel=channel)
        self.board = can.Bus(interface="virtual", channel=channel)
        self.network = RecordingNetworkBackend()
        self.link = SecondaryLink(self.link_bus, self.network, **kwargs)  # type: ignore[arg-type]
        self.t = 0.0
        self.seen: list[tuple[float, can.Message]] = []

    def step(self, n: int = 1, *, answer: bool = False) -> None:
        for _ in range(n):
            self.link.tick(self.t)
            while (msg := self.board.recv(timeout=0)) is not None:
                self.seen.append((self.t, msg))
                if answer and msg.arbitration_id == CanId.HEARTBEAT and Heartbeat.decode(msg).from_primary:
                    self.board.send(Heartbeat(from_primary=False).encode())
            self.t = round(self.t + DT, 9)

    def sent(self, arbitration_id: int) -> list[tuple[float, can.Message]]:
        return [(t, m) for t, m in self.seen if m.arbitration_id == arbitration_id]

    def close(self) -> None:
        self.link.shutdown()
        self.link_bus.shutdown()
        self.board.shutdown()


@pytest.fixture
def rig() -> Iterator[Rig]:
    r = Rig()
    yield r
    r.close()


def test_heartbeat_sent_every_half_second(rig: Rig) -> None:
    rig.step(100)
    times = [t for t, m in rig.sent(CanId.HEARTBEAT) if Heartbeat.decode(m).from_primary]
    assert times == pytest.approx([0.0, 0.5, 1.0, 1.5])


def test_heartbeat_ok_only_with_answers_and_lost_after_2s(rig: Rig) -> None:
    changes: list[bool] = []
    rig.link.on_heartbeat = changes.append
    rig.step(150)
    assert not rig.link.heartbeat_ok and not rig.link.heartbeat_established and changes == []
    rig.step(50, answer=True)
    assert rig.link.heartbeat_ok and changes == [True]
    last_ping = max(t for t, m in rig.sent(CanId.HEARTBEAT) if Heartbeat.decode(m).from_primary)
    exchange = last_ping + DT  # the answer is read at the link's next tick
    rig.step(round((exchange + 1.96 - rig.t) / DT))  # silent secondary
    assert rig.link.heartbeat_ok
    rig.step(4)  # 2 s and one tick (float times: 5.52 - 3.52 may be a hair under 2)
    assert not rig.link.heartbeat_ok and changes == [True, False] and rig.link.heartbeat_losses == 1
    rig.step(30, answer=True)
    assert rig.link.heartbeat_ok and changes == [True, False, True]


def test_unsolicited_or_invalid_heartbeat_is_not_an_exchange(rig: Rig) -> None:
    rig.board.send(Heartbeat(from_primary=False).encode())  # before any ping
    rig.link.tick(-1.0)
    assert not rig.link.heartbeat_established
    rig.board.send(can.Message(arbitration_id=CanId.HEARTBEAT, data=b"\x02", is_extended_id=False))
    rig.step(3)
    assert not rig.link.heartbeat_ok and rig.link.bad_frames == 1


def test_status_sent_at_2hz_and_at_once_on_change(rig: Rig) -> None:
    rig.step(50)  # 1 s
    assert len(rig.sent(CanId.PRIMARY_STATUS)) == 2
    rig.link.set_status(AgentBits.HEARTBEAT | AgentBits.AUTO, HardwareBits.IMU, StateCode.EXEC)
    before = len(rig.sent(CanId.PRIMARY_STATUS))
    rig.step(1)
    frames = rig.sent(CanId.PRIMARY_STATUS)
    assert len(frames) == before + 1
    status = PrimaryStatus.decode(frames[-1][1])
    assert status.state is StateCode.EXEC and status.auto_mode and status.hardware == HardwareBits.IMU
    rig.step(49)
    assert len(rig.sent(CanId.PRIMARY_STATUS)) == before + 2


def test_power_state_sent_periodically_and_on_change(rig: Rig) -> None:
    rig.step(10)
    assert Power.decode(rig.sent(CanId.POWER)[-1][1]) == Power(PowerState.INITIALISING, PowerRequest.NORMAL)
    rig.link.set_power_state(PowerState.RUNNING)
    rig.step(1)
    assert Power.decode(rig.sent(CanId.POWER)[-1][1]).state is PowerState.RUNNING
    rig.step(50)
    assert len(rig.sent(CanId.POWER)) == 1 + 1 + 2


def test_invalid_status_values_refused(rig: Rig) -> None:
    with pytest.raises(ProtocolError, match="0x153"):
        rig.link.set_status(0x80, 0, StateCode.IDLE)
    with pytest.raises(ProtocolError, match="state code"):
        rig.link.set_status(0, 0, 0x42)
    with pytest.raises(ProtocolError, match="0x150"):
        rig.link.set_power_state(7)


def test_power_off_request_reported_once_until_acknowledged(rig: Rig) -> None:
    calls: list[int] = []
    rig.link.on_power_off_request = lambda: calls.append(1)
    for _ in range(3):
        rig.board.send(Power(PowerState.RUNNING, PowerRequest.POWER_OFF).encode())
        rig.step(25)
    assert rig.link.power_off_requested and calls == [1]
    rig.link.acknowledge_power_off()
    assert not rig.link.power_off_requested
    rig.step(1)
    assert Power.decode(rig.sent(CanId.POWER)[-1][1]).state is PowerState.POWER_OFF_ACK
    rig.board.send(Power(PowerState.RUNNING, PowerRequest.POWER_OFF).encode())  # late repeat
    rig.step(2)
    assert calls == [1]


def test_normal_power_frames_are_not_requests(rig: Rig) -> None:
    rig.board.send(Power(PowerState.RUNNING, PowerRequest.NORMAL).encode())
    rig.step(2)
    assert not rig.link.power_off_requested


@pytest.mark.parametrize(("ip", "answer"), [("192.168.1.7", "192.168.1.7"), (None, "0.0.0.0"),
                                            ("127.0.0.1", "0.0.0.0"), ("not an ip", "0.0.0.0")])
def test_ip_request_answered(rig: Rig, ip: str | None, answer: str) -> None:
    rig.network.ip = ip
    rig.board.send(IpRequest().encode())
    rig.step(1)
    answers = [IpAddress.decode(m) for _, m in rig.sent(CanId.IP_ADDRESS)]
    assert [str(a.address) for a in answers] == [answer]


def test_ir_frames_become_cliff_readings(rig: Rig) -> None:
    rig.board.send(IrFront(4.5, 12.0).encode())
    rig.step(1)
    assert rig.link.latest_cliff() is None, "needs both front and rear"
    rig.board.send(IrRear(IR_OUT_OF_RANGE_CM).encode())
    rig.step(1)
    cliff = rig.link.latest_cliff()
    assert cliff is not None
    assert cliff.front_left_m == pytest.approx(0.045) and cliff.front_right_m == pytest.approx(0.12)
    assert math.isinf(cliff.rear_m)
    assert cliff.t == 0.0, "stamped with the older frame's arrival"


def test_ir_unit_conversion_round_trip() -> None:
    for m in (0.0, 0.04, 0.3, 1.5):
        assert ir_cm_to_m(ir_m_to_cm(m)) == pytest.approx(m)
    for bad in (math.inf, math.nan, -0.1, 50.0):
        assert math.isinf(ir_cm_to_m(ir_m_to_cm(bad)))


def send_credentials(rig: Rig, ssid: str, password: str, *, drop: tuple[int, int] | None = None) -> None:
    frames = encode_text(SSID, ssid) + encode_text(PASSWORD, password)
    for i, frame in enumerate(frames):
        if drop is not None and (frame.arbitration_id, i) == drop:
            continue
        rig.board.send(frame)


def test_wifi_credentials_applied(rig: Rig) -> None:
    results: list[WifiResult] = []
    rig.link.on_wifi_result = results.append
    send_credentials(rig, "Home network", "s3cret-passphrase")
    rig.step(1)
    assert rig.network.applied == [AppliedNetwork("Home network", "s3cret-passphrase", ok=True)]
    assert results[-1].ok and results[-1].ssid == "Home network"


def test_wifi_password_without_ssid_refused(rig: Rig) -> None:
    for frame in encode_text(PASSWORD, "s3cret-passphrase"):
        rig.board.send(frame)
    rig.step(1)
    assert rig.network.applied == []
    assert "without a complete SSID" in (rig.link.wifi_results[-1].error or "")


def test_wifi_gap_refused(rig: Rig) -> None:
    send_credentials(rig, "A rather long network", "s3cret-passphrase", drop=(CanId.WIFI_SSID, 1))
    rig.step(1)
    assert rig.network.applied == []
    assert not rig.link.wifi_results[-1].ok


def test_wifi_ssid_alone_expires(rig: Rig) -> None:
    for frame in encode_text(SSID, "Lonely"):
        rig.board.send(frame)
    rig.step(int(2.5 / DT))
    assert rig.network.applied == []
    assert "no password" in (rig.link.wifi_results[-1].error or "")


def test_wifi_backend_failure_reported(rig: Rig) -> None:
    rig.network.fail_with = "no network with SSID 'Home' found"
    send_credentials(rig, "Home", "s3cret-passphrase")
    rig.step(1)
    result = rig.link.wifi_results[-1]
    assert not result.ok and "no network" in (result.error or "")


def test_wifi_applied_off_the_loop_with_an_executor() -> None:
    release = threading.Event()

    class SlowNetwork(RecordingNetworkBackend):
        def connect(self, ssid: str, password: str) -> None:
            release.wait(5)
            super().connect(ssid, password)

    with ThreadPoolExecutor(max_workers=1) as pool:
        rig = Rig(executor=pool)
        rig.network = rig.link.network = SlowNetwork()
        try:
            send_credentials(rig, "Home", "s3cret-passphrase")
            rig.step(5)  # ticks go on while nmcli would be working
            assert not rig.link.wifi_results
            release.set()
            for _ in range(200):
                rig.step(1)
                if rig.link.wifi_results:
                    break
                threading.Event().wait(0.005)  # let the worker thread finish (real thread, real time)
            assert rig.link.wifi_results and rig.link.wifi_results[-1].ok
        finally:
            rig.close()


def test_backend_raising_unexpected_exception_is_reported_not_raised(rig: Rig) -> None:
    class Broken(RecordingNetworkBackend):
        def connect(self, ssid: str, password: str) -> None:
            raise RuntimeError("boom")

    rig.link.network = Broken()
    send_credentials(rig, "Home", "s3cret-passphrase")
    rig.step(1)
    assert "RuntimeError: boom" in (rig.link.wifi_results[-1].error or "")


def test_foreign_and_motor_frames_ignored(rig: Rig) -> None:
    rig.board.send(can.Message(arbitration_id=0x141, data=bytes(8), is_extended_id=False))
    rig.board.send(can.Message(arbitration_id=0x123, data=b"\x01", is_extended_id=False))
    rig.step(1)
    assert rig.link.frames_in == 0 and rig.link.bad_frames == 0


def test_bad_timing_parameters_refused() -> None:
    bus = can.Bus(interface="virtual", channel=unique_channel("link-test"))
    try:
        with pytest.raises(ProtocolError, match="heartbeat_timeout_s"):
            SecondaryLink(bus, RecordingNetworkBackend(), heartbeat_timeout_s=0.0)
    finally:
        bus.shutdown()


def test_recording_backend_rejects_bad_ip() -> None:
    with pytest.raises(ValueError):
        RecordingNetworkBackend(ip="300.1.1.1")
    with pytest.raises(HardwareError, match="wrong"):
        RecordingNetworkBackend(fail_with="wrong").connect("a", "b" * 8)
