"""``atemr trace show FILE [--json]``: the agent's transitions in a recording, with times and reasons;
``atemr trace convert OLD.atrace NEW.mcap``: a trace recorded before MCAP, as an MCAP recording.

A recording is what the robot writes under ``data_dir/traces`` (or ``atemr mission run --trace FILE``): MCAP,
whose agent topics hold what ``.atrace`` files held (those still open). A damaged or cut file is read up to
the damage: the warning (file and byte offset) goes to stderr and the exit code is 1; a file that is not a
recording at all exits 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from atemr.cli.command import commands, report_and_warn


class TraceCommand:
    help = "read recorded agent traces (data_dir/traces, atemr mission run --trace)"

    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="trace_action", metavar="ACTION", required=True)
        show = sub.add_parser("show", help="print the transitions of a trace with times and reasons")
        show.add_argument("file", type=Path, metavar="FILE")
        show.add_argument("--json", action="store_true", help="print one JSON document")
        convert = sub.add_parser("convert", help="write an old .atrace trace as an MCAP recording")
        convert.add_argument("file", type=Path, metavar="FILE.atrace")
        convert.add_argument("output", type=Path, metavar="OUT.mcap")

    def run(self, args: argparse.Namespace) -> int:
        from atemr.fsm.trace_timeline import TraceTimeline
        from atemr.io.recording.agent_trace import convert_atrace, read_agent_trace

        if args.trace_action == "convert":
            converted = convert_atrace(args.file, args.output)
            print(f"{args.output}: {len(converted.records)} records from {args.file}")
            for warning in converted.warnings:
                print(f"warning: {warning}", file=sys.stderr)
            return 1 if converted.warnings else 0
        contents = read_agent_trace(args.file)
        timeline = TraceTimeline(contents.records, name=str(args.file), warnings=contents.warnings)
        report = {"file": str(args.file), **{k: v for k, v in timeline.summary().items() if k != "name"}}
        return report_and_warn(report, as_json=args.json, printer=print_report, warnings=contents.warnings)


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
