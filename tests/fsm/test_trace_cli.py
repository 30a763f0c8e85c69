"""``atemr trace show FILE [--json]`` and ``atemr mission run --headless --trace FILE``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from atemr.cli.main import main
from atemr.io.trace_file import TraceWriter


def write_trace(path: Path) -> None:
    with TraceWriter(path) as writer:
        for record in [
            {"k": "head", "t": 0.0, "v": 1, "agent": "agent", "meta": {"world": "studio", "seed": 3}},
            {"k": "snap", "t": 0.0, "state": "STARTUP", "mode": "MANUAL", "blackboard": {},
             "transitions": [{"t": 0.0, "trigger": "(initial)", "source": "", "dest": "STARTUP", "accepted": True,
                              "reason": "agent started", "origin": ""}]},
            {"k": "tr", "t": 0.1, "trigger": "startup_ok", "source": "STARTUP", "dest": "IDLE.MANUAL",
             "accepted": True, "reason": "start-up succeeded", "origin": "tree:STARTUP"},
            {"k": "tr", "t": 0.2, "trigger": "set_auto", "source": "IDLE.MANUAL", "dest": None, "accepted": False,
             "reason": "level-1 status not OK (unhealthy: ir_front)", "origin": "dashboard"},
            {"k": "pose", "t": 0.5, "x": 1.0, "y": 2.0, "yaw": 0.0},
        ]:
            writer.write(record)


def test_show_prints_the_transitions_with_times_and_reasons(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "run.atrace"
    write_trace(path)
    assert main(["trace", "show", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"{path}: agent 'agent', 0.000-0.500 s, 5 records (world studio, seed 3)"
    assert out[1].split() == ["0.000", "(initial)", "—", "->", "STARTUP:", "agent", "started"]
    assert "0.100  startup_ok       STARTUP -> IDLE.MANUAL [tree:STARTUP]: start-up succeeded" in out[2]
    assert "0.200  set_auto         refused in IDLE.MANUAL [dashboard]: level-1 status not OK" in out[3]


def test_show_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "run.atrace"
    write_trace(path)
    assert main(["trace", "show", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["file"] == str(path) and report["records"] == 5 and report["warnings"] == []
    assert [(t["t"], t["trigger"], t["dest"], t["accepted"]) for t in report["transitions"]] == [
        (0.0, "(initial)", "STARTUP", True), (0.1, "startup_ok", "IDLE.MANUAL", True),
        (0.2, "set_auto", None, False)]
    assert report["transitions"][2]["reason"].startswith("level-1 status not OK")


def test_show_a_cut_file_warns_with_the_offset_and_exits_1(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "run.atrace"
    write_trace(path)
    data = path.read_bytes()
    cut = data.rindex(b"\n", 0, len(data) - 1) + 1  # the last record (the pose) starts here
    path.write_bytes(data[: cut + 12])
    assert main(["trace", "show", str(path), "--json"]) == 1
    captured = capsys.readouterr()
    assert json.loads(captured.out)["records"] == 4
    assert f"warning: {path}: offset {cut}: the last record is cut short" in captured.err


def test_show_refuses_what_is_not_a_trace(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "notes.txt"
    path.write_text("hello")
    assert main(["trace", "show", str(path)]) == 2
    assert "neither an MCAP recording nor an ATEMR trace" in capsys.readouterr().err


def test_a_headless_mission_run_writes_a_trace(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    trace = tmp_path / "goal.mcap"
    code = main(["--log-level", "ERROR", "mission", "run", "--headless", "--goal", "1.5,1.0,0", "--json",
                 "--data-dir", str(tmp_path / "data"), "--trace", str(trace)])
    result = json.loads(capsys.readouterr().out)
    assert code == 0 and result["trace_files"] == [str(trace)]
    assert [r["dest"] for r in result["trace"]][-2:] == ["EXEC", "IDLE.AUTO"]  # the agent's state trace stays
    assert not (tmp_path / "data" / "traces").exists()  # headless runs record only where --trace says
    assert main(["trace", "show", str(trace), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    moves = [(t["trigger"], t["dest"]) for t in report["transitions"] if t["accepted"]]
    assert moves[-3:] == [("set_auto", "IDLE.AUTO"), ("start_mission", "EXEC"), ("reached", "IDLE.AUTO")]
    assert report["meta"]["world"] == "studio" and report["end_t"] >= result["finished_s"] - 0.2
