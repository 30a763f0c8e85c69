"""A simulated IMU: yaw rate and linear acceleration in the base frame, with bias and white noise.

Biases are drawn once per run from the injected generator (a real gyro's turn-on bias), then stay
fixed; each sample adds white noise. The accelerometer saturates at its range, so a bump shows as a
clipped spike rather than an impossible value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atemr.errors import ConfigError
from atemr.msgs import ImuSample

STANDARD_GRAVITY = 9.80665


@dataclass(frozen=True)
class ImuParams:
    """Noise model; defaults are those of a consumer MEMS IMU (MPU-6050 class)."""

    gyro_noise_std_radps: float = 0.005
    gyro_bias_std_radps: float = 0.002
    accel_noise_std_mps2: float = 0.05
    accel_bias_std_mps2: float = 0.02
    accel_range_mps2: float = 4 * STANDARD_GRAVITY

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"must be a finite number >= 0, got {value!r}", path=f"imu.{name}")


class Imu:
    """Turns the base's true motion into `ImuSample`s."""

    def __init__(self, params: ImuParams, rng: np.random.Generator) -> None:
        self.params = params
        self.rng = rng
        self.gyro_bias_radps = float(rng.normal(0.0, params.gyro_bias_std_radps)) if params.gyro_bias_std_radps else 0.0
        b = rng.normal(0.0, params.accel_bias_std_mps2, 2) if params.accel_bias_std_mps2 else np.zeros(2)
        self.accel_bias_mps2 = (float(b[0]), float(b[1]))

    def sample(self, t: float, v_mps: float, w_radps: float, accel_mps2: float) -> ImuSample:
        """A reading for body speed ``v``, turn rate ``ω`` and forward acceleration (centripetal ``v ω`` on y)."""
        p = self.params
        n = self.rng.normal(0.0, 1.0, 3)
        lim = p.accel_range_mps2
        ax = accel_mps2 + self.accel_bias_mps2[0] + p.accel_noise_std_mps2 * n[1]
        ay = v_mps * w_radps + self.accel_bias_mps2[1] + p.accel_noise_std_mps2 * n[2]
        return ImuSample(
            t,
            w_radps + self.gyro_bias_radps + p.gyro_noise_std_radps * float(n[0]),
            float(min(lim, max(-lim, ax))),
            float(min(lim, max(-lim, ay))),
        )
