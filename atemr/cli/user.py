"""``atemr user``: manage dashboard users from the robot's console (the first admin password too)."""

from __future__ import annotations

import argparse
import getpass
import sys
from pathlib import Path

from atemr.errors import AtemrError


def read_new_password(prompt: str = "New password: ") -> str:
    """From a terminal: asked twice without echo. Piped: the first line of stdin (for scripts)."""
    if sys.stdin.isatty():
        first = getpass.getpass(prompt)
        second = getpass.getpass("Repeat: ")
        if first != second:
            raise AtemrError("the two passwords differ")
        return first
    line = sys.stdin.readline()
    if not line:
        raise AtemrError("no password on stdin")
    return line.rstrip("\r\n")


class UserCommand:
    def configure(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--config", type=Path, help="YAML configuration file (default: $ATEMR_CONFIG)")
        parser.add_argument("--data-dir", type=Path, help="where the users database lives")
        sub = parser.add_subparsers(dest="action", required=True)
        setpw = sub.add_parser("set-password", help="set a user's password (asked on the terminal or read from stdin)")
        setpw.add_argument("username")
        sub.add_parser("list", help="list users and their roles")

    def run(self, args: argparse.Namespace) -> int:
        from atemr.config import load_config
        from atemr.ui.app import database_path
        from atemr.ui.users import UserStore

        config = load_config(args.config, overrides={"data_dir": args.data_dir})
        store = UserStore(database_path(config))
        if args.action == "list":
            for user in store.list():
                note = "" if user.has_password else "  (no password yet)"
                print(f"{user.username:32} {user.role}{note}")
            return 0
        if store.get(args.username) is None:
            raise AtemrError(f"no user called {args.username!r} (create users on the dashboard)")
        store.set_password(args.username, read_new_password(f"New password for {args.username}: "))
        print(f"password of {args.username} set", file=sys.stderr)
        return 0
