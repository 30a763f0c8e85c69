"""Runs every ``benchmarks/bench_*.py`` and prints one table: ours, the baseline measured in the same
run, the ratio and the goal. Benchmarks report; they never fail the test suite.

Each benchmark module exposes ``run(quick: bool = False) -> list[dict]`` with rows
``{"what", "ours", "baseline", "ratio", "goal", "unit"}`` (``goal`` is a minimum ratio, or None).

Each module runs in a process of its own (this file with ``--module``), as ``atemr bench <topic>`` would run it
alone: what one benchmark leaves behind (a heap grown and fragmented by hundreds of megabytes of arrays, threads,
caches) must not slow the ones after it. Cold A* on the warehouse map read 0.77x tcod in a run of every benchmark
in one process, and 1.13x alone: its 100 MB of fresh weights a plan paid for the heap the earlier ones left.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

HERE = Path(__file__).resolve().parent


def discover(names: Sequence[str] = ()) -> list[Path]:
    """The benchmark files, optionally only those whose topic (``bench_<topic>.py``) is in ``names``."""
    files = sorted(HERE.glob("bench_*.py"))
    if names:
        wanted = set(names)
        files = [f for f in files if f.stem.removeprefix("bench_") in wanted]
        missing = wanted - {f.stem.removeprefix("bench_") for f in files}
        if missing:
            known = ", ".join(f.stem.removeprefix("bench_") for f in sorted(HERE.glob("bench_*.py")))
            raise SystemExit(f"unknown benchmark(s): {', '.join(sorted(missing))}; known: {known}")
    return files


def _load(path: Path) -> ModuleType:
    """The benchmark module at ``path``, with its folder importable as when it runs as a script (``python
    benchmarks/bench_sim.py``), so benchmarks import the modules beside them (``numpy_baselines``) by name."""
    folder = str(path.resolve().parent)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    spec = importlib.util.spec_from_file_location(f"atemr_bench_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run_all(files: Sequence[Path], *, quick: bool = False, progress: bool = True) -> list[dict[str, Any]]:
    """Run each benchmark module in a process of its own, collecting its rows; a failing benchmark becomes an
    error row (what it printed to stderr goes to ours)."""
    rows: list[dict[str, Any]] = []
    for i, path in enumerate(files, 1):
        topic = path.stem.removeprefix("bench_")
        if progress:
            bar = "#" * i + "." * (len(files) - i)
            print(f"\r[{bar}] {i}/{len(files)} {topic:<20}", end="", file=sys.stderr, flush=True)
        cmd = [sys.executable, str(Path(__file__).resolve()), "--module", str(path), *(["--quick"] if quick else [])]
        done = subprocess.run(cmd, capture_output=True, text=True, check=False, env=_child_env())
        sys.stderr.write(done.stderr)
        try:
            found = json.loads(done.stdout.strip().splitlines()[-1]) if done.stdout.strip() else None
        except json.JSONDecodeError:
            found = None
        if isinstance(found, list):
            rows.extend({"benchmark": topic, **row} for row in found)
        else:
            error = found["error"] if isinstance(found, dict) and "error" in found else \
                f"exit status {done.returncode}, no rows"
            rows.append({"benchmark": topic, "what": f"FAILED: {error}", "ours": None, "baseline": None,
                         "ratio": None, "goal": None, "unit": ""})
    if progress:
        print(file=sys.stderr)
    return rows


def _child_env() -> dict[str, str]:
    """This environment, with the checkout first on the import path (as `atemr bench` from it has it)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(HERE.parent), env.get("PYTHONPATH", "")) if p)
    return env


def _run_module(path: Path, quick: bool) -> int:
    """The child's side of `run_all`: one module's rows, or its error, as the last line of stdout."""
    try:
        rows = list(_load(path).run(quick=quick))
    except Exception as exc:
        traceback.print_exc(file=sys.stderr)
        print(json.dumps({"error": str(exc)}))
        return 1
    print(json.dumps(rows))
    return 0


def _fmt(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:,.3g}" if abs(value) < 1000 else f"{value:,.0f}"
    return str(value)


def table(rows: Sequence[dict[str, Any]]) -> str:
    """A Markdown table of the rows, with a verdict column against each goal."""
    lines = ["| benchmark | what | ours | baseline | unit | ratio | goal | met |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        goal, ratio = r.get("goal"), r.get("ratio")
        met = "-" if goal is None or ratio is None else ("yes" if ratio >= goal else "NO")
        lines.append(
            f"| {r['benchmark']} | {r['what']} | {_fmt(r.get('ours'))} | {_fmt(r.get('baseline'))} | "
            f"{r.get('unit', '')} | {_fmt(ratio)}{'×' if ratio is not None else ''} | "
            f"{'≥ ' + _fmt(goal) + '×' if goal is not None else '-'} | {met} |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="benchmarks/run", description=__doc__)
    parser.add_argument("topics", nargs="*", help="only these benchmarks (e.g. can fuzzy)")
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (a smoke run)")
    parser.add_argument("--json", action="store_true", help="print JSON rows instead of a table")
    parser.add_argument("--module", type=Path, help=argparse.SUPPRESS)  # run_all's child: one module, JSON rows
    args = parser.parse_args(argv)
    if args.module is not None:
        return _run_module(args.module, args.quick)
    rows = run_all(discover(args.topics), quick=args.quick, progress=not args.json)
    print(json.dumps(rows, indent=2) if args.json else table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
