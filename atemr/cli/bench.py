"""``atemr bench``: run the benchmarks of a source checkout (``benchmarks/`` beside the package)."""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

from atemr.errors import AtemrError

HARNESS = Path(__file__).resolve().parents[2] / "benchmarks" / "harness.py"


class BenchCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("topics", nargs="*", help="only these benchmarks (e.g. can fuzzy)")
        parser.add_argument("--quick", action="store_true", help="fewer repetitions (a smoke run)")
        parser.add_argument("--json", action="store_true", help="print JSON rows instead of a table")

    def run(self, args: argparse.Namespace) -> int:
        if not HARNESS.is_file():
            raise AtemrError(f"the benchmarks live in a source checkout; {HARNESS} is not there")
        spec = importlib.util.spec_from_file_location("atemr_benchmarks_harness", HARNESS)
        assert spec is not None and spec.loader is not None
        harness = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(harness)
        argv = [*args.topics, *(["--quick"] if args.quick else []), *(["--json"] if args.json else [])]
        return int(harness.main(argv))
