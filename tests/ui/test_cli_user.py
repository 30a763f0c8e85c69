"""``atemr user set-password`` / ``list``: the console way to set the first admin password."""

from __future__ import annotations

import io

from atemr.cli.main import main
from atemr.ui.users import UserStore


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
