"""What a subcommand is, and the registry that lists them.

A subcommand module defines a `Command` and registers it with ``@commands.register("name")``; a
third-party package can add one through the ``atemr.commands`` entry-point group.
"""

from __future__ import annotations

import argparse
from typing import Protocol

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
