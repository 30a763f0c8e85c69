"""``atemr can decode`` / ``monitor`` / ``dbc``."""

from __future__ import annotations

import json
from pathlib import Path

import can
import pytest

from atemr.cli.can import monitor_bus
from atemr.cli.main import main
from atemr.clock import SimClock
from atemr.domain.status import PowerState
from atemr.io.can import Heartbeat, Power
from atemr.io.motors.rmd_codec import RmdCommand, RmdRequest


def write_log(path: Path) -> None:
    with can.Logger(path) as logger:
        for k, msg in enumerate([Heartbeat(True).encode(), Power(PowerState.RUNNING).encode(),
                                 RmdRequest(2, RmdCommand.MOTOR_STOP).encode(),
                                 can.Message(arbitration_id=0x157, data=b"\x05", is_extended_id=False)]):
            msg.timestamp = 100.0 + k
            logger.on_message_received(msg)


def test_decode_prints_every_frame_by_name(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bus.log"
    write_log(path)
    assert main(["can", "decode", str(path)]) == 0
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert len(lines) == 4
    assert "0x157 heartbeat" in lines[0] and "Heartbeat from_primary=True" in lines[0]
    assert "Power state=RUNNING request=NORMAL" in lines[1]
    assert "RMD motor 2 RmdRequest motor=2 command=MOTOR_STOP" in lines[2]
    assert "! 0x157 heartbeat: value 0x05" in lines[3]
    assert "4 frame(s), 1 not decodable" in err


def test_decode_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bus.asc"
    write_log(path)
    assert main(["can", "decode", "--json", str(path)]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert rows[1]["fields"] == {"state": "RUNNING", "request": "NORMAL"} and rows[1]["id"] == "0x150"


def test_decode_missing_file_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["can", "decode", str(tmp_path / "nope.log")]) == 2
    assert "no such log file" in capsys.readouterr().err


def test_monitor_unknown_interface(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["can", "monitor", "--interface", "virtul", "--channel", "x", "--count", "1"]) == 2
    assert "did you mean 'virtual'" in capsys.readouterr().err


def test_monitor_bus_prints_and_logs(tmp_path: Path) -> None:
    channel = "cli-monitor"
    lines: list[str] = []
    with can.Bus(interface="virtual", channel=channel) as tx, can.Bus(interface="virtual", channel=channel) as rx:
        tx.send(Heartbeat(False).encode())
        tx.send(Heartbeat(True).encode())
        with can.Logger(tmp_path / "mon.log") as logger:
            seen = monitor_bus(rx, lines.append, SimClock(), count=2, logger=logger, poll_s=0)
    assert seen == 2 and "from_primary=False" in lines[0] and "from_primary=True" in lines[1]
    assert len(list(can.LogReader(tmp_path / "mon.log"))) == 2


def test_monitor_bus_stops_after_duration() -> None:
    class TickingClock(SimClock):
        def now(self) -> float:
            return self.advance(0.1)

    with can.Bus(interface="virtual", channel="cli-monitor-idle") as rx:
        assert monitor_bus(rx, print, TickingClock(), duration=1.0, poll_s=0) == 0


def test_dbc_path(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["can", "dbc"]) == 0
    assert Path(capsys.readouterr().out.strip()).name == "atemr.dbc"
    assert main(["can", "dbc", "--print"]) == 0
    assert "BO_ 339 PRIMARY_STATUS" in capsys.readouterr().out
