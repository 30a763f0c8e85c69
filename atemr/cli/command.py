"""What a subcommand is, and the registry that lists them.

A subcommand module defines a `Command` and registers it with ``@commands.register("name")``; a
third-party package can add one through the ``atemr.commands`` entry-point group.
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

    help: str

    def configure(self, parser: argparse.ArgumentParser) -> None:
        """Add this subcommand's arguments to its parser."""
        ...

    def run(self, args: argparse.Namespace) -> int:
        """Execute; the return value is the process exit code."""
        ...


commands: Registry[Command] = Registry("commands")


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
