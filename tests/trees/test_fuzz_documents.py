"""Random documents never crash the mission or agent parsers: they are valid or a ConfigError, nothing else."""

from __future__ import annotations

import contextlib
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from atemr.errors import ConfigError
from atemr.fsm.spec import parse_agent
from atemr.trees.builder import parse_node
from atemr.trees.missions import STEP_KINDS, parse_mission
from atemr.typed import Source

KEYS = st.sampled_from([*STEP_KINDS, "name", "steps", "mission", "type", "children", "child", "params",
                        "x_m", "y_m", "yaw_rad", "duration_s", "waypoints", "loops", "timeout_s", "retries",
                        "label", "angle_rad", "home", "states", "transitions", "initial", "trigger", "source",
                        "dest", "Sequence", "Wait", "memory", "policy"])
SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True),
                    st.sampled_from(["", "Wait", "Sequence", "IDLE", "STARTUP", "x", "go_to", "*"]))
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                        st.dictionaries(KEYS, inner, max_size=4)), max_leaves=25)


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(KEYS, VALUES, max_size=5))
def test_random_missions_are_valid_or_config_errors(body: dict[str, Any]) -> None:
    for document in ({"mission": body}, body):
        with contextlib.suppress(ConfigError):
            parse_mission(document, "fuzz.yaml")


@settings(max_examples=150, deadline=None)
@given(VALUES)
def test_random_tree_nodes_are_valid_or_config_errors(node: Any) -> None:
    with contextlib.suppress(ConfigError):
        parse_node(node, Source("file", "fuzz.yaml"), "tree")


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(KEYS, VALUES, max_size=5))
def test_random_agent_documents_are_valid_or_config_errors(document: dict[str, Any]) -> None:
    with contextlib.suppress(ConfigError):
        parse_agent(document, "fuzz.yaml")


@settings(max_examples=200, deadline=None)
@given(st.lists(st.dictionaries(KEYS, VALUES, min_size=1, max_size=3), min_size=1, max_size=4),
       st.one_of(st.none(), st.dictionaries(KEYS, VALUES, max_size=3)))
def test_random_steps_are_valid_or_config_errors(steps: list[dict[str, Any]], home: Any) -> None:
    body: dict[str, Any] = {"name": "fuzz", "steps": steps}
    if home is not None:
        body["home"] = home
    try:
        mission = parse_mission({"mission": body}, "fuzz.yaml")
    except ConfigError:
        return
    assert len(mission.steps) == len(steps)
