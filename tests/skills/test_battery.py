"""The battery estimator (issue 27): the 7-cell Li-ion curve, sag compensation, the filter, and bad readings
(NaN, 0, impossible values and jumps) rejected, not used."""

from __future__ import annotations

import math

import pytest

from atemr.errors import ConfigError
from atemr.skills.battery import BatteryEstimator, BatteryParams
from atemr.typed import Source, merge_into


def test_the_default_pack_is_the_thesis_seven_cell_li_ion() -> None:
    p = BatteryParams()
    assert p.voltage_at(100) == pytest.approx(29.4) and p.percent_at(29.4) == 100.0
    assert p.percent_at(21.0) == 0.0 and p.percent_at(35.0) == 100.0
    for percent in (3.0, 10.0, 20.0, 47.5, 88.0):
        assert p.percent_at(p.voltage_at(percent)) == pytest.approx(percent)


def test_bad_readings_are_rejected_and_the_estimate_kept() -> None:
    est = BatteryEstimator(BatteryParams(filter_s=0.0))
    assert est.update(0.0, 26.0) is None
    kept = est.latest
    reasons = [est.update(0.1, math.nan), est.update(0.2, 0.0), est.update(0.3, -3.0), est.update(0.4, 400.0),
               est.update(0.5, 20.0), est.update(0.6, 26.0, [(math.inf, 1.0)])]
    assert all(reasons) and est.rejected == 6 and est.latest == kept
    assert "not a number" in reasons[0] and "not a battery's" in reasons[1]
    assert "outside what a 7-cell pack can read" in reasons[3]
    assert "20.00 V jumps -5.97 V from 26.09 V" in reasons[4]  # the sag of the 15 W base load added back
    assert est.update(0.7, 25.9) is None and est.latest is not None and est.latest.voltage_v == 25.9


def test_a_new_level_that_persists_is_believed() -> None:
    est = BatteryEstimator(BatteryParams(filter_s=0.0, confirm_readings=3))
    est.update(0.0, 23.0)
    assert est.update(1.0, 29.0) and est.update(2.0, 29.1)  # a fresh pack swapped in: two readings doubted
    assert est.update(3.0, 29.05) is None and est.latest is not None and est.latest.open_circuit_v > 29.0


def test_sag_under_load_is_compensated_and_the_reading_filtered() -> None:
    p = BatteryParams(sag_ohm=0.2, filter_s=2.0)
    est = BatteryEstimator(p)
    ocv = p.voltage_at(60.0)

    def terminal(motors: list[tuple[float, float]]) -> float:  # v = ocv - R * P / v, the pack under a load P
        power = p.base_load_w + p.motor_power_w(motors)
        return (ocv + math.sqrt(ocv * ocv - 4 * p.sag_ohm * power)) / 2

    est.update(0.0, terminal([]))
    hard = [(8.0, 15.0), (8.0, 15.0)]  # both motors accelerating hard: about 8 A from the pack
    sagged = terminal(hard)
    assert ocv - sagged > 1.5
    for i in range(1, 50):
        assert est.update(i * 0.1, sagged, hard) is None
    assert est.latest is not None and est.latest.percent == pytest.approx(60.0, abs=2.0)
    naive = BatteryEstimator(BatteryParams(sag_ohm=0.0, filter_s=2.0))
    naive.update(0.0, ocv)
    for i in range(1, 50):
        naive.update(i * 0.1, sagged, hard)
    assert naive.latest is not None and naive.latest.percent < 40.0  # what it would read without compensation
    one = BatteryEstimator(p)
    one.update(0.0, ocv)
    one.update(0.1, ocv - 1.0)  # one low reading moves the filtered value only by its share
    assert one.latest is not None and ocv - one.latest.open_circuit_v < 0.1


@pytest.mark.parametrize(("layer", "words"), [
    ({"curve": [[3.0, 0], [2.9, 100]]}, "must rise"),
    ({"curve": [[3.0, 0]]}, "at least two points"),
    ({"warn_percent": 5, "critical_percent": 10}, "ordered"),
    ({"cells": 0}, "at least 1"),
    ({"at_return": "wait"}, "battery.at_return: expected one of 'cancel', 'finish', got 'wait'"),
])
def test_bad_battery_settings_are_refused(layer: dict, words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        merge_into(BatteryParams(), layer, Source("file", "robot.yaml"), prefix="battery")


def test_the_status_carries_the_limits_and_names_the_level() -> None:
    params = BatteryParams(warn_percent=30.0, return_percent=15.0, critical_percent=8.0, at_return="finish")
    levels = []
    for percent in (50.0, 29.0, 14.0, 7.0):
        est = BatteryEstimator(params)
        est.update(0.0, params.voltage_at(percent) - params.sag_ohm * params.load_current_a(24.0, []))  # idling
        assert est.latest is not None
        status = params.status(est.latest)
        assert status.at_return == "finish" and (status.warn_percent, status.return_percent) == (30.0, 15.0)
        levels.append((status.level, status.forbids_task()))
    assert [lv for lv, _ in levels] == ["ok", "low", "return", "critical"]
    assert levels[0][1] is None and levels[1][1] is None and levels[2][1] == "battery 14 %"
