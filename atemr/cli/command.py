"""What a subcommand is, and the registry of the ones other packages add.

The built-in commands are named in `atemr.cli.main.BUILTIN_COMMANDS` (the class that runs each and its
one-line help), so the command line imports a command's module only when that command runs. A third-party
package adds a command through the ``atemr.commands`` entry-point group: the entry point names a
`PluginCommand` object, which carries its own help.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from atemr.registry import Registry


class Command(Protocol):
    """A subcommand: adds its own arguments, then runs with the parsed namespace."""

    def configure(self, parser: argparse.ArgumentParser) -> None:
        """Add this subcommand's arguments to its parser."""
        ...

    def run(self, args: argparse.Namespace) -> int:
        """Execute; the return value is the process exit code."""
        ...


class PluginCommand(Command, Protocol):
    """A command from another package: as it is loaded only to be listed, it carries its one-line help."""

    help: str


#: Commands added by other packages (entry-point group ``atemr.commands``); read only when needed.
commands: Registry[PluginCommand] = Registry("commands")


def report_and_warn(report: dict[str, Any], *, as_json: bool, printer: Callable[[dict[str, Any]], None],
                    warnings: Sequence[str]) -> int:
    """Print ``report`` (JSON, or through ``printer``), then each warning on stderr; exit code 1 when a file was
    read only up to damage (there are warnings), else 0."""
    if as_json:
        print(json.dumps(report, indent=2))
    else:
        printer(report)
    for warning in warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return 1 if warnings else 0
