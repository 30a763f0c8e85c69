"""Entry point of the ``atemr`` console script."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from atemr import __version__
from atemr.cli.arguments import Parser
from atemr.cli.command import commands
from atemr.errors import AtemrError
from atemr.logsetup import configure_logging

#: The built-in subcommands, in the order ``--help`` lists them.
COMMAND_MODULES = ["atemr.cli.run", "atemr.cli.dashboard", "atemr.cli.bench", "atemr.cli.user", "atemr.cli.fuzzy",
                   "atemr.cli.sim", "atemr.cli.can", "atemr.cli.tree", "atemr.cli.mission", "atemr.cli.trace",
                   "atemr.cli.replay", "atemr.cli.hw", "atemr.cli.localize"]


def build_parser() -> argparse.ArgumentParser:
    """The full parser with every registered subcommand."""
    for module in COMMAND_MODULES:
        importlib.import_module(module)
    parser = Parser(
        prog="atemr",
        description="ATEMR: the software of an autonomous telepresence robot, on the robot or in simulation.",
    )
    parser.add_argument("--version", action="version", version=f"atemr {__version__}")
    parser.add_argument(
        "--log-level", default=None, choices=["DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"], type=str.upper,
        help="logging threshold (default: from config, INFO)",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, command in commands.items():
        sub_parser = sub.add_parser(name, help=command.help, description=command.help)
        command.configure(sub_parser)
        sub_parser.set_defaults(_command=command)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv``, run the subcommand, turn framework errors into a one-line message and exit 2."""
    parser = build_parser()
    args = parser.parse_args(argv)
    configure_logging(args.log_level or "INFO")
    try:
        return int(args._command.run(args))
    except AtemrError as exc:
        print(f"atemr {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
