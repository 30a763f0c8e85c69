"""The command line takes negative coordinates in both spellings, names the option of a bad pose in one
line, and has ``--host``/``--port`` on the commands that serve the dashboard."""

from __future__ import annotations

import logging

import pytest

from atemr.cli.main import build_parser, main
from atemr.msgs import Pose2D

NEGATIVE = "-1.625,0.825,2.017"


@pytest.mark.parametrize("spelling", ["space", "equals"])
def test_every_pose_option_takes_negative_coordinates(spelling: str) -> None:
    def option(name: str, value: str) -> list[str]:
        return [name, value] if spelling == "space" else [f"{name}={value}"]

    args = build_parser().parse_args([
        "mission", "run", "--headless", *option("--start", NEGATIVE), *option("--goal", "-0.5,-0.5,-3.1"),
        *option("--goal", "0.5,0.5,0"), *option("--kidnap", "4,-2,-3,-1.5"),
    ])
    assert args.start == Pose2D(-1.625, 0.825, 2.017)
    assert args.goal == [Pose2D(-0.5, -0.5, -3.1), Pose2D(0.5, 0.5, 0.0)]
    assert args.kidnap == (4.0, Pose2D(-2.0, -3.0, -1.5))


def test_negative_numbers_still_work_where_they_did() -> None:
    args = build_parser().parse_args(["sim", "--twist", "-0.2", "-.5"])
    assert tuple(args.twist) == (-0.2, -0.5)


@pytest.mark.parametrize(("argv", "option", "what"), [
    (["--goal", "1,2"], "--goal", "X,Y,YAW (metres, metres, radians"),
    (["--goal", "a,b,c"], "--goal", "X,Y,YAW (metres, metres, radians"),
    (["--goal", "nan,0,0"], "--goal", "X,Y,YAW (metres, metres, radians"),
    (["--goal", "-1,2"], "--goal", "X,Y,YAW (metres, metres, radians"),
    (["--goal=1,inf,0"], "--goal", "X,Y,YAW (metres, metres, radians"),
    (["--start", "1,2,3,4"], "--start", "X,Y,YAW (metres, metres, radians"),
    (["--kidnap", "-1,0,0,0"], "--kidnap", "T,X,Y,YAW with T >= 0"),
    (["--kidnap", "1,0,0"], "--kidnap", "T,X,Y,YAW: T >= 0 robot seconds, then X,Y,YAW (metres"),
])
def test_a_bad_pose_is_one_line_naming_the_option(argv: list[str], option: str, what: str,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["mission", "run", "--headless", *argv])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"atemr mission run: error: argument {option}: expected {what}"), err
    assert "(see 'atemr mission run --help')" in err


def test_host_and_port_are_command_line_layers(monkeypatch: pytest.MonkeyPatch) -> None:
    """``./run --port 8080 --host ...`` sets ui.port/ui.host above the environment; the dashboard's too."""
    import atemr.robot
    from atemr.config import Config

    seen: list[Config] = []

    def build_robot(config: Config, realtime: bool) -> None:
        seen.append(config)
        raise SystemExit(0)

    monkeypatch.setattr(atemr.robot, "build_robot", build_robot)
    monkeypatch.setenv("ATEMR_UI__PORT", "7000")
    with pytest.raises(SystemExit):
        main(["run", "--port", "8080", "--host", "0.0.0.0"])
    assert (seen[0].ui.port, seen[0].ui.host) == (8080, "0.0.0.0")
    args = build_parser().parse_args(["dashboard", "--port", "8081", "--host", "::1"])
    assert (args.port, args.host) == (8081, "::1")


def test_listening_beyond_this_machine_is_warned_about(tmp_path, caplog: pytest.LogCaptureFixture) -> None:
    """The warning names the address and what it exposes; tests only ever bind 127.0.0.1, so the address that
    warns is checked on the message itself and the loopback start on a real server."""
    from atemr.config import load_config
    from atemr.ui.server import DashboardServer, exposure_warning, is_loopback

    assert is_loopback("127.0.0.1") and is_loopback("127.0.0.2") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("kay.local") and not is_loopback("::")
    message = exposure_warning("0.0.0.0", 8080)
    assert message is not None and "listens on 0.0.0.0" in message and "port 8080" in message
    assert "drives the robot" in message and exposure_warning("127.0.0.1", 8080) is None
    config = load_config(None, overrides={"ui.port": 0, "data_dir": tmp_path})
    server = DashboardServer(config, None)
    with caplog.at_level(logging.WARNING, logger="atemr.ui.server"):
        server.start()
        server.shutdown()
    assert not [r for r in caplog.records if "not only on this machine" in r.getMessage()]
