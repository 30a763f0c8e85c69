"""Fixtures for the localization tests: the studio map and one seeded simulated drive, shared per session."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

from atemr.domain.maps import OccupancyMap
from atemr.io.sim.maps import load_map

ROOT = Path(__file__).resolve().parents[3]


def load_simdrive() -> ModuleType:
    """The `simdrive` helper module beside this file (tests run in importlib mode: no package imports)."""
    if "atemr_test_simdrive" in sys.modules:
        return sys.modules["atemr_test_simdrive"]
    spec = importlib.util.spec_from_file_location("atemr_test_simdrive", Path(__file__).with_name("simdrive.py"))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["atemr_test_simdrive"] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def studio_map() -> OccupancyMap:
    return load_map(ROOT / "atemr" / "worlds" / "studio" / "studio.yaml")


@pytest.fixture(scope="session")
def living_room_drive():  # type: ignore[no-untyped-def]
    """One lap round the living room (seed 3), about 27 simulated seconds, 10 Hz scans."""
    return load_simdrive().drive(seed=3)


@pytest.fixture(scope="session")
def simdrive() -> ModuleType:
    """The drive-and-record helper module (for tests that need their own drive)."""
    return load_simdrive()
