"""``atemr user set-password`` / ``list``: the console way to set the first admin password."""

from __future__ import annotations

import argparse
import io

from atemr.cli.user import UserCommand
from atemr.errors import AtemrError
from atemr.ui.users import UserStore


def main(argv):
    """Run ``atemr user ...`` as atemr.cli.main does (AtemrError → message and exit 2), without importing
    the other subcommands."""
    parser = argparse.ArgumentParser(prog="atemr")
    sub = parser.add_subparsers(dest="command", required=True)
    command = UserCommand()
    command.configure(sub.add_parser("user"))
    args = parser.parse_args(argv)
    try:
        return command.run(args)
    except AtemrError as exc:
        import sys

        print(f"atemr user: error: {exc}", file=sys.stderr)
        return 2


def test_user_is_a_builtin_command():
    from atemr.cli import main as cli_main

    assert cli_main.BUILTIN_COMMANDS["user"].target == "atemr.cli.user:UserCommand"


def test_set_admin_password_from_stdin(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("sys.stdin", io.StringIO("console-secret\n"))
    assert main(["user", "--data-dir", str(tmp_path), "set-password", "admin"]) == 0
    store = UserStore(tmp_path / "users.sqlite3")
    assert not store.needs_root_password()
    assert store.verify("admin", "console-secret") is not None
    assert main(["user", "--data-dir", str(tmp_path), "list"]) == 0
    assert "admin" in capsys.readouterr().out


def test_refusals_are_one_line_errors(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("sys.stdin", io.StringIO("short\n"))
    assert main(["user", "--data-dir", str(tmp_path), "set-password", "admin"]) == 2
    assert "at least 8 characters" in capsys.readouterr().err
    monkeypatch.setattr("sys.stdin", io.StringIO(""))
    assert main(["user", "--data-dir", str(tmp_path), "set-password", "admin"]) == 2
    assert "no password on stdin" in capsys.readouterr().err
    monkeypatch.setattr("sys.stdin", io.StringIO("long-enough\n"))
    assert main(["user", "--data-dir", str(tmp_path), "set-password", "ghost"]) == 2
    assert "no user called 'ghost'" in capsys.readouterr().err
