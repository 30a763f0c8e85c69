"""Shared fixtures: paths to the project and to ../shared, and helpers to skip clearly when absent."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"


@pytest.fixture
def shared_dir() -> Path:
    """``../shared`` beside the checkout; tests that need it skip with a clear message when absent."""
    if not SHARED.is_dir():
        pytest.skip(f"../shared is not beside the checkout (looked for {SHARED})")
    return SHARED
