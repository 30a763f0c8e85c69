import contextlib
import os
import signal
import subprocess
import sys
import time

from atemr import __version__
from atemr.cli.main import main


def test_version(capsys):
    try:
        main(["--version"])
    except SystemExit as exit_:
        assert exit_.code == 0
    assert __version__ in capsys.readouterr().out


def test_help_lists_only_real_subcommands(capsys):
    with contextlib.suppress(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "run" in out


def test_config_errors_are_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "c.yaml"
    bad.write_text("sim:\n  sead: 1\n")
    assert main(["run", "--config", str(bad), "--duration", "0"]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:2:3 sim.sead: unknown key 'sead'" in err


def test_run_for_a_duration_exits_0(tmp_path, capsys):
    assert main(["run", "--duration", "0.01", "--speed", "100"]) == 0
    assert "started:" in capsys.readouterr().out


def test_run_stops_cleanly_on_sigterm_and_sigint(tmp_path):
    for sig in (signal.SIGTERM, signal.SIGINT):
        env = dict(os.environ, XDG_DATA_HOME=str(tmp_path))
        proc = subprocess.Popen(
            [sys.executable, "-m", "atemr", "run"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        )
        line = proc.stdout.readline()  # blocks until the robot says it runs
        assert "started:" in line
        time.sleep(0.2)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=30)
        assert proc.returncode == 0, err
        assert "ATEMR stopped." in out
        assert f"{signal.Signals(sig).name} received" in err
