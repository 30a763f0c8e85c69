"""The localization configuration section: validated by `atemr.typed`, turned into the skills' parameters."""

from __future__ import annotations

import math

import pytest

from atemr.errors import ConfigError
from atemr.skills.localization.config import LocalizationConfig
from atemr.typed import Source, merge_into


def test_defaults_build_params() -> None:
    cfg = LocalizationConfig()
    p = cfg.localizer_params()
    assert p.amcl.max_particles == 5000 and p.amcl.max_beams == 60
    assert p.monitor.max_std_yaw_rad == pytest.approx(math.radians(20.0))
    assert cfg.slam_params().resolution_m == 0.05


def test_layer_is_validated() -> None:
    cfg = merge_into(LocalizationConfig(), {"min_particles": 600, "max_std_xy_m": 0.3}, Source("argument"))
    assert cfg.localizer_params().amcl.min_particles == 600 and cfg.localizer_params().monitor.max_std_xy_m == 0.3
    with pytest.raises(ConfigError, match="min_particles"):
        merge_into(LocalizationConfig(), {"min_particles": 1}, Source("argument"))
    with pytest.raises(ConfigError, match=r"unknown|particles_max"):
        merge_into(LocalizationConfig(), {"particles_max": 10}, Source("argument"))
    with pytest.raises(ConfigError, match="min_particles <= max_particles"):
        LocalizationConfig(min_particles=6000).localizer_params()
