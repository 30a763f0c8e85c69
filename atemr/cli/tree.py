"""``atemr tree validate FILE`` and ``atemr tree export FILE --format F [--state S] [--output OUT]``.

FILE is an agent document (``trees/agent.yaml``) or a mission file (its compiled tree is drawn).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from atemr.cli.command import commands

if TYPE_CHECKING:  # only what runs a command imports what it needs: `atemr --help` stays fast
    from atemr.fsm.export import Drawing
    from atemr.fsm.spec import AgentSpec
    from atemr.trees.missions import Mission


def load_document(path: Path) -> AgentSpec | Mission:
    """An agent document or a mission, told apart by the top-level ``mission`` key."""
    from atemr.fsm.spec import parse_agent
    from atemr.trees.missions import parse_mission
    from atemr.yamlsafe import load_yaml

    document: Any = load_yaml(path)
    if isinstance(document, dict) and "mission" in document:
        return parse_mission(document, str(path))
    return parse_agent(document, str(path))


def drawing_for(document: AgentSpec | Mission, state: str | None) -> Drawing:
    from atemr.fsm.export import Drawing, ExportError, drawing_of
    from atemr.trees.missions import Mission

    if isinstance(document, Mission):
        if state not in (None, "mission"):
            raise ExportError("a mission file has one tree; --state does not apply")
        return Drawing(document.name, None, (("mission", document.spec),))
    return drawing_of(document, state)


def summary(document: AgentSpec | Mission) -> str:
    """One line that says what was validated."""
    from atemr.trees.missions import Mission

    if isinstance(document, Mission):
        missing = document.missing_behaviours()
        runnable = "runnable" if not missing else f"not runnable in this build (needs {', '.join(missing)})"
        return f"mission '{document.name}': {len(document.steps)} steps, {runnable}"
    trees = sum(s.tree is not None for s in document.states.values())
    return (f"agent: {len(document.states)} states ({len(document.leaves())} leaf states), "
            f"{len(document.transitions)} transitions, {trees} state trees"
            f"{', a monitor tree' if document.monitor else ''}")


class TreeCommand:
    help = "validate or draw the agent's lifecycle and behaviour trees (or a mission's tree)"

    def configure(self, parser: argparse.ArgumentParser) -> None:
        sub = parser.add_subparsers(dest="tree_action", metavar="ACTION", required=True)
        validate = sub.add_parser("validate", help="check a document; exit 0 when valid, 2 with file:line:col")
        validate.add_argument("file", type=Path)
        export = sub.add_parser("export", help="draw the machine and trees")
        export.add_argument("file", type=Path)
        export.add_argument("--format", "-f", default="ascii",
                            help="ascii, mermaid, json and dot always work; svg and png need Graphviz's dot "
                                 "(plugins add more: the atemr.exporters entry points)")
        export.add_argument("--state", "-s", help="draw only this state's tree ('monitor' for the Monitor)")
        export.add_argument("--output", "-o", type=Path, help="write here instead of standard output")

    def run(self, args: argparse.Namespace) -> int:
        from atemr.fsm.export import ExportError, exporters

        if args.tree_action == "export" and args.format not in exporters:
            raise ExportError(exporters.unknown_message(args.format))
        document = load_document(args.file)
        if args.tree_action == "validate":
            print(f"{args.file}: OK, {summary(document)}")
            return 0
        output = exporters.get(args.format)(drawing_for(document, args.state))
        if args.output is not None:
            args.output.write_bytes(output if isinstance(output, bytes) else output.encode())
            print(f"wrote {args.output} ({args.format})")
        elif isinstance(output, bytes):
            if sys.stdout.isatty():
                raise ExportError(f"{args.format} is binary: give --output FILE")
            sys.stdout.buffer.write(output)
        else:
            sys.stdout.write(output)
        return 0


commands.add("tree", TreeCommand())
