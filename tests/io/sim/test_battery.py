"""The simulated pack (issue 27): it drains with the motors' power and the electronics' load off the dock, and
charging is a time on the dock (``sim.battery_charge_s``: empty to full, whatever the robot draws there)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from atemr.io.sim.battery import DOCK_RADIUS_M, SimBattery
from atemr.msgs import Pose2D
from atemr.skills.battery import BatteryParams


@dataclass
class Motor:
    """A motor model as the pack sees it: a fixed current and speed; the pack sets the voltage it reports."""

    current_a: float = 0.0
    speed_radps: float = 0.0
    voltage_v: float = 0.0


def pack_at(pose: Pose2D, motors: list[Motor], **kwargs: float) -> SimBattery:
    dock = Pose2D(1.0, 1.0)
    return SimBattery(BatteryParams(), motors, pose=lambda: pose, dock=lambda: dock, **kwargs)


def run(pack: SimBattery, start_s: float, end_s: float, dt: float = 0.1) -> None:
    """Tick the pack from ``start_s`` to ``end_s`` of robot time."""
    for i in range(round((end_s - start_s) / dt) + 1):
        pack.tick(start_s + i * dt)


def test_off_the_dock_the_load_drains_the_pack_and_sags_its_voltage() -> None:
    motors = [Motor(4.0, 10.0), Motor(4.0, 10.0)]
    pack = pack_at(Pose2D(3.0, 1.0), motors, capacity_wh=10.0, percent=50.0, base_load_w=15.0)
    load_w = 15.0 + pack.motor_power_w()
    run(pack, 0.0, 60.0)
    assert not pack.charging
    assert pack.percent == pytest.approx(50.0 - 100.0 * load_w * 60.0 / 3600.0 / 10.0)
    assert all(m.voltage_v == pack.terminal_v for m in motors)
    assert pack.terminal_v < pack.params.voltage_at(pack.percent)  # the sag under load


@pytest.mark.parametrize("motor_current_a", [0.0, 6.0])
def test_on_the_dock_a_full_charge_takes_the_configured_time(motor_current_a: float) -> None:
    near = Pose2D(1.0 + DOCK_RADIUS_M * 0.9, 1.0)
    pack = pack_at(near, [Motor(motor_current_a, 5.0)] * 2, capacity_wh=2.0, percent=0.0, charge_s=30.0)
    run(pack, 0.0, 15.0)
    assert pack.charging and pack.percent == pytest.approx(50.0)  # half the time, half the charge, any load
    run(pack, 15.0, 45.0)
    assert pack.percent == 100.0
    assert pack.terminal_v == pytest.approx(pack.params.voltage_at(100.0))  # the charger's voltage limit


def test_just_off_the_dock_it_does_not_charge() -> None:
    pack = pack_at(Pose2D(1.0 + DOCK_RADIUS_M * 1.1, 1.0), [Motor(), Motor()], capacity_wh=2.0, percent=40.0,
                   charge_s=30.0)
    run(pack, 0.0, 5.0)
    assert not pack.charging and pack.percent < 40.0
