"""The control channel on a running robot: missions started, followed and cancelled from another client.

Two robots: the agent over fake ports (fast, for the protocol), and the whole simulated robot (CAN motors,
secondary core, localization, navigation) for ``atemr mission run`` end to end. Each runs its scheduler on
its own thread, as ``./run`` does, on simulated time faster than real time.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from atemr.cli.main import main
from atemr.clock import RealTimeSimClock, SimClock
from atemr.config import Config, load_config
from atemr.errors import ControlError
from atemr.fsm.agent import Agent
from atemr.fsm.spec import AgentSpec
from atemr.io.can.bus import unique_channel
from atemr.io.control_client import ControlClient
from atemr.robot import build_robot
from atemr.robot import control as control_module
from atemr.robot.control import RobotControl
from atemr.robot.core import Robot
from atemr.scheduler import Scheduler
from atemr.trees.fakes import RecordingLink, RecordingPort

ROOT = Path(__file__).resolve().parents[2]

LONG_WAIT = """mission:
  name: long-wait
  steps:
    - wait: {duration_s: 86000}
"""

TWO_WAITS = """mission:
  name: two-waits
  steps:
    - wait: {duration_s: 1}
    - wait: {duration_s: 1}
"""


class Running:
    """A robot whose scheduler runs on a thread until the test ends."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.control: RobotControl = robot.components["control"]  # type: ignore[assignment]
        self.agent: Agent = robot.components["agent"]  # type: ignore[assignment]
        self.socket = self.control.server.path
        robot.start()
        self.thread = threading.Thread(target=robot.run, name="robot", daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self.robot.stop()
        self.thread.join(30)
        self.robot.shutdown()


def light_robot(data_dir: Path, spec: AgentSpec, **agent: Any) -> Running:
    """The agent over fake ports with the control channel, paced at 50x real time."""
    clock = RealTimeSimClock(speed=50.0)
    robot = Robot(Config(data_dir=data_dir), clock, Scheduler(clock, realtime=False))
    the_agent = Agent(spec, RecordingPort(), RecordingLink(time_source=clock.now), **agent)
    robot.add(the_agent, 10.0)
    robot.add(RobotControl(robot, the_agent), 10.0)
    return Running(robot)


@pytest.fixture
def light(tmp_path: Path, agent_spec: AgentSpec) -> Iterator[Running]:
    running = light_robot(tmp_path, agent_spec)
    yield running
    running.stop()


@pytest.fixture
def whole(tmp_path: Path) -> Iterator[Running]:
    """The whole simulated robot as ``./run`` builds it (dashboard off), unpaced: as fast as the CPU allows."""
    config = load_config(environ={}, overrides={
        "data_dir": str(tmp_path), "can.channel": unique_channel("control"), "sim.seed": 1,
        "secondary.portal_serve": False, "ui.enabled": False})
    running = Running(build_robot(config, realtime=False, clock=SimClock()))
    yield running
    running.stop()


def start(socket: Path, text: str, **extra: Any) -> tuple[ControlClient, dict[str, Any]]:
    client = ControlClient(socket)
    return client, client.request({"cmd": "start", "mission": {"text": text, "file": "m.yaml"}, **extra})


def ask(client: ControlClient, request: dict[str, Any]) -> dict[str, Any]:
    """One request's raw answer (a refusal is returned, not raised)."""
    client.send(request)
    return client.receive()


def until(client: ControlClient, event: str, **match: Any) -> dict[str, Any]:
    for answer in client.answers():
        if answer["event"] == event and all(answer.get(k) == v or answer.get("step", {}).get(k) == v
                                            for k, v in match.items()):
            return answer
    raise AssertionError("unreachable")


# -- protocol, on the light robot ---------------------------------------------------------------------------
def test_an_invalid_mission_is_refused_with_where_and_nothing_starts(light: Running) -> None:
    bad_kind = "mission:\n  name: x\n  steps:\n    - go_tu: {x_m: 1, y_m: 1}\n"
    with ControlClient(light.socket) as client:
        for request, error in [
            ({"mission": {"text": bad_kind, "file": "x.yaml"}},
             "x.yaml:4:7 mission.steps[0].go_tu: unknown step kind 'go_tu' (did you mean 'go_to'?)"),
            ({"mission": {"text": "mission: [\n", "file": "y.yaml"}}, "y.yaml:2:1"),
            ({"mission": "patrol"}, "'mission' must be {\"text\": the mission YAML"),
            ({"goals": [{"x_m": 1, "y_m": "a", "yaw_rad": 0}]}, "goals[0] coordinates must be numbers"),
            ({"goals": []}, "'goals' must be a list of 1 to 1000 poses"),
            ({"goals": [{"x_m": 1, "y_m": 2}]}, "goals[0] must be"),
            ({"goals": [{"x_m": 1, "y_m": 2, "yaw_rad": 0}], "timeout_s": -1}, "'timeout_s' must be a number"),
            ({"goals": [{"x_m": 1, "y_m": 2, "yaw_rad": 0}], "mission": {"text": TWO_WAITS}}, "not both"),
        ]:
            answer = ask(client, {"cmd": "start", **request})
            assert answer["ok"] is False and error in answer["error"], (request, answer)
        status = client.request({"cmd": "status"})["status"]
    assert status["control"] is None and status["task"] is None
    assert not status["state"].startswith("EXEC")
    assert all(c["trigger"] != "start_mission" for c in light.agent.snapshot()["commands"])


def test_a_mission_is_followed_to_its_end_with_the_headless_result_shape(light: Running) -> None:
    client, started = start(light.socket, TWO_WAITS)
    with client:
        assert started["event"] == "started" and started["steps"] == ["step 0: wait", "step 1: wait"]
        events = []
        for answer in client.answers():
            events.append(answer)
            if answer["event"] == "result":
                break
    result = events[-1]["result"]
    assert result["outcome"] == "reached" and result["reason"] is None
    assert {"mission", "file", "outcome", "reason", "steps", "started_s", "finished_s", "duration_s",
            "final_pose", "state", "trace", "world", "seed"} <= set(result)
    assert [s["status"] for s in result["steps"]] == ["reached", "reached"]
    assert [r["dest"] for r in result["trace"]][-3:] == ["IDLE.AUTO", "EXEC", "IDLE.AUTO"]
    steps = [(e["step"]["index"], e["step"]["status"]) for e in events if e["event"] == "step"]
    assert steps == [(0, "running"), (0, "reached"), (1, "running"), (1, "reached")]
    states = [e["state"] for e in events if e["event"] == "state"]
    assert states[-2:] == ["EXEC", "IDLE.AUTO"]
    with ControlClient(light.socket) as client:
        status = client.request({"cmd": "status"})["status"]
    assert status["last_control"]["outcome"] == "reached" and status["last_task"]["mission"] == "two-waits"


def test_cancel_a_second_start_and_a_client_that_goes_away(light: Running) -> None:
    client, _ = start(light.socket, LONG_WAIT, timeout_s=600000)
    with client:
        until(client, "step", status="running")
        with ControlClient(light.socket) as other:
            busy = ask(other, {"cmd": "start", "mission": {"text": TWO_WAITS, "file": "t"}})
            assert "already running: 'long-wait'" in busy["error"]
            with ControlClient(light.socket) as follower:
                follower.send({"cmd": "follow"})
                assert follower.receive()["event"] == "started"
                assert other.request({"cmd": "cancel", "reason": "tea time"}) == {"ok": True, "cancelled": "long-wait"}
                assert until(follower, "result")["result"]["outcome"] == "cancelled"
        result = until(client, "result")["result"]
    assert result["outcome"] == "cancelled" and result["reason"] == "tea time"
    assert result["steps"][0]["status"] == "interrupted"
    with ControlClient(light.socket) as other, pytest.raises(ControlError, match="nothing to cancel"):
        other.request({"cmd": "cancel"})

    client, _ = start(light.socket, LONG_WAIT, timeout_s=600000)
    until(client, "step", status="running")
    with ControlClient(light.socket) as follower:
        follower.send({"cmd": "follow"})
        until(follower, "started")
        client.close()  # killed: nobody could press Ctrl-C any more
        result = until(follower, "result")["result"]
    assert result["outcome"] == "cancelled"
    assert result["reason"] == "the client that started the mission disconnected"


def test_the_robots_stop_ends_a_followed_mission_and_removes_the_socket(light: Running) -> None:
    client, _ = start(light.socket, LONG_WAIT, timeout_s=600000)
    with client:
        until(client, "step", status="running")
        light.stop()
        result = until(client, "result")["result"]
    assert result["outcome"] == "interrupted" and result["reason"] == "the robot stopped before the mission ended"
    assert not light.socket.exists()


def test_a_follower_whose_wait_ends_as_the_robot_stops_still_sends_the_result(
        light: Running, monkeypatch: pytest.MonkeyPatch) -> None:
    """The robot's stop publishes the result, then stops the server. A follower whose wait for events ended just
    before the result, and who then sees the server stopping, must still send it (CI lost it once)."""
    original = control_module._Session.wait
    armed, stopper = threading.Event(), threading.Thread(target=light.stop, name="stopper")

    def wait_then_stop(session: Any, seen: int, timeout_s: float) -> list[dict[str, Any]]:
        events = original(session, seen, timeout_s)
        if armed.is_set() and not stopper.is_alive() and not events:
            armed.clear()
            stopper.start()
            for _ in range(1000):  # the robot stops between this follower's wait and its look at the server
                if light.control.server.stopping:
                    break
                threading.Event().wait(0.01)
        return events

    monkeypatch.setattr(control_module._Session, "wait", wait_then_stop)
    client, _ = start(light.socket, LONG_WAIT, timeout_s=600000)
    with client:
        until(client, "step", status="running")
        armed.set()
        result = until(client, "result")["result"]
    stopper.join(30)
    assert result["outcome"] == "interrupted" and result["reason"] == "the robot stopped before the mission ended"


def test_below_the_missions_autonomy_level_the_start_waits_for_the_operator(tmp_path: Path,
                                                                           agent_spec: AgentSpec) -> None:
    running = light_robot(tmp_path, agent_spec, autonomy="low")  # start_mission needs "high"
    try:
        client, _ = start(running.socket, TWO_WAITS)
        with client:
            assert until(client, "phase", phase="confirming")["autonomy"] == "low"
            request = running.agent.gate.pending
            assert request is not None and request.trigger == "start_mission"
            assert running.agent.answer(request.id, True, by="operator") is None
            result = until(client, "result")["result"]
        assert result["outcome"] == "reached", result["reason"]
        assert [s["status"] for s in result["steps"]] == ["reached", "reached"]

        client, _ = start(running.socket, TWO_WAITS)
        with client:
            until(client, "phase", phase="confirming")
            with ControlClient(running.socket) as other:
                other.request({"cmd": "cancel"})
            result = until(client, "result")["result"]
        assert result["outcome"] == "cancelled" and result["steps"] == []
        assert running.agent.state == "IDLE.AUTO" and running.agent.gate.pending is None
        denial = [r for r in running.agent.trace if r.decision == "denied"][-1]
        assert denial.trigger == "start_mission" and denial.decided_by == "control socket"
    finally:
        running.stop()


# -- atemr mission run/status/cancel on the whole simulated robot -----------------------------------------
def test_mission_run_attaches_to_the_running_robot(whole: Running, capsys: pytest.CaptureFixture[str]) -> None:
    data = str(whole.robot.config.data_dir)
    assert main(["--log-level", "ERROR", "mission", "run", "--goal", "3.4,2.6,0", "--data-dir", data, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["outcome"] == "reached", result["reason"]
    step = result["steps"][0]
    assert step["kind"] == "go_to" and step["status"] == "reached" and step["position_error_m"] <= 0.25
    assert abs(result["final_pose"]["x_m"] - 3.4) <= 0.25
    assert (result["world"], result["seed"]) == ("studio", 1)
    assert [r["dest"] for r in result["trace"]][-2:] == ["EXEC", "IDLE.AUTO"]
    assert whole.agent.state == "IDLE.AUTO"

    assert main(["mission", "status", "--data-dir", data]) == 0
    out = capsys.readouterr().out
    assert "agent IDLE.AUTO (mode AUTO)" in out and "last task 'goals': reached" in out
    assert main(["mission", "cancel", "--data-dir", data]) == 2
    assert "nothing to cancel: the agent is in IDLE.AUTO" in capsys.readouterr().err


def test_mission_run_is_cancelled_from_another_terminal(whole: Running, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    mission = tmp_path / "long-wait.yaml"
    mission.write_text(LONG_WAIT)
    data = str(whole.robot.config.data_dir)

    def cancel_once_running() -> None:
        with ControlClient(whole.socket) as follower:
            follower.send({"cmd": "follow"})
            until(follower, "step", status="running")
            with ControlClient(whole.socket) as other:
                other.request({"cmd": "cancel"})

    def follow_when_started() -> None:
        for _ in range(1000):
            try:
                return cancel_once_running()
            except ControlError:  # not started yet
                threading.Event().wait(0.02)

    helper = threading.Thread(target=follow_when_started)
    helper.start()
    code = main(["--log-level", "ERROR", "mission", "run", str(mission), "--data-dir", data, "--timeout", "500000"])
    helper.join(30)
    out = capsys.readouterr().out
    assert code == 1
    assert "step 0 (step 0: wait): running" in out
    assert "mission 'long-wait': cancelled (cancelled by the operator (atemr mission cancel))" in out
    assert whole.agent.state == "IDLE.AUTO"


def test_cli_refusals_when_attaching(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    look = str(ROOT / "trees" / "missions" / "look-around.yaml")
    assert main(["mission", "run", look, "--data-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"no robot is running: there is no control socket at {tmp_path / 'control.sock'}" in err
    assert "./run" in err and "--headless" in err
    assert main(["mission", "run", look, "--world", "studio", "--seed", "2", "--data-dir", str(tmp_path)]) == 2
    assert "--world, --seed: only for a fresh simulation (add --headless)" in capsys.readouterr().err
    bad = tmp_path / "bad.yaml"
    bad.write_text("mission:\n  name: b\n  steps:\n    - wiat: {duration_s: 1}\n")
    assert main(["mission", "run", str(bad), "--data-dir", str(tmp_path)]) == 2  # checked before connecting
    assert f"{bad}:4:7 mission.steps[0].wiat: unknown step kind 'wiat'" in capsys.readouterr().err


def test_sigterm_cancels_the_mission_on_the_robot_before_exiting(light: Running, tmp_path: Path) -> None:
    mission = tmp_path / "long-wait.yaml"
    mission.write_text(LONG_WAIT)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(
        [sys.executable, "-m", "atemr", "mission", "run", str(mission), "--data-dir", str(tmp_path),
         "--timeout", "500000"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    assert proc.stdout is not None
    for line in proc.stdout:
        if "running" in line:
            break
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "SIGTERM: cancelling the mission on the robot" in err
    assert "mission 'long-wait': cancelled (interrupted (SIGTERM) in atemr mission run)" in out
    session = light.control.last or light.control.session
    assert session is not None and session.run.result["outcome"] == "cancelled"
