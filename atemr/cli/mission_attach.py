"""``atemr mission run/status/cancel`` on the robot that is already running (``./run``), through its control
socket (`atemr.io.control_socket`, commands in `atemr.robot.control`).

``run`` validates the mission here first (a typo is reported with file:line:col before anything is sent),
then the robot validates it again and runs it; progress lines are printed as they come (``--json``: only
the result, the same JSON as a headless run). Ctrl-C or SIGTERM cancels the mission on the robot, prints
how it ended, and exits 128 + the signal number; otherwise the exit code is 0 only when the mission was
completed. Only the user the robot runs as can connect (the socket is mode 0600).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # only what runs a command imports what it needs: `atemr --help` stays fast
    from atemr.io.control_client import ControlClient
from atemr.cli.signals import Interrupted, interrupt_on_signals
from atemr.errors import ConfigError, ControlError

#: Real seconds to wait for the robot's last answer after asking it to cancel.
CANCEL_WAIT_S = 30.0


def socket_of(args: argparse.Namespace) -> Path:
    """The running robot's control socket: ``--socket``, else from the configuration (``--data-dir``)."""
    from atemr.config import load_config
    from atemr.io.control_socket import control_socket_path

    config = load_config(args.config, overrides={"data_dir": args.data_dir, "control.socket": args.socket})
    return control_socket_path(config)


def start_request(args: argparse.Namespace) -> dict[str, Any]:
    """The ``start`` request, the mission checked here first (the robot checks it again)."""
    from atemr.trees.missions import load_mission, mission_from_goals

    headless_only = (("--world", args.world), ("--seed", args.seed), ("--start", args.start),
                     ("--trace", args.trace), ("--kidnap", args.kidnap))
    given = ", ".join(option for option, value in headless_only if value is not None)
    if given:
        raise ConfigError(f"{given}: only for a fresh simulation (add --headless); the running robot already has "
                          f"its world, its pose is set on the dashboard, and it records its own trace",
                          path="atemr mission run")
    if not (args.timeout > 0 and math.isfinite(args.timeout)):
        raise ConfigError(f"must be a positive number of seconds, got {args.timeout}", path="argument --timeout")
    request: dict[str, Any] = {"cmd": "start", "timeout_s": args.timeout, "follow": True}
    if args.file is not None:
        load_mission(args.file)  # file:line:col errors here, before the robot is asked
        request["mission"] = {"text": args.file.read_text(encoding="utf-8"), "file": str(args.file)}
    else:
        mission_from_goals(args.goal)
        request["goals"] = [asdict(g) for g in args.goal]
    return request


def run_attached(args: argparse.Namespace) -> int:
    """``atemr mission run`` without ``--headless``."""
    from atemr.cli.mission import print_summary
    from atemr.io.control_client import ControlClient

    request = start_request(args)
    path = socket_of(args)
    with ControlClient(path) as client, interrupt_on_signals():
        try:
            started = client.request(request)
            client.set_timeout(None)  # the robot bounds the mission (--timeout); wait as long as it runs
            if not args.json:
                print(f"mission '{started['mission']}' started on the robot ({len(started['steps'])} steps); "
                      f"Ctrl-C cancels it", flush=True)
            result = follow(client, started["t"], quiet=args.json)
            signum = None
        except Interrupted as interrupt:
            signum = interrupt.signum
            cancelled = cancel_and_wait(path, client, interrupt)
            if cancelled is None:
                return 128 + signum
            result = cancelled
    if args.json:
        print(json.dumps(result, indent=2, default=str))
    else:
        print_summary(result)
    if signum is not None:
        return 128 + signum
    return 0 if result["outcome"] == "reached" else 1


def follow(client: ControlClient, t0: float, *, quiet: bool) -> dict[str, Any]:
    """Print each answer as a progress line until the result comes; return the result."""
    for answer in client.answers():
        event = answer.get("event")
        if event == "result":
            return dict(answer["result"])
        if quiet:
            continue
        stamp = f"[{answer.get('t', t0) - t0:7.1f} s]"
        if event == "state":
            print(f"{stamp} agent: {answer['state']}", flush=True)
        elif event == "step":
            print(f"{stamp} {step_line(answer['step'])}", flush=True)
        elif event == "phase" and answer["phase"] == "confirming":
            print(f"{stamp} waiting for the operator to confirm the mission on the dashboard (the robot's "
                  f"autonomy level is {answer['autonomy']})", flush=True)
    raise ControlError("the robot stopped answering before the mission ended")  # answers() never ends


def step_line(step: dict[str, Any]) -> str:
    line = f"step {step['index']} ({step['name']}): {step['status']}"
    if step.get("position_error_m") is not None and step["status"] != "running":
        line += (f", {step['position_error_m']:.2f} m / {math.degrees(step['heading_error_rad']):.1f} deg "
                 f"from the target")
    return line


def cancel_and_wait(path: Path, client: ControlClient, interrupt: Interrupted) -> dict[str, Any] | None:
    """Cancel the mission on the robot and read its last answer (the result of the cancelled run).

    None when there was nothing to cancel yet: closing this connection then cancels the mission if the
    robot starts it after all (the connection that starts a mission owns it)."""
    from atemr.io.control_client import ControlClient

    print(f"{interrupt.args[0]}: cancelling the mission on the robot...", file=sys.stderr, flush=True)
    try:
        with ControlClient(path) as other:
            other.request({"cmd": "cancel", "reason": f"interrupted ({interrupt.args[0]}) in atemr mission run"})
    except ControlError as exc:
        print(f"nothing cancelled: {exc}", file=sys.stderr, flush=True)
        return None
    client.set_timeout(CANCEL_WAIT_S)
    return follow(client, 0.0, quiet=True)


def status_command(args: argparse.Namespace) -> int:
    """``atemr mission status``: the agent's state and its task, from the running robot."""
    from atemr.io.control_client import ControlClient

    with ControlClient(socket_of(args)) as client:
        status = client.request({"cmd": "status"})["status"]
    if args.json:
        print(json.dumps(status, indent=2, default=str))
        return 0
    print(f"agent {status['state']} (mode {status['mode']}) at t={status['t']:.1f} s"
          + ("" if status["error"] is None else f"; last error: {status['error']}"))
    progress = status["task_progress"]
    if progress is not None:
        done = sum(1 for s in progress["steps"] if s["status"] in ("reached", "failed"))
        print(f"running '{progress['mission']}': {done}/{len(progress['steps'])} steps done")
        for step in progress["steps"]:
            print(f"  {step_line(step)}")
    elif status["last_task"] is not None:
        last = status["last_task"]
        print(f"last task '{last['mission']}': {last['outcome']}")
    pose = status["pose"]
    if pose is not None:
        print(f"pose ({pose['x_m']:.2f}, {pose['y_m']:.2f}, {pose['yaw_rad']:.2f})")
    return 0


def cancel_command(args: argparse.Namespace) -> int:
    """``atemr mission cancel``: stop the mission (or the dashboard's task) on the running robot."""
    from atemr.io.control_client import ControlClient, checked

    with ControlClient(socket_of(args)) as client:
        answer = checked(client.request({"cmd": "cancel"}))
    print(f"cancelled '{answer['cancelled']}'")
    return 0
