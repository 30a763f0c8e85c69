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


def test_power_off_command_runs_only_after_an_acknowledged_power_off(tmp_path):
    """The robot's example configuration runs ``systemctl poweroff`` once the ESP32's power-off request is
    acknowledged; here the command touches a file, and it runs only when the agent halted that way."""
    from atemr.cli.run import after_stop
    from atemr.clock import SimClock
    from atemr.config import load_config
    from atemr.io.can.bus import unique_channel
    from atemr.robot import build_robot

    marker = tmp_path / "powered-off"
    config = load_config(environ={}, overrides={
        "data_dir": str(tmp_path), "can.channel": unique_channel("poweroff"), "ui.enabled": False,
        "secondary.portal_serve": False, "power_off_command": f"touch {marker}"})
    robot = build_robot(config, realtime=False, clock=SimClock())
    with robot:
        robot.run(until=5.0)
        assert robot.parts.agent.state.startswith("IDLE")
        assert after_stop(robot) == 0 and not marker.exists()  # stopped without a power-off: nothing runs
        robot.parts.agent.submit("shutdown")
        robot.run(until=8.0)
        assert robot.parts.agent.halted
    assert after_stop(robot) == 0 and marker.exists()


def test_the_parser_imports_no_heavy_library():
    """``atemr --help`` and every command's start-up import only what the chosen command runs: building the
    whole parser pulls in none of numpy, scipy, Flask, python-can or filterpy (each costs tenths of a second)."""
    code = ("import sys; from atemr.cli.main import build_parser; build_parser(); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'numpy', 'scipy', 'flask', 'can', 'filterpy', "
            "'cv2', 'serial', 'py_trees', 'transitions'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert out.stdout.strip() == "[]", out.stdout
