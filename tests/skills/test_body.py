"""The robot's volume in the configuration (issue 24): base footprint plus a height profile."""

import pytest

from atemr.config import load_config
from atemr.errors import ConfigError
from atemr.skills.body import KAY, BodyConfig, BodyPart, RobotBody


def test_kay_is_a_base_a_mast_and_a_tablet_about_a_metre_up():
    assert [p.name for p in KAY.parts] == ["base", "mast", "tablet"]
    assert KAY.footprint_radius_m == 0.25
    assert 1.0 < KAY.height_m < 1.3
    base, mast, tablet = KAY.parts
    assert base.top_m == mast.bottom_m  # the mast stands on the base
    assert tablet.bottom_m < mast.top_m < tablet.top_m  # the tablet is held by the mast


def test_which_parts_are_at_a_height():
    assert [p.name for p in KAY.parts_between(0.70, 0.75)] == ["mast"]  # a table top
    assert [p.name for p in KAY.parts_between(0.0, 0.1)] == ["base"]  # a shoe
    assert KAY.parts_between(1.5, 1.6) == ()  # a shelf above the robot


def test_the_configuration_carries_the_profile_and_the_footprint_from_nav():
    cfg = load_config(environ={}, overrides={"nav.robot_radius_m": 0.3, "body.mast_height_m": 1.2})
    body = cfg.robot_body()
    assert body.footprint_radius_m == 0.3
    assert body.parts[1].top_m == 1.2


def test_bad_profiles_are_refused():
    with pytest.raises(ConfigError, match="bottom < top"):
        BodyPart("mast", 0.04, 1.0, 0.5)
    with pytest.raises(ConfigError, match="inside the base's footprint"):
        RobotBody((BodyPart("base", 0.2, 0.0, 0.3), BodyPart("tablet", 0.3, 0.9, 1.1)))
    with pytest.raises(ConfigError, match="inside the base's footprint"):
        BodyConfig(tablet_width_m=0.8).body(0.25)
    with pytest.raises(ConfigError, match=r"body\.mast_radius_m"):
        load_config(environ={}, overrides={"body.mast_radius_m": 0.0})
