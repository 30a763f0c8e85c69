import math

import pytest

from atemr.errors import ConfigError
from atemr.msgs import ZERO_TWIST, Twist
from atemr.skills.twist_mux import JOYSTICK, NAVIGATION, REACTIVE, SAFETY_STOP, MuxInput, TwistMux

JOY = Twist(0.3, 0.1)
NAV = Twist(0.5, 0.0)
REA = Twist(0.1, -0.5)


def test_priority_order_and_admissibility():
    mux = TwistMux()
    mux.publish(NAVIGATION, NAV, 0.0)
    assert mux.select(0.1).source == NAVIGATION
    mux.publish(JOYSTICK, JOY, 0.0)
    assert mux.select(0.1).twist == JOY
    mux.publish(REACTIVE, REA, 0.05)
    assert mux.select(0.1).source == REACTIVE
    # AUTO mode without awareness: only navigation is admissible
    assert mux.select(0.1, admissible={NAVIGATION}).twist == NAV
    assert mux.select(0.1, admissible=set()).source is None


def test_expired_inputs_are_absent_and_nothing_fresh_is_zero():
    mux = TwistMux()
    mux.publish(JOYSTICK, JOY, 1.0)
    mux.publish(NAVIGATION, NAV, 1.2)
    assert mux.select(1.49).source == JOYSTICK
    r = mux.select(1.5)  # exactly 0.5 s old: already absent, navigation takes over
    assert r.source == NAVIGATION
    r = mux.select(1.7)
    assert r.twist == ZERO_TWIST and r.source is None and not r.fresh


def test_safety_lock_outranks_everything_until_released():
    mux = TwistMux()
    mux.publish(REACTIVE, REA, 0.0)
    mux.set_lock(SAFETY_STOP, True)
    r = mux.select(0.1)
    assert r.twist == ZERO_TWIST and r.source == SAFETY_STOP and r.locked and r.fresh
    assert mux.select(100.0).source == SAFETY_STOP  # locks never expire
    mux.set_lock(SAFETY_STOP, False)
    assert mux.select(0.1).source == REACTIVE


def test_a_low_priority_lock_only_silences_inputs_below_it():
    mux = TwistMux(locks={"pause_nav": 15})
    mux.publish(NAVIGATION, NAV, 0.0)
    mux.set_lock("pause_nav", True)
    assert mux.select(0.1).source == "pause_nav"
    mux.publish(JOYSTICK, JOY, 0.0)
    assert mux.select(0.1).source == JOYSTICK


def test_non_finite_commands_are_dropped_and_clear_forgets():
    mux = TwistMux()
    mux.publish(JOYSTICK, JOY, 0.0)
    mux.publish(JOYSTICK, Twist(math.nan, 0.0), 0.1)
    assert mux.select(0.2).twist == JOY
    assert mux.is_fresh(JOYSTICK, 0.2) and not mux.is_fresh(JOYSTICK, 0.6)
    mux.set_lock(SAFETY_STOP, True)
    assert mux.fresh_command(JOYSTICK, 0.2) == JOY and mux.fresh_command(NAVIGATION, 0.2) is None
    mux.set_lock(SAFETY_STOP, False)
    mux.clear(JOYSTICK)
    assert mux.select(0.2).source is None


def test_configuration_errors():
    with pytest.raises(ConfigError, match="unknown input 'joy'"):
        TwistMux().publish("joy", JOY, 0.0)
    with pytest.raises(ConfigError, match="unknown lock"):
        TwistMux().set_lock("estop", True)
    with pytest.raises(ConfigError, match="unique"):
        TwistMux([MuxInput("a", 1), MuxInput("a", 2)])
    with pytest.raises(ConfigError, match="positive timeout"):
        TwistMux([MuxInput("a", 1, 0.0)])
