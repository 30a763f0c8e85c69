"""Recording the bus to .log/.asc/.blf and decoding every frame by name."""

from __future__ import annotations

import itertools
from pathlib import Path

import can
import pytest

from atemr.domain.status import StateCode
from atemr.errors import ConfigError
from atemr.io.can import Heartbeat, PrimaryStatus
from atemr.io.can.recording import BusRecorder, check_log_path, describe, read_log
from atemr.io.motors.rmd_codec import RmdCommand, RmdRequest, Status1Reply

_names = itertools.count()

TRAFFIC = [
    Heartbeat(True).encode(),
    PrimaryStatus(state=StateCode.IDLE).encode(),
    RmdRequest(1, RmdCommand.SPEED_CONTROL, 1.5).encode(),
    Status1Reply(2, RmdCommand.READ_STATUS_1, 30, 24.0, 0).encode(),  # type: ignore[arg-type]
    can.Message(arbitration_id=0x153, data=b"\x00\x00\x09", is_extended_id=False),
    can.Message(arbitration_id=0x7FF, data=b"\x01", is_extended_id=False),
]


@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf"])
def test_record_and_read_back(tmp_path: Path, suffix: str) -> None:
    ch = f"recording-{next(_names)}"
    path = tmp_path / f"bus{suffix}"
    with can.Bus(interface="virtual", channel=ch) as tx:
        recorder = BusRecorder(can.Bus(interface="virtual", channel=ch), path)
        for k, msg in enumerate(TRAFFIC):
            tx.send(msg)
            recorder.tick(1.0 + k * 0.5)
        recorder.shutdown()
        recorder.shutdown()
    assert recorder.frames == len(TRAFFIC)
    back = list(read_log(path))
    assert [(m.arbitration_id, bytes(m.data)) for m in back] == [(m.arbitration_id, bytes(m.data)) for m in TRAFFIC]
    if suffix == ".log":  # ASC and BLF store times relative to the start of the file
        assert [m.timestamp for m in back] == pytest.approx([1.0 + k * 0.5 for k in range(len(TRAFFIC))])


def test_describe_names_every_frame() -> None:
    lines = [describe(m) for m in TRAFFIC]
    assert lines[0].name == "Heartbeat" and lines[0].fields == {"from_primary": True}
    assert lines[1].fields["state"] == "IDLE"
    assert lines[2].name == "RMD motor 1 RmdRequest" and lines[2].fields["command"] == "SPEED_CONTROL"
    assert lines[3].fields["voltage_v"] == 24.0
    assert lines[4].error is not None and "state code 9" in lines[4].error
    assert lines[5].error == "not a frame of this robot's bus"
    assert "0x153 primary status" in lines[1].line() and "state=IDLE" in lines[1].line()
    assert lines[4].as_dict()["id"] == "0x153"


def test_bad_paths(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"\.log"):
        check_log_path(tmp_path / "bus.txt2")
    with pytest.raises(ConfigError, match="no such log file"):
        list(read_log(tmp_path / "missing.log"))


def test_recorder_from_config(tmp_path: Path) -> None:
    from atemr.config import CanConfig
    from atemr.io.can.bus import open_bus, unique_channel
    from atemr.io.can.recording import recorder_from_config

    assert recorder_from_config(CanConfig()) is None
    config = CanConfig(channel=unique_channel("rec"), log_file=tmp_path / "run" / "bus.log")
    recorder = recorder_from_config(config)
    assert recorder is not None
    with open_bus(config) as tx, recorder:
        tx.send(Heartbeat(True).encode())
        recorder.tick(0.5)
    assert [m.arbitration_id for m in read_log(config.log_file)] == [0x157]  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="cannot record"):
        recorder_from_config(CanConfig(log_file=tmp_path / "bus.docx"))
