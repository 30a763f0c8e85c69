"""The ``nav`` configuration section: validated by `atemr.typed`, turned into the navigator's parameters with the
motion pipeline's stop zone."""

from __future__ import annotations

import pytest

from atemr.config import load_config
from atemr.errors import ConfigError
from atemr.skills.nav.config import NavConfig
from atemr.skills.nav.navigator import NavParams
from atemr.skills.ramp import MotionLimits
from atemr.typed import Source, merge_into


def test_defaults_are_the_navigators_defaults() -> None:
    assert NavConfig().nav_params() == NavParams()


def test_values_reach_the_params_and_the_stop_zone_comes_from_motion() -> None:
    cfg = merge_into(NavConfig(), {"xy_tolerance_m": 0.3, "obstacle_padding_m": 0.15, "max_linear_mps": 0.4},
                     Source("argument"))
    p = cfg.nav_params(MotionLimits(stop_distance_m=0.35, slow_distance_m=0.6, brake_latency_s=0.2))
    assert p.xy_tolerance_m == 0.3 and p.costmap.obstacle_padding_m == 0.15 and p.local.max_linear_mps == 0.4
    assert (p.local.stop_distance_m, p.local.brake_latency_s) == (0.35, 0.2)


def test_the_global_planner_is_chosen_by_name() -> None:
    assert NavConfig().nav_params().planner.algorithm == "astar"
    cfg = load_config(None, overrides={"nav.planner": "dijkstra"})
    assert cfg.nav.nav_params().planner.algorithm == "dijkstra"
    with pytest.raises(ConfigError, match=r"nav\.planner"):
        load_config(None, overrides={"nav.planner": "rrt"})


def test_bad_values_name_the_key() -> None:
    with pytest.raises(ConfigError, match="xy_tolerance_m"):
        merge_into(NavConfig(), {"xy_tolerance_m": 5.0}, Source("argument"))
    with pytest.raises(ConfigError, match=r"unknown|tolerance_xy"):
        merge_into(NavConfig(), {"tolerance_xy": 0.2}, Source("argument"))
    with pytest.raises(ConfigError, match="nav"):
        load_config(None, overrides={"nav.timeout_s": -1.0})
