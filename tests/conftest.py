"""Shared fixtures: paths to the project and ../shared, a clean py_trees blackboard for every test, and
the agent's document and fake ports for the agent tests."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from atemr.fsm.spec import AgentSpec, load_agent
from atemr.trees.context import clear_blackboard
from atemr.trees.fakes import RecordingLink, RecordingPort

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


@pytest.fixture(scope="session")
def agent_spec() -> AgentSpec:
    return load_agent(AGENT_YAML)


@pytest.fixture
def port() -> RecordingPort:
    return RecordingPort()


@pytest.fixture
def link() -> RecordingLink:
    return RecordingLink()
