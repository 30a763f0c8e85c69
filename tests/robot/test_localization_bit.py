"""CAN 0x153 agent bit 4 (localization) on the whole simulated robot: set while the robot knows where it is,
cleared on the bus when the covariance monitor finds it lost (kidnapped: teleported 2.3 m), set again once it
has relocalized, and the relocalized pose is the true one (thesis 5.4 iii; docs/navigation.md#localization
and docs/can.md#the-inter-core-protocol-0x1500x157)."""

from __future__ import annotations

from collections.abc import Iterator

import can
import pytest

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.domain.status import AgentBits
from atemr.io.can import PrimaryStatus
from atemr.io.can.bus import unique_channel
from atemr.msgs import Pose2D
from atemr.robot import build_robot
from atemr.robot.core import Robot

BOOTED_S = 7.0
#: Across the living room from the start, facing the other way: far beyond the local (1 m) search.
ELSEWHERE = Pose2D(4.0, 3.4, 3.0)


class Listener:
    """What the secondary core hears of 0x153: every status frame with its robot time."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.bus: can.BusABC = robot.open_bus()
        self.frames: list[tuple[float, PrimaryStatus]] = []

    def run(self, until: float) -> None:
        while self.robot.clock.now() < until - 1e-9:
            self.robot.run(until=min(until, self.robot.clock.now() + 0.1))
            while (msg := self.bus.recv(timeout=0)) is not None:
                if msg.arbitration_id == PrimaryStatus.arbitration_id:
                    self.frames.append((self.robot.clock.now(), PrimaryStatus.decode(msg)))

    def localized_bits(self, since: float = 0.0) -> list[tuple[float, bool]]:
        return [(t, bool(s.agent & AgentBits.LOCALIZATION)) for t, s in self.frames if t >= since]


@pytest.fixture
def robot(tmp_path: object) -> Iterator[Robot]:
    config = load_config(environ={}, overrides={
        "data_dir": str(tmp_path), "can.channel": unique_channel("locbit"), "sim.seed": 2,
        "secondary.portal_serve": False, "ui.enabled": False, "sim.camera_hz": 0.0})
    built = build_robot(config, realtime=False, clock=SimClock())
    with built:
        yield built


def test_the_localization_bit_follows_a_kidnap_and_the_relocalization(robot: Robot) -> None:
    listener = Listener(robot)
    listener.run(BOOTED_S)
    localization = robot.parts.localization
    assert robot.components["agent"].state == "IDLE.MANUAL" and localization.localized
    before = listener.localized_bits(since=BOOTED_S - 2.0)
    assert before and all(ok for _, ok in before), "bit 4 set while localized"

    kidnapped_at = robot.clock.now()
    robot.parts.sim.kidnap(ELSEWHERE)
    listener.run(kidnapped_at + 60.0)
    after = listener.localized_bits(since=kidnapped_at)
    lost = [t for t, ok in after if not ok]
    assert lost, "the lost robot cleared bit 4 on the bus"
    assert lost[0] - kidnapped_at < 2.0, f"noticed {lost[0] - kidnapped_at:.2f} s after the kidnap"
    found = [t for t, ok in after if ok and t > lost[0]]
    assert found, "bit 4 set again once relocalized"
    assert all(ok for t, ok in after if t >= found[0]), "and it stays set"
    truth = robot.parts.sim.base.pose
    estimate = localization.map_pose()
    assert estimate is not None and estimate.distance_to(truth) < 0.15, (estimate, truth)
