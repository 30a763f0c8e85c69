import math

import numpy as np
import pytest

from atemr.errors import ConfigError
from atemr.msgs import Twist
from atemr.skills.fuzzy import load_builtin_engine
from atemr.skills.hexpattern import HEX, HEX90, SECTORS, HexSectors
from atemr.skills.reactive import ReactiveEngine, ReactiveParams


def sectors(layout=HEX90, **near):
    """HEX sectors reading 1.2 m (clear) except the given ones."""
    mean = np.array([near.get(s, 1.2) for s in SECTORS])
    return HexSectors(layout, 1.2, mean, mean.copy(), np.ones(6, dtype=np.int64))


@pytest.fixture(scope="module")
def engines():
    return load_builtin_engine("idle"), load_builtin_engine("manual")


@pytest.fixture
def reactive(engines):
    return ReactiveEngine(*engines)


def test_idle_holds_still_when_nothing_approaches(reactive):
    assert reactive.idle_twist(sectors()) == Twist(0.0, 0.0)


@pytest.mark.parametrize(
    ("near", "v_sign", "w_sign"),
    [
        ({"FL": 0.4, "FR": 0.4}, -1, 0),  # from the front: back straight out
        ({"RL": 0.4, "RR": 0.4}, 1, 0),  # from behind: drive straight off
        ({"FR": 0.4}, -1, 1),  # front-right: back off, nose left
        ({"LC": 0.4}, 1, -1),  # left side: move off veering right
        ({"FL": 0.4, "RL": 0.4}, 0, -1),  # front-left and behind: turn in place away
    ],
)
def test_idle_moves_away_from_what_approaches(reactive, near, v_sign, w_sign):
    t = reactive.idle_twist(sectors(**near))
    assert np.sign(round(t.linear_mps, 6)) == v_sign
    assert np.sign(round(t.angular_radps, 6)) == w_sign
    assert abs(t.linear_mps) <= 0.26 and abs(t.angular_radps) <= 1.0


def test_manual_steers_round_what_is_ahead_and_limits_speed(reactive):
    clear = reactive.manual_assist(sectors(), Twist(0.8, 0.3))
    # nothing near: τ = 0, the operator's turn is untouched; speed limited to the engine's 0.26 m/s
    assert clear.tau == 0.0 and clear.twist == Twist(0.26, 0.3)
    right = reactive.manual_assist(sectors(FR=0.4), Twist(0.2, 0.0))
    assert right.tau == pytest.approx(0.8)  # FR fully NEAR
    assert right.engine_radps > 0.5 and right.twist.angular_radps == pytest.approx(0.8 * right.engine_radps)
    left = reactive.manual_assist(sectors(FL=0.4), Twist(0.2, 0.0))
    assert left.twist.angular_radps < -0.4
    # reversing towards something behind-left: yaw left (CCW) so the tail swings right
    back = reactive.manual_assist(sectors(RL=0.4), Twist(-0.2, 0.0))
    assert back.twist.linear_mps == -0.2 and back.twist.angular_radps > 0.4


def test_manual_blend_follows_eq_3_1(reactive):
    s = sectors(FR=0.85)  # NEAR (1.2 → 0.5) membership 0.5 → τ = 0.4
    a = reactive.manual_assist(s, Twist(0.2, -1.0))
    assert a.tau == pytest.approx(0.4)
    assert a.twist.angular_radps == pytest.approx(a.engine_radps * 0.4 + (-1.0) * 0.6)


def test_turning_on_the_spot_is_the_operators(reactive):
    a = reactive.manual_assist(sectors(FR=0.4), Twist(0.0, 0.7))
    assert a.twist == Twist(0.0, 0.7) and a.tau == 0.0


def test_engines_run_once_per_sector_set(engines):
    calls = []

    class Counting:
        def __init__(self, engine):
            self.engine = engine
            self.name, self.inputs = engine.name, engine.inputs
            self.input_names, self.output_names = engine.input_names, engine.output_names

        def process(self, inputs):
            calls.append(self.name)
            return self.engine.process(inputs)

    r = ReactiveEngine(Counting(engines[0]), Counting(engines[1]))
    s = sectors(FR=0.5)
    for _ in range(5):
        r.idle_twist(s)
        r.manual_assist(s, Twist(0.2, 0.0))
    assert calls == ["IDLE", "MANUAL"]
    r.idle_twist(sectors(FR=0.5))
    assert calls == ["IDLE", "MANUAL", "IDLE"]


def test_wrong_layout_and_wrong_engines(reactive, engines):
    with pytest.raises(ConfigError, match="HEX-90"):
        reactive.idle_twist(sectors(HEX))
    with pytest.raises(ConfigError, match="must take the six sectors"):
        ReactiveEngine(engines[1], engines[1])
    with pytest.raises(ConfigError, match="tau_max"):
        ReactiveParams(tau_max=1.5)
    with pytest.raises(ConfigError, match="max_linear_mps"):
        ReactiveParams(max_linear_mps=math.nan)


def test_nearness_with_a_different_near_term_per_sector(engines):
    import dataclasses

    from atemr.skills.fuzzy.terms import Term

    manual = engines[1]
    near = manual.inputs[0].term("NEAR")
    narrower = dataclasses.replace(near, params=(1.0, 0.4))
    assert isinstance(narrower, Term) and near.params == (1.2, 0.5)
    inputs = tuple(
        dataclasses.replace(v, terms=tuple(narrower if t.name == "NEAR" else t for t in v.terms))
        if v.name == "LC" else v
        for v in manual.inputs
    )
    r = ReactiveEngine(engines[0], dataclasses.replace(manual, inputs=inputs))
    # LC at 0.7 m: NEAR by the narrower ramp (1.0 → 0.4) is 0.5; by the shared one (1.2 → 0.5) it would be 5/7
    assert r.nearness(sectors(LC=0.7)) == pytest.approx(0.5)
    assert ReactiveEngine(*engines).nearness(sectors(LC=0.7)) == pytest.approx(5 / 7)
