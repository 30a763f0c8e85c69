"""benchmarks/README.md is generated from benchmarks/results.json, so a hand edit (or a stale page) fails here."""

from __future__ import annotations

import importlib.util
import json
from datetime import UTC, datetime
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


def load_report() -> ModuleType:
    spec = importlib.util.spec_from_file_location("report_under_test", ROOT / "benchmarks" / "report.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_page_is_what_the_stored_results_make() -> None:
    report = load_report()
    stored = json.loads((ROOT / "benchmarks" / "results.json").read_text(encoding="utf-8"))
    page = (ROOT / "benchmarks" / "README.md").read_text(encoding="utf-8")
    assert page == report.render(stored), "regenerate it: python benchmarks/report.py"


def test_the_page_says_where_its_figures_came_from_and_shows_every_row() -> None:
    report = load_report()
    rows = [{"benchmark": "can", "what": "decode vs cantools", "ours": 2000.0, "baseline": 1000.0, "ratio": 2.0,
             "goal": 1.0, "unit": "frames/s"},
            {"benchmark": "sim", "what": "FAILED: boom", "ours": None, "baseline": None, "ratio": None, "goal": None,
             "unit": ""}]
    stored = report.results(rows, command="atemr bench can sim --json", date=datetime(2026, 11, 25, 18, 5, tzinfo=UTC),
                            note="under load")
    page = report.render(stored)
    assert "- **Command:** `atemr bench can sim --json`" in page
    assert "- **Date:** 2026-11-25 18:05 UTC" in page
    assert f"- **Machine:** {report.machine()}" in page and "cores" in report.machine()
    assert "- **Note:** under load" in page
    assert "| can | decode vs cantools | 2,000 | 1,000 | frames/s | 2× | ≥ 1× | yes |" in page
    assert "| sim | FAILED: boom | - | - |  | - | - | - |" in page
    assert json.loads(json.dumps(stored)) == stored  # what results.json stores survives the round trip
