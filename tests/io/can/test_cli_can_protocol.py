"""``atemr can decode`` reads motor frames in the configured RMD protocol version (``--protocol``, ``--config``)."""

from __future__ import annotations

import json
from pathlib import Path

import can
import pytest

from atemr.cli.can import describe_frame, monitor_bus
from atemr.cli.main import main
from atemr.clock import SimClock
from atemr.io.can import Heartbeat
from atemr.io.motors.rmd_codec import RmdCommand, RmdRequest

#: A V4.2 exchange: speed command and its reply, a status-1 request and the document's example replies.
V4_FRAMES = [
    RmdRequest(1, RmdCommand.SPEED_CONTROL, 1.0).encode(),
    can.Message(arbitration_id=0x241, data=bytes.fromhex("A2 32 64 00 F4 01 2D 00"), is_extended_id=False),
    RmdRequest(1, RmdCommand.READ_STATUS_1).encode(),
    can.Message(arbitration_id=0x241, data=bytes.fromhex("9A 32 00 01 E5 01 04 00"), is_extended_id=False),
    can.Message(arbitration_id=0x242, data=bytes.fromhex("81 00 00 00 00 00 00 00"), is_extended_id=False),
    Heartbeat(True).encode(),
]


def write_v4_log(path: Path) -> None:
    with can.Logger(path) as logger:
        for k, msg in enumerate(V4_FRAMES):
            msg.timestamp = 10.0 + k
            logger.on_message_received(msg)


def test_decode_v4_by_name_and_field(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "v4.log"
    write_v4_log(path)
    assert main(["can", "decode", "--protocol", "v4", str(path)]) == 0
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert len(lines) == 6
    assert "RMD motor 1 RmdRequest motor=1 command=SPEED_CONTROL speed_radps=1.0" in lines[0]
    assert "0x241" in lines[1] and "RMD motor 1 V4Status2Reply" in lines[1]
    assert "command=SPEED_CONTROL temperature_c=50 current_a=1.0 speed_radps=8.7266 angle_rad=0.7854" in lines[1]
    assert ("RMD motor 1 V4Status1Reply motor=1 command=READ_STATUS_1 temperature_c=50 voltage_v=48.5 "
            "brake_released=True errors=UNDER_VOLTAGE error_code=0x0004") in lines[3]
    assert "RMD motor 2 AckReply motor=2 command=MOTOR_STOP" in lines[4]
    assert "Heartbeat from_primary=True" in lines[5]
    assert "6 frame(s), 0 not decodable (motor frames as RMD protocol V4.2)" in err


def test_decode_v4_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "v4.log"
    write_v4_log(path)
    assert main(["can", "decode", "--json", "--protocol", "v4", str(path)]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    status = rows[3]
    assert status["id"] == "0x241" and status["name"] == "RMD motor 1 V4Status1Reply" and status["error"] is None
    assert status["fields"]["voltage_v"] == 48.5 and status["fields"]["errors"] == "UNDER_VOLTAGE"


def test_the_protocol_comes_from_the_config(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "v4.log"
    write_v4_log(path)
    config = tmp_path / "robot.yaml"
    config.write_text("devices:\n  motors: {protocol: v4}\n", encoding="utf-8")
    assert main(["can", "decode", "--config", str(config), str(path)]) == 0
    out, err = capsys.readouterr()
    assert "V4Status1Reply" in out and "0 not decodable (motor frames as RMD protocol V4.2)" in err
    # --protocol overrides the file; read as V1.61, 0x241 is no frame of this bus
    assert main(["can", "decode", "--config", str(config), "--protocol", "v1", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "not a frame of this robot's bus" in out.splitlines()[1]
    assert "3 not decodable (motor frames as RMD protocol V1.61)" in err


def test_default_is_v1_and_a_bad_config_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "v4.log"
    write_v4_log(path)
    assert main(["can", "decode", str(path)]) == 0
    assert "motor frames as RMD protocol V1.61" in capsys.readouterr().err
    config = tmp_path / "bad.yaml"
    config.write_text("devices:\n  motors: {protocol: v2}\n", encoding="utf-8")
    assert main(["can", "decode", "--config", str(config), str(path)]) == 2
    assert "devices.motors.protocol: expected one of 'v1', 'v4', got 'v2'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["can", "decode", "--protocol", "v2", str(path)])


def test_v4_frames_that_are_not_v4_say_so() -> None:
    run = describe_frame(RmdRequest(1, RmdCommand.MOTOR_RUN).encode(), "v4")
    assert run.error is not None and "MOTOR_RUN (0x88) is not a V4.2 command" in run.error
    short = describe_frame(can.Message(arbitration_id=0x241, data=b"\x9a\x00", is_extended_id=False), "v4")
    assert short.name == "invalid" and short.error is not None and "wrong length 2" in short.error


def test_monitor_reads_v4(request: pytest.FixtureRequest) -> None:
    channel = f"cli-{request.node.name}"
    lines: list[str] = []
    with can.Bus(interface="virtual", channel=channel) as tx, can.Bus(interface="virtual", channel=channel) as rx:
        tx.send(V4_FRAMES[3])
        assert monitor_bus(rx, lines.append, SimClock(), count=1, poll_s=0, protocol="v4") == 1
    assert "V4Status1Reply" in lines[0] and "errors=UNDER_VOLTAGE" in lines[0]
