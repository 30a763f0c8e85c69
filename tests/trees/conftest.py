"""Fixtures for the agent tests: a clean py_trees blackboard, the shipped agent document, fake ports."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from atemr.fsm.spec import AgentSpec, load_agent
from atemr.trees.context import clear_blackboard
from atemr.trees.fakes import RecordingLink, RecordingPort

ROOT = Path(__file__).resolve().parents[2]
AGENT_YAML = ROOT / "trees" / "agent.yaml"


@pytest.fixture(autouse=True)
def clean_blackboard() -> Iterator[None]:
    """py_trees keeps the blackboard at class level: every test starts and ends with it empty."""
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
