import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from atemr import __version__
from atemr.cli.main import BUILTIN_COMMANDS, build_parser, main, named_command


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


def test_run_freezes_the_start_up_heap_while_the_robot_runs(monkeypatch, capsys):
    """A full garbage collection over the start-up heap would stall the control loop: frozen while it runs."""
    import gc

    from atemr.robot.core import Robot

    frozen_while_running: list[int] = []
    real_run = Robot.run

    def run(self, **kwargs):
        frozen_while_running.append(gc.get_freeze_count())
        real_run(self, **kwargs)

    monkeypatch.setattr(Robot, "run", run)
    assert main(["run", "--duration", "0.01", "--speed", "100"]) == 0
    assert frozen_while_running and frozen_while_running[0] > 10_000, frozen_while_running
    assert gc.get_freeze_count() == 0, "unfrozen once the robot stopped"


def test_run_stops_cleanly_on_sigterm_and_sigint(tmp_path):
    for sig, delay_s in ((signal.SIGTERM, 0.2), (signal.SIGINT, 0.2)):
        env = dict(os.environ, XDG_DATA_HOME=str(tmp_path))
        proc = subprocess.Popen(
            [sys.executable, "-m", "atemr", "run"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        )
        try:
            line = proc.stdout.readline()  # blocks until the robot says it runs
            assert "started:" in line
            time.sleep(delay_s)
            proc.send_signal(sig)
            out, err = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:  # a robot that ignored the signal must not hold port 5000 for later tests
                proc.kill()
                proc.communicate()
        assert proc.returncode == 0, err
        assert "ATEMR stopped." in out
        assert f"{signal.Signals(sig).name} received" in err


def test_a_sigterm_between_the_robots_start_and_its_loop_stops_it(monkeypatch, capsys):
    """The signal lands after the robot started and before its loop began (systemd stopping a robot that is just
    coming up): the loop returns at once instead of running on."""
    from atemr.robot.core import Robot

    real_start, real_run = Robot.start, Robot.run
    ran_for: list[float] = []

    def start(self):
        real_start(self)
        os.kill(os.getpid(), signal.SIGTERM)  # handled now: robot.stop() before robot.run()

    def run(self, **kwargs):
        t0 = self.clock.now()
        real_run(self, **kwargs)
        ran_for.append(self.clock.now() - t0)

    monkeypatch.setattr(Robot, "start", start)
    monkeypatch.setattr(Robot, "run", run)
    assert main(["run", "--duration", "5"]) == 0  # on the wall clock: a lost stop runs the whole 5 s
    assert ran_for and ran_for[0] < 2.5, ran_for
    assert "ATEMR stopped." in capsys.readouterr().out


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


def _imported_after(code: str) -> dict[str, list[str]]:
    """Run ``code`` in a fresh interpreter, then name the heavy libraries and the atemr modules it imported."""
    probe = (f"import sys, json\n{code}\n"
             "print(json.dumps({'heavy': sorted({m.split('.')[0] for m in sys.modules} & {'numpy', 'scipy', 'flask', "
             "'can', 'cantools', 'filterpy', 'cv2', 'serial', 'py_trees', 'transitions', 'yaml', 'skfuzzy', "
             "'networkx', 'PIL', 'av', 'mcap'}), 'atemr': sorted(m for m in sys.modules if m.startswith('atemr.'))}))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=True)
    return json.loads(out.stdout.splitlines()[-1])


def test_the_parser_imports_no_heavy_library():
    """``atemr --help`` and every command's start-up import only what the chosen command runs: building the
    whole parser pulls in none of numpy, scipy, Flask, python-can or filterpy (each costs tenths of a second),
    no command's module, and nothing of the robot or the simulator."""
    seen = _imported_after("from atemr.cli.main import build_parser; build_parser().format_help()")
    assert seen["heavy"] == []
    assert set(seen["atemr"]) <= {"atemr.cli", "atemr.cli.main", "atemr.cli.arguments", "atemr.cli.command",
                                  "atemr.registry", "atemr.errors"}, seen["atemr"]


@pytest.mark.parametrize("name", sorted(BUILTIN_COMMANDS))
def test_a_command_parses_with_its_own_module_only(name):
    """Reading one command's arguments imports that command's module and none of the others, and still no
    heavy library: the command imports those when it runs."""
    seen = _imported_after(f"from atemr.cli.main import build_parser\n"
                           f"try:\n    build_parser(plugins=False).parse_args([{name!r}, '--help'])\n"
                           f"except SystemExit:\n    pass")
    assert seen["heavy"] == []
    module = BUILTIN_COMMANDS[name].target.partition(":")[0]
    commands = {b.target.partition(":")[0] for b in BUILTIN_COMMANDS.values()}
    assert module in seen["atemr"]
    assert commands & set(seen["atemr"]) <= {module, "atemr.cli.mission"}, seen["atemr"]  # mission attach


def test_every_builtin_command_has_its_arguments_in_the_parser():
    """The lazily filled parsers still describe every command: each prints its own usage and options."""
    parser = build_parser(plugins=False)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, command_parser in sub.choices.items():
        text = command_parser.format_help()
        assert text.startswith(f"usage: atemr {name} [-h] ")
        assert BUILTIN_COMMANDS[name].help.replace(" ", "") in "".join(text.split())  # wrapped anywhere


def test_a_command_line_names_its_command():
    assert named_command(["--log-level", "DEBUG", "sim", "--world", "run"]) == "sim"
    assert named_command(["--log-level=debug", "fuzzy"]) == "fuzzy"
    assert named_command(["--help"]) is None


def test_command_line_mistakes_say_what_and_where(tmp_path, capsys):
    """An engineer's slips answered with what to do: an engine name that is not shipped, a log line that is not
    a frame (after how many good ones), and the status command's help names no --headless it does not have."""
    assert main(["fuzzy", "show", "nosuch"]) == 2
    assert "no engine named 'nosuch': give a shipped engine (idle, manual)" in capsys.readouterr().err
    log = tmp_path / "bus.log"
    log.write_text("(0.000000) can0 150#01\n(0.010000) can0 153#0200\nnot a frame\n")
    assert main(["can", "decode", str(log)]) == 2
    assert "cannot read the log after its first 2 frames" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["mission", "status", "--help"])
    assert "--headless" not in capsys.readouterr().out


def test_output_cut_short_by_a_pipe_ends_quietly(tmp_path):
    """``atemr can decode LOG | head -1``: the reader closing the pipe is no error and prints no traceback."""
    log = tmp_path / "bus.log"
    log.write_text("".join(f"({i / 100:.6f}) can0 153#02000000\n" for i in range(20_000)))  # far more than a pipe holds
    proc = subprocess.Popen([sys.executable, "-m", "atemr", "can", "decode", str(log)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    assert proc.stdout is not None
    assert proc.stdout.readline()
    proc.stdout.close()  # the reader has what it wanted
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0 and b"Traceback" not in err, err
