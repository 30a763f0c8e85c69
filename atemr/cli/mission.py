"""``atemr mission validate FILE...``: check missions and say whether this build can run them.

A mission is valid when its document is right (kinds, parameters, poses, timeouts). Whether it can run
here is a separate answer: a step whose behaviour this build lacks (a plugin kind, or ``GoToPose`` in a
build without it) is reported with the behaviour it needs; ``--strict`` makes that an error (exit 1).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from atemr.cli.command import commands
from atemr.errors import ConfigError
from atemr.trees.missions import load_mission


class MissionCommand:
    help = "validate mission files (trees/missions/*.yaml)"

    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="mission_action", metavar="ACTION", required=True)
        validate = sub.add_parser("validate", help="check mission files; exit 2 on an error, with file:line:col")
        validate.add_argument("files", type=Path, nargs="+", metavar="FILE")
        validate.add_argument("--json", action="store_true", help="print one JSON report for all files")
        validate.add_argument("--strict", action="store_true",
                              help="exit 1 when a valid mission cannot run in this build (missing behaviours)")

    def run(self, args: argparse.Namespace) -> int:
        reports: list[dict[str, Any]] = []
        worst = 0
        for path in args.files:
            try:
                mission = load_mission(path)
            except ConfigError as exc:
                reports.append({"file": str(path), "valid": False, "error": str(exc), "line": exc.line,
                                "column": exc.column, "path": exc.path})
                worst = 2
                continue
            report = {"valid": True, **mission.report()}
            reports.append(report)
            if not report["runnable"] and args.strict:
                worst = max(worst, 1)
        if args.json:
            print(json.dumps(reports if len(reports) > 1 else reports[0], indent=2))
            return worst
        for report in reports:
            if not report["valid"]:
                print(f"error: {report['error']}", file=sys.stderr)
                continue
            print(f"{report['file']}: OK, mission '{report['name']}', {len(report['steps'])} steps")
            blocked = [s for s in report["steps"] if not s["runnable"]]
            if blocked:
                steps = ", ".join(f"{s['index']} ({s['kind']}, line {s['line']})" for s in blocked)
                print(f"  not runnable in this build: needs {', '.join(report['missing_behaviours'])}; "
                      f"steps {steps}")
        return worst


commands.add("mission", MissionCommand())
