"""CAN 0x153 agent bit 4 (localization) on the whole simulated robot: the one confidence number, as the
secondary core hears it. Set while the robot knows where it is; a kidnap is noticed, and where the scan cannot
tell two places apart (the twin rooms, point-symmetric) the robot does not pick one: bit 4 is cleared on the bus
and stays cleared, the candidates are both rooms, until the operator sets the pose (thesis 5.4 iii; issue 21;
docs/navigation.md#localization and docs/can.md#the-inter-core-protocol-0x1500x157).
"""

from __future__ import annotations

import math
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
#: In the east room; its twin is (8.15 - x, 3.5 - y, yaw + π) in the west room, where the robot starts.
ELSEWHERE = Pose2D(6.2, 1.2, 1.0)


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
        "data_dir": str(tmp_path), "can.channel": unique_channel("locbit"), "sim.seed": 2, "sim.world": "twin_rooms",
        "secondary.portal_serve": False, "ui.enabled": False, "sim.camera_hz": 0.0})
    built = build_robot(config, realtime=False, clock=SimClock())
    with built:
        yield built


def test_the_localization_bit_is_the_confidence_and_stays_clear_while_ambiguous(robot: Robot) -> None:
    listener = Listener(robot)
    listener.run(BOOTED_S)
    localization = robot.parts.localization
    assert robot.components["agent"].state == "IDLE.MANUAL" and localization.localized
    before = listener.localized_bits(since=BOOTED_S - 2.0)
    assert before and all(ok for _, ok in before), "bit 4 set while localized"
    assert localization.confidence >= localization.min_confidence

    kidnapped_at = robot.clock.now()
    robot.parts.sim.kidnap(ELSEWHERE)
    listener.run(kidnapped_at + 5.0)
    events = localization.drain_events()
    lost = [e for e in events if e.kind == "lost"]
    assert lost and lost[0].t - kidnapped_at < 5.0, events
    after = listener.localized_bits(since=kidnapped_at)
    cleared = [t for t, ok in after if not ok]
    assert cleared and cleared[0] - kidnapped_at < 5.0, "the lost robot cleared bit 4 on the bus"
    assert all(not ok for t, ok in after if t > cleared[0]), "and keeps it clear: two rooms fit, it picks neither"
    assert localization.state == "ambiguous" and localization.confidence < localization.min_confidence
    truth = robot.parts.sim.base.pose
    twin = Pose2D(8.15 - truth.x_m, 3.5 - truth.y_m, truth.yaw_rad + math.pi)
    places = localization.candidates
    assert any(h.pose.distance_to(truth) < 0.15 for h in places) and any(h.pose.distance_to(twin) < 0.15
                                                                         for h in places), places
    assert any(e.kind == "ambiguous" and "2 places explain the scan about equally" in e.detail for e in events)

    localization.set_initial_pose(robot.clock.now(), truth)  # the operator says which room
    set_at = robot.clock.now()
    listener.run(set_at + 1.0)
    assert any(ok for _, ok in listener.localized_bits(since=set_at)), "bit 4 set again once the pose is set"
    estimate = localization.map_pose()
    assert estimate is not None and estimate.distance_to(truth) < 0.1, (estimate, truth)
