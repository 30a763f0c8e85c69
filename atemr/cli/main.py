"""Entry point of the ``atemr`` console script.

A command's module is imported only when that command runs (or prints its own help). `BUILTIN_COMMANDS`
names each built-in command's class and one-line help, which is all ``atemr --help`` shows; the chosen
command's parser is filled in when argparse hands it its arguments (`CommandParser`). So the start-up of
any command pays for argparse and that command's own module, not for every command's libraries, and the
entry-point scan for third-party commands runs only when the command line does not name a built-in one.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

from atemr import __version__
from atemr.cli.arguments import Parser

if TYPE_CHECKING:  # the registry behind it imports logging: a command that needs that imports it itself
    from atemr.cli.command import Command


class Builtin(NamedTuple):
    """Where a built-in command lives (``"module:Class"``) and the line ``atemr --help`` shows for it."""

    target: str
    help: str

    def load(self) -> Command:
        """Import the command's module and make the command."""
        module, _, name = self.target.partition(":")
        command: Command = getattr(importlib.import_module(module), name)()
        return command


#: The built-in subcommands (``--help`` lists them, and plugins, by name).
BUILTIN_COMMANDS: dict[str, Builtin] = {
    "run": Builtin("atemr.cli.run:RunCommand",
                   "start the robot: in simulation by default, or on real hardware with --can-interface socketcan"),
    "dashboard": Builtin("atemr.cli.dashboard:DashboardCommand",
                         "serve the dashboard without a robot: it shows the robots publishing into "
                         "ui.message_queue (Redis)"),
    "bench": Builtin("atemr.cli.bench:BenchCommand",
                     "run every benchmark (or the named ones) and print ours vs. baseline ratios"),
    "user": Builtin("atemr.cli.user:UserCommand",
                    "manage dashboard users: set-password NAME (the first admin password), list"),
    "screen": Builtin("atemr.cli.screen:ScreenCommand",
                      "the robot's screens (its tablet): add NAME (prints the device token once), list, revoke NAME"),
    "tls": Builtin("atemr.cli.tls:TlsCommand",
                   "HTTPS for the dashboard (calls need it): make-cert makes a self-signed certificate"),
    "fuzzy": Builtin("atemr.cli.fuzzy:FuzzyCommand",
                     "evaluate a fuzzy engine on rows from stdin (eval) or print and plot it (show)"),
    "sim": Builtin("atemr.cli.sim:SimCommand",
                   "run the simulated robot in a world (headless as fast as possible, or locked to real time)"),
    "can": Builtin("atemr.cli.can:CanCommand", "CAN tools: decode a bus log, monitor live traffic, locate the DBC"),
    "tree": Builtin("atemr.cli.tree:TreeCommand",
                    "validate or draw the agent's lifecycle and behaviour trees (or a mission's tree)"),
    "mission": Builtin("atemr.cli.mission:MissionCommand",
                       "validate mission files (trees/missions/*.yaml) or run one in a fresh simulation"),
    "trace": Builtin("atemr.cli.trace:TraceCommand",
                     "read recorded agent traces (data_dir/traces, atemr mission run --trace)"),
    "replay": Builtin("atemr.cli.replay:ReplayCommand",
                      "feed a recording into SLAM (--slam) or localization (--localize --map NAME)"),
    "hw": Builtin("atemr.cli.hw:HwCommand",
                  "check and read the robot's devices (lidar, IMU, camera, motors, secondary core); emulate its "
                  "lidar and IMU"),
    "localize": Builtin("atemr.cli.localize:LocalizeCommand",
                        "put the simulated robot somewhere without telling it, run FIND POSITION, report what it "
                        "found"),
}


class CommandParser(Parser):
    """A subcommand's parser that makes its command and adds the command's arguments on first use.

    argparse hands a subcommand's arguments to that subcommand parser's `parse_known_args`, and the top-level
    help reads only the help given to ``add_parser``; so only the command that runs is imported. Parsers of
    nested actions (``mission run``) are made with this class too, with nothing to load.
    """

    def __init__(self, *args: Any, load: Callable[[], Command] | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._load = load

    def _configure(self) -> None:
        if self._load is None:
            return
        load, self._load = self._load, None
        command = load()
        command.configure(self)
        self.set_defaults(_command=command)

    def parse_known_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                         namespace: argparse.Namespace | None = None) -> tuple[argparse.Namespace, list[str]]:
        self._configure()
        return super().parse_known_args(args, namespace)

    def format_help(self) -> str:
        self._configure()
        return super().format_help()


def _loaded(command: Command) -> Callable[[], Command]:
    """A plugin's command, which the entry-point scan has loaded already."""
    return lambda: command


def build_parser(*, plugins: bool = True) -> argparse.ArgumentParser:
    """The full parser: every built-in command, then (with ``plugins``) those other packages add.

    Leaving ``plugins`` out spares importlib.metadata and the scan of installed distributions (about a tenth of
    a second) when the command line names a built-in command."""
    parser = Parser(
        prog="atemr",
        description="ATEMR: the software of an autonomous telepresence robot, on the robot or in simulation.",
    )
    parser.add_argument("--version", action="version", version=f"atemr {__version__}")
    parser.add_argument(
        "--log-level", default=None, choices=["DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"], type=str.upper,
        help="logging threshold (default: from config, INFO)",
    )
    listed: dict[str, tuple[str, Callable[[], Command]]] = {
        name: (builtin.help, builtin.load) for name, builtin in BUILTIN_COMMANDS.items()}
    if plugins:
        from atemr.cli.command import commands

        for name, command in commands.items():
            if name not in BUILTIN_COMMANDS:  # a built-in name is never shadowed
                listed[name] = (command.help, _loaded(command))
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=CommandParser)
    for name, (text, load) in sorted(listed.items()):
        sub.add_parser(name, help=text, description=text, load=load)
    return parser


def named_command(argv: Sequence[str]) -> str | None:
    """The first word of ``argv`` that is not an option or the value of ``--log-level``: the command, unless
    an abbreviated option hides it (then a caller merely pays for looking up plugins it did not need)."""
    words = iter(argv)
    for word in words:
        if word == "--log-level":
            next(words, None)
        elif not word.startswith("-"):
            return word
    return None


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv``, run the subcommand, turn framework errors into a one-line message and exit 2."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(plugins=named_command(argv) not in BUILTIN_COMMANDS)
    args = parser.parse_args(argv)
    from atemr.errors import AtemrError
    from atemr.logsetup import configure_logging

    configure_logging(args.log_level or "INFO")
    try:
        return int(args._command.run(args))
    except AtemrError as exc:
        print(f"atemr {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # `atemr can decode LOG | head`: the reader has what it wanted
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # Python's own flush at exit must not fail again
        return 0


if __name__ == "__main__":
    sys.exit(main())
