"""The pure RMD-L-7015 model: dynamics, encoder, heating, error flags, unplugging; deterministic."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from atemr.errors import HardwareError
from atemr.io.motors.model import ENCODER_COUNTS, MotorMode, RmdMotorModel, RmdMotorParams
from atemr.io.motors.rmd_codec import MotorErrorFlags


def run(model: RmdMotorModel, seconds: float, dt: float = 0.01) -> None:
    for _ in range(round(seconds / dt)):
        model.step(dt)


def test_first_order_step_response() -> None:
    model = RmdMotorModel(RmdMotorParams(time_constant_s=0.1))
    model.set_speed(10.0)
    model.step(0.1)
    assert model.speed_radps == pytest.approx(10.0 * (1 - math.exp(-1)))
    run(model, 1.0)
    assert model.speed_radps == pytest.approx(10.0, abs=1e-3)


@given(st.floats(-50, 50), st.integers(1, 200))
def test_exact_for_any_step_size(target: float, n: int) -> None:
    a, b = RmdMotorModel(), RmdMotorModel()
    a.set_speed(target)
    b.set_speed(target)
    a.step(1.0)
    for _ in range(n):
        b.step(1.0 / n)
    assert a.speed_radps == pytest.approx(b.speed_radps, abs=1e-9)
    assert a.position_rad == pytest.approx(b.position_rad, abs=1e-9)


def test_encoder_counts_one_revolution_per_two_pi() -> None:
    model = RmdMotorModel(RmdMotorParams(time_constant_s=0.01))
    model.set_speed(math.pi)  # half a turn per second
    run(model, 10.0)
    # first-order lag: the shaft is behind the ideal angle by target·tau
    assert model.position_rad == pytest.approx(math.pi * (10.0 - 0.01), rel=1e-6)
    expected = math.floor(model.position_rad / (2 * math.pi) * ENCODER_COUNTS) % ENCODER_COUNTS
    assert model.encoder == expected
    assert 0 <= model.encoder < ENCODER_COUNTS


def test_speed_is_clamped_and_must_be_finite() -> None:
    model = RmdMotorModel(RmdMotorParams(max_speed_radps=20.0))
    model.set_speed(100.0)
    assert model.command_radps == 20.0
    with pytest.raises(HardwareError):
        model.set_speed(float("nan"))
    with pytest.raises(HardwareError):
        model.step(-1.0)


def test_stop_run_and_off() -> None:
    model = RmdMotorModel()
    model.set_speed(5.0)
    run(model, 1.0)
    model.stop()
    assert model.mode is MotorMode.STOPPED and model.target_radps == 0.0
    run(model, 1.0)
    assert abs(model.speed_radps) < 1e-3
    model.run()
    assert model.target_radps == 5.0
    model.off()
    assert model.command_radps == 0.0 and model.mode is MotorMode.OFF
    run(model, 0.5)
    assert model.current_a == 0.0  # output disabled: coasting draws nothing


def test_temperature_rises_with_current_and_latches_over_temperature() -> None:
    params = RmdMotorParams(heating_c_per_a2s=5.0, over_temperature_c=60.0, damping_a_per_radps=0.5)
    model = RmdMotorModel(params)
    model.set_speed(10.0)  # 5 A steady → +125 °C/s
    run(model, 0.05)
    assert model.temperature_c > params.ambient_c
    run(model, 1.0)
    assert MotorErrorFlags.OVER_TEMPERATURE in model.error_flags
    assert not model.output_enabled and model.target_radps == 0.0
    assert model.clear_errors() & MotorErrorFlags.OVER_TEMPERATURE  # still hot: the flag stays


def test_idle_motor_stays_at_ambient() -> None:
    model = RmdMotorModel()
    run(model, 5.0)
    assert model.temperature_c == pytest.approx(25.0)
    assert model.error_flags == MotorErrorFlags.NONE


def test_injected_errors_latch_until_cleared() -> None:
    model = RmdMotorModel()
    model.set_speed(3.0)
    model.inject_error(MotorErrorFlags.UNDER_VOLTAGE)
    assert model.error_flags == MotorErrorFlags.UNDER_VOLTAGE
    assert model.target_radps == 0.0
    model.clear_injected()
    assert model.error_flags == MotorErrorFlags.UNDER_VOLTAGE  # latched
    assert model.clear_errors() == MotorErrorFlags.NONE
    assert model.target_radps == 3.0


def test_low_supply_voltage_sets_under_voltage() -> None:
    model = RmdMotorModel()
    model.voltage_v = 15.0
    assert MotorErrorFlags.UNDER_VOLTAGE in model.error_flags


def test_unplugged_motor_has_no_output() -> None:
    model = RmdMotorModel()
    model.set_speed(4.0)
    run(model, 1.0)
    model.unplug()
    assert not model.output_enabled and model.target_radps == 0.0
    run(model, 5.0)
    assert abs(model.speed_radps) < 0.1
    model.plug()
    assert model.plugged and model.command_radps == 0.0


def test_deterministic() -> None:
    def trace() -> list[tuple[float, int, float]]:
        model = RmdMotorModel(initial_angle_rad=0.3)
        out = []
        for k in range(300):
            model.set_speed(math.sin(k / 30) * 10)
            model.step(0.013)
            out.append((model.speed_radps, model.encoder, model.temperature_c))
        return out

    assert trace() == trace()


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(HardwareError, match="time_constant_s"):
        RmdMotorParams(time_constant_s=0.0)


def test_clear_errors_only_some_and_reset() -> None:
    """V4.2 motors clear level-2 errors by themselves (`clear_errors(only=...)`) and the rest on a system reset."""
    model = RmdMotorModel()
    model.inject_error(MotorErrorFlags.MOTOR_STALL | MotorErrorFlags.OVER_TEMPERATURE)
    model.set_speed(3.0)
    model.clear_injected()
    assert model.clear_errors(only=MotorErrorFlags.OVER_TEMPERATURE) == MotorErrorFlags.MOTOR_STALL
    model.voltage_v = 10.0
    model.reset()  # restarts with its command cleared; an error whose cause is still there stays
    assert model.error_flags == MotorErrorFlags.UNDER_VOLTAGE and model.command_radps == 0.0
    model.voltage_v = 24.0
    model.reset()
    assert model.error_flags == MotorErrorFlags.NONE and model.output_enabled
