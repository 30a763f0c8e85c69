"""Command-line start-up: the CPU time of ``atemr --help`` and of one command's start-up (``atemr sim --help``:
its parser is built, nothing runs) in a fresh interpreter, against the 0.3 s a start-up may take (issue 22), with
a bare ``python -c pass`` beside them. CPU time (user + system) of the child processes, median of interleaved
trials, so a busy machine does not count.

Run: ``.venv/bin/python benchmarks/bench_cli.py`` (or ``atemr bench cli``).
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: The most a start-up may take.
LIMIT_S = 0.3


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run(quick: bool = False) -> list[dict[str, Any]]:
    """One row per command line, ours against the limit (ratio = limit / ours)."""
    cases = {"atemr --help": ["-m", "atemr", "--help"], "atemr sim --help (a command's start-up)":
             ["-m", "atemr", "sim", "--help"], "python -c pass (the interpreter alone)": ["-c", "pass"]}
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    times: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(5 if quick else 15):
        for name, argv in cases.items():
            before = _children_cpu_s()
            subprocess.run([sys.executable, *argv], cwd=ROOT, env=env, stdout=subprocess.DEVNULL, check=True)
            times[name].append(_children_cpu_s() - before)
    rows = []
    for name, samples in times.items():
        ours = statistics.median(samples)
        rows.append({"what": f"start-up CPU time, {name}, vs the {LIMIT_S} s limit", "ours": ours,
                     "baseline": LIMIT_S, "ratio": LIMIT_S / ours, "goal": None if name.startswith("python") else 1.0,
                     "unit": "s"})
    return rows


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        print(f"{row['what']}: {row['ours'] * 1000:.0f} ms ({row['ratio']:.1f}x under the limit)")
