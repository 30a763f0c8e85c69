"""``atemr trace show FILE [--json]``: the transitions of a recorded agent trace, with times and reasons.

A trace is what the robot records under ``data_dir/traces`` (or ``atemr mission run --trace FILE``). A
damaged or cut file is read up to the damage: the warning (file and byte offset) goes to stderr and the exit
code is 1; a file that is not a trace at all exits 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from atemr.cli.command import commands


class TraceCommand:
    help = "read recorded agent traces (data_dir/traces, atemr mission run --trace)"

    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="trace_action", metavar="ACTION", required=True)
        show = sub.add_parser("show", help="print the transitions of a trace with times and reasons")
        show.add_argument("file", type=Path, metavar="FILE")
        show.add_argument("--json", action="store_true", help="print one JSON document")

    def run(self, args: argparse.Namespace) -> int:
        from atemr.fsm.trace_timeline import TraceTimeline
        from atemr.io.trace_file import read_trace

        contents = read_trace(args.file)
        timeline = TraceTimeline(contents.records, name=str(args.file), warnings=contents.warnings)
        report = {"file": str(args.file), **{k: v for k, v in timeline.summary().items() if k != "name"}}
        if args.json:
            print(json.dumps(report, indent=2))
        else:
            print_report(report)
        for warning in contents.warnings:
            print(f"warning: {warning}", file=sys.stderr)
        return 1 if contents.warnings else 0


def print_report(report: dict[str, Any]) -> None:
    meta = ", ".join(f"{k} {v}" for k, v in report["meta"].items() if v is not None)
    print(f"{report['file']}: agent '{report['agent']}', {report['start_t']:.3f}-{report['end_t']:.3f} s, "
          f"{report['records']} records" + (f" ({meta})" if meta else ""))
    for row in report["transitions"]:
        move = f"{row['source'] or '—'} -> {row['dest']}" if row["accepted"] else f"refused in {row['source']}"
        origin = f" [{row['origin']}]" if row.get("origin") else ""
        reason = f": {row['reason']}" if row.get("reason") else ""
        by = f" by {row['decided_by']}" if row.get("decided_by") else ""
        decision = f" ({row['decision']}{by})" if row.get("decision") else ""
        print(f"{row['t']:10.3f}  {row['trigger']:<16} {move}{origin}{decision}{reason}")


commands.add("trace", TraceCommand())
