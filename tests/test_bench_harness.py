"""The benchmark harness: it runs benchmark modules, reports ratios against goals, and never raises."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def load_harness():
    spec = importlib.util.spec_from_file_location("harness_under_test", ROOT / "benchmarks" / "harness.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_rows_are_collected_and_failures_reported(tmp_path):
    harness = load_harness()
    good = tmp_path / "bench_good.py"
    good.write_text(
        "def run(quick=False):\n"
        "    return [{'what': 'x', 'ours': 200.0, 'baseline': 10.0, 'ratio': 20.0, 'goal': 10, 'unit': 'ops/s'}]\n"
    )
    bad = tmp_path / "bench_bad.py"
    bad.write_text("def run(quick=False):\n    raise RuntimeError('boom')\n")
    rows = harness.run_all([good, bad], quick=True, progress=False)
    assert rows[0]["benchmark"] == "good" and rows[0]["ratio"] == 20.0
    assert rows[1]["what"] == "FAILED: boom"
    text = harness.table(rows)
    assert "| good | x | 200 | 10 | ops/s | 20× | ≥ 10× | yes |" in text
    assert "FAILED: boom" in text


def test_goal_not_met_is_visible():
    harness = load_harness()
    text = harness.table([{"benchmark": "b", "what": "w", "ours": 1.0, "baseline": 2.0, "ratio": 0.5, "goal": 1,
                           "unit": "s"}])
    assert text.endswith("| NO |")


def test_every_shipped_benchmark_has_the_run_contract():
    harness = load_harness()
    for path in harness.discover():
        module = harness._load(path)
        assert callable(getattr(module, "run", None)), f"{path.name} has no run(quick=False)"


def test_each_benchmark_runs_in_a_process_of_its_own(tmp_path):
    """What one benchmark leaves in its process (here a mark on a shared module) is not there for the next, and a
    benchmark that kills its process is a failed row, not a lost run."""
    harness = load_harness()
    first = tmp_path / "bench_first.py"
    first.write_text(
        "import json\n"
        "def run(quick=False):\n"
        "    json.left_behind = True\n"
        "    return [{'what': 'first', 'ours': 1.0, 'baseline': 1.0, 'ratio': 1.0, 'goal': None, 'unit': ''}]\n"
    )
    second = tmp_path / "bench_second.py"
    second.write_text(
        "import json\n"
        "def run(quick=False):\n"
        "    seen = float(getattr(json, 'left_behind', False))\n"
        "    return [{'what': 'second', 'ours': seen, 'baseline': 1.0, 'ratio': seen, 'goal': None, 'unit': ''}]\n"
    )
    dies = tmp_path / "bench_dies.py"
    dies.write_text("import os\ndef run(quick=False):\n    os._exit(3)\n")
    rows = harness.run_all([first, second, dies], quick=True, progress=False)
    assert [r["what"] for r in rows[:2]] == ["first", "second"] and rows[1]["ours"] == 0.0
    assert rows[2]["benchmark"] == "dies" and rows[2]["what"] == "FAILED: exit status 3, no rows"
