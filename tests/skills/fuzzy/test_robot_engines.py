"""Behaviour of the robot's shipped IDLE and MANUAL engines (scenario tests, not a table match).

Sector distances are metres within the 1.2 m radius of interest (1.2 = nothing there). NEAR is full at
0.4 m and gone at 1.0 m. Sign conventions: linSteer > 0 forward; angular outputs > 0 counter-clockwise.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.errors import ConfigError
from atemr.skills.fuzzy import MANUAL_ENGINE_SPEED_LIMIT_MPS, blend, load_builtin_engine
from atemr.skills.fuzzy.engine import Engine

SECTORS = ("FR", "FL", "LC", "RL", "RR", "RC")
CLEAR = 1.2


@pytest.fixture(scope="module")
def idle() -> Engine:
    return load_builtin_engine("idle")


@pytest.fixture(scope="module")
def manual() -> Engine:
    return load_builtin_engine("manual")


def scene(**near: float) -> dict[str, float]:
    return {s: near.get(s, CLEAR) for s in SECTORS}


def run(engine: Engine, **near: float) -> dict[str, float]:
    return {k: float(v) for k, v in engine.process(scene(**near)).items()}


def test_shapes_of_the_shipped_engines(idle: Engine, manual: Engine) -> None:
    assert idle.type == "Larsen" and len(idle.rules) == 14
    assert idle.input_names == SECTORS and idle.output_names == ("linSteer", "angSteer")
    assert all(b.implication == "AlgebraicProduct" for b in idle.rule_blocks)
    assert manual.type == "Tsukamoto" and len(manual.rules) == 13
    assert manual.input_names == SECTORS and manual.output_names == ("fwdSteer", "revSteer")
    for engine in (idle, manual):
        for var in engine.inputs:
            assert [t.name for t in var.terms] == ["NEAR", "FAR"] and (var.minimum, var.maximum) == (0.0, 1.2)


# ---- IDLE: move away from what approaches, never towards another obstacle ----

def test_idle_obstacle_front_right_backs_off_steering_left(idle: Engine) -> None:
    out = run(idle, FR=0.4)
    assert out["angSteer"] > 0.1 and out["linSteer"] < -0.3


def test_idle_obstacle_front_left_backs_off_steering_right(idle: Engine) -> None:
    out = run(idle, FL=0.4)
    assert out["angSteer"] < -0.1 and out["linSteer"] < -0.3


def test_idle_approach_from_the_rear_drives_forward(idle: Engine) -> None:
    for near in ({"RL": 0.5, "RR": 0.5}, {"RL": 0.4}, {"RR": 0.6}):
        assert run(idle, **near)["linSteer"] > 0.2, near


def test_idle_side_approach_veers_away(idle: Engine) -> None:
    left = run(idle, LC=0.4)
    right = run(idle, RC=0.4)
    assert left["linSteer"] > 0.2 and left["angSteer"] < -0.2
    assert right["linSteer"] > 0.2 and right["angSteer"] > 0.2


def test_idle_keeps_still_when_nothing_approaches_or_when_boxed_in(idle: Engine) -> None:
    for near in ({}, {"FL": 0.3, "FR": 0.3, "RL": 0.3, "RR": 0.3}):
        out = run(idle, **near)
        assert abs(out["linSteer"]) < 1e-9 and abs(out["angSteer"]) < 1e-9, near


def test_idle_the_closer_the_rear_obstacle_the_faster_it_leaves(idle: Engine) -> None:
    d = np.linspace(1.2, 0.3, 40)
    out = idle.process({**scene(), "RL": d, "RR": d})
    assert np.all(np.diff(out["linSteer"]) >= -1e-12)
    assert out["linSteer"][0] == pytest.approx(0.0, abs=1e-9) and out["linSteer"][-1] > 0.5


def test_idle_turns_in_place_when_it_cannot_back_off(idle: Engine) -> None:
    out = run(idle, FR=0.3, RR=0.3)
    assert abs(out["linSteer"]) < 1e-9 and out["angSteer"] > 0.2


def bends_towards(lin: float, ang: float, eps: float = 1e-9) -> set[str]:
    """Sectors a (linear, angular) command moves the base towards (see idle.yaml's header)."""
    towards: set[str] = set()
    if lin > eps:
        towards |= {"FL", "FR"} | ({"FL", "LC"} if ang > eps else set()) | ({"FR", "RC"} if ang < -eps else set())
    if lin < -eps:
        towards |= {"RL", "RR"} | ({"RR", "RC"} if ang > eps else set()) | ({"RL", "LC"} if ang < -eps else set())
    return towards


CRISP = np.array(list(itertools.product([0.3, 1.1], repeat=6)))


def test_idle_never_moves_towards_a_near_sector_in_any_of_the_64_situations(idle: Engine) -> None:
    out = idle.process({s: CRISP[:, i] for i, s in enumerate(SECTORS)})
    moving = 0
    for k, row in enumerate(CRISP):
        near = {s for s, v in zip(SECTORS, row, strict=True) if v < 0.4}
        lin, ang = float(out["linSteer"][k]), float(out["angSteer"][k])
        assert not bends_towards(lin, ang) & near, (sorted(near), lin, ang)
        moving += abs(lin) > 0.1
    assert moving >= 20  # it does move away in many of them, it is not just standing still


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(min_value=0.0, max_value=1.2), min_size=6, max_size=6))
def test_idle_never_translates_towards_a_near_sector(idle: Engine, d: list[float]) -> None:
    out = idle.process(dict(zip(SECTORS, d, strict=True)))
    lin = float(out["linSteer"])
    near = {s for s, v in zip(SECTORS, d, strict=True) if v <= 0.4}
    if lin > 1e-9:
        assert not near & {"FL", "FR"}
    if lin < -1e-9:
        assert not near & {"RL", "RR"}


# ---- MANUAL: steer round what is ahead or behind while the operator drives ----

def test_manual_steers_round_an_obstacle_ahead(manual: Engine) -> None:
    right_front = run(manual, FR=0.6)
    closer = run(manual, FR=0.3)
    assert right_front["fwdSteer"] > 0.1
    assert closer["fwdSteer"] > right_front["fwdSteer"]  # closer → harder ('very NEAR' rule)
    assert run(manual, FL=0.5)["fwdSteer"] < -0.1


def test_manual_steers_round_a_wall_square_ahead_towards_the_clear_side(manual: Engine) -> None:
    # both front sectors near, both sides clear: no front sector is clear, so the engine must pick a side (left)
    # rather than let the two turning rules cancel out and the base run on into the stop zone
    assert run(manual, FL=0.6, FR=0.6)["fwdSteer"] > 0.1
    assert run(manual, FL=0.4, FR=0.4)["fwdSteer"] > run(manual, FL=0.6, FR=0.6)["fwdSteer"]
    # the left side blocked as well (a corner): turn right
    assert run(manual, FL=0.6, FR=0.6, LC=0.5)["fwdSteer"] < -0.1


def test_manual_steers_round_an_obstacle_behind(manual: Engine) -> None:
    # reversing, yaw left (CCW) bends the path to the rear-right: round a rear-left obstacle
    assert run(manual, RL=0.5)["revSteer"] > 0.1
    assert run(manual, RR=0.5)["revSteer"] < -0.1


def test_manual_walls_and_corridors(manual: Engine) -> None:
    left_wall = run(manual, LC=0.4)
    assert left_wall["fwdSteer"] < 0 and left_wall["revSteer"] > 0
    corridor = run(manual, LC=0.4, RC=0.4)
    assert corridor["fwdSteer"] == pytest.approx(0.0, abs=1e-9)
    assert corridor["revSteer"] == pytest.approx(0.0, abs=1e-9)


def test_manual_leaves_the_operator_alone_when_clear(manual: Engine) -> None:
    assert run(manual) == {"fwdSteer": 0.0, "revSteer": 0.0}


#: The MANUAL engine's crisp situations: near (0.3 m) or clear (nothing within the 1.2 m radius of interest; its
#: NEAR term reaches out to 1.2 m, so 1.1 m is still slightly near for it).
CRISP_MANUAL = np.array(list(itertools.product([0.3, 1.2], repeat=6)))


def test_manual_never_steers_towards_a_near_sector_in_any_of_the_64_situations(manual: Engine) -> None:
    out = manual.process({s: CRISP_MANUAL[:, i] for i, s in enumerate(SECTORS)})
    for k, row in enumerate(CRISP_MANUAL):
        near = {s for s, v in zip(SECTORS, row, strict=True) if v < 0.4}
        fwd, rev = float(out["fwdSteer"][k]), float(out["revSteer"][k])
        # driving forward: never towards a near side, nor towards a near front sector while the other is clear
        # (with both front sectors near, a wall square ahead, every turn bends towards one: the clear side decides)
        if fwd > 1e-9:
            assert "LC" not in near and not ("FL" in near and "FR" not in near)
        if fwd < -1e-9:
            assert "RC" not in near and not ("FR" in near and "FL" not in near)
        if rev > 1e-9:
            assert not near & {"RR", "RC"}
        if rev < -1e-9:
            assert not near & {"RL", "LC"}


def test_outputs_stay_in_range_for_random_scenes(idle: Engine, manual: Engine) -> None:
    rng = np.random.default_rng(7)
    d = rng.uniform(0.0, 1.5, size=(5000, 6))
    for engine in (idle, manual):
        out = engine.process({s: d[:, i] for i, s in enumerate(SECTORS)})
        for name, values in out.items():
            assert np.all(np.isfinite(values)) and np.all(np.abs(values) <= 1.0), name


# ---- blend and speed limit ----

def test_speed_limit_constant() -> None:
    assert MANUAL_ENGINE_SPEED_LIMIT_MPS == 0.26


def test_blend() -> None:
    assert float(blend(1.0, -1.0, 1.0)) == 1.0
    assert float(blend(1.0, -1.0, 0.0)) == -1.0
    assert float(blend(0.8, 0.2, 0.25)) == pytest.approx(0.8 * 0.25 + 0.2 * 0.75)
    np.testing.assert_allclose(blend([0.0, 1.0], [1.0, 1.0], 0.5), [0.5, 1.0])


def test_blend_refuses_tau_outside_unit_interval() -> None:
    with pytest.raises(ConfigError, match="tau"):
        blend(1.0, 0.0, 1.5)


def test_invalid_or_empty_input_means_no_motion(idle: Engine, manual: Engine) -> None:
    for engine in (idle, manual):
        out = engine.process({s: np.nan for s in SECTORS})
        assert all(float(v) == 0.0 for v in out.values())  # nothing fires: the outputs' default 0
        empty = engine.process({s: np.zeros(0) for s in SECTORS})
        assert all(v.shape == (0,) for v in empty.values())
