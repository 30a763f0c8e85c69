"""Shared fixtures: paths to the project and ../shared, a clean py_trees blackboard for every test, and
the agent's document and fake ports for the agent tests."""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings

from atemr.fsm.spec import AgentSpec, load_agent
from atemr.trees.context import clear_blackboard
from atemr.trees.fakes import RecordingLink, RecordingPort

# Property tests are deterministic like the rest of the suite: the same examples on every run (CI's and a
# newcomer's alike). ATEMR_HYPOTHESIS=explore draws fresh random examples to hunt for new counterexamples.
settings.register_profile("deterministic", derandomize=True, print_blob=True)
settings.register_profile("explore", derandomize=False, print_blob=True)
settings.load_profile("explore" if os.environ.get("ATEMR_HYPOTHESIS") == "explore" else "deterministic")

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
AGENT_YAML = ROOT / "trees" / "agent.yaml"


@pytest.fixture
def shared_dir() -> Path:
    """``../shared`` beside the checkout; tests that need it skip with a clear message when absent."""
    if not SHARED.is_dir():
        pytest.skip(f"../shared is not beside the checkout (looked for {SHARED})")
    return SHARED


@pytest.fixture(autouse=True)
def clean_blackboard() -> Iterator[None]:
    """py_trees keeps the blackboard at class level: every test (any that builds an agent or a robot)
    starts and ends with it empty."""
    clear_blackboard()
    yield
    clear_blackboard()


@pytest.fixture(autouse=True)
def root_logger_restored() -> Iterator[None]:
    """An in-process ``atemr`` ``main()`` configures logging as the command line does: a stderr handler on
    the root logger (this test's captured stream, closed afterwards) and the root level from ``--log-level``.
    Put both back, and the ``transitions`` logger's level, so no later test logs into a closed stream or
    loses its warnings to an ``ERROR`` level left behind (``caplog`` only sees records the level lets by)."""
    root = logging.getLogger()
    transitions = logging.getLogger("transitions")
    handlers, level, transitions_level = list(root.handlers), root.level, transitions.level
    yield
    for handler in list(root.handlers):
        if handler not in handlers and getattr(handler, "_atemr", False):
            root.removeHandler(handler)
    root.setLevel(level)
    transitions.setLevel(transitions_level)


@pytest.fixture(scope="session")
def agent_spec() -> AgentSpec:
    return load_agent(AGENT_YAML)


@pytest.fixture
def port() -> RecordingPort:
    return RecordingPort()


@pytest.fixture
def link() -> RecordingLink:
    return RecordingLink()
