"""The live Foxglove server (``ui.foxglove``): a client speaking the Foxglove WebSocket protocol (the
``websockets`` package) subscribes to the scan and the agent's state and receives them while the robot runs,
decoded with `mcap-ros2-support` as a recording's; a client that never reads does not hold the robot up."""

from __future__ import annotations

import json
import socket
import struct
from contextlib import ExitStack
from typing import Any

import pytest
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
from websockets.sync.client import ClientConnection, connect

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.io.can.bus import unique_channel
from atemr.io.recording.topics import SCAN
from atemr.robot import build_robot

SUBPROTOCOL = "foxglove.sdk.v1"


def open_client(stack: ExitStack, port: int, **kwargs: Any) -> tuple[ClientConnection, dict[str, dict[str, Any]]]:
    """Connect and read the server's advertisements: topic → channel."""
    ws = stack.enter_context(connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL],  # type: ignore[list-item]
                                     open_timeout=10, **kwargs))
    channels: dict[str, dict[str, Any]] = {}
    while "/scan" not in channels:
        message = ws.recv(timeout=10)
        if isinstance(message, str):
            op = json.loads(message)
            if op.get("op") == "advertise":
                channels.update({c["topic"]: c for c in op["channels"]})
    return ws, channels


def subscribe(ws: ClientConnection, channels: dict[str, dict[str, Any]], topics: list[str]) -> dict[int, str]:
    subs = {i + 1: topic for i, topic in enumerate(topics)}
    ws.send(json.dumps({"op": "subscribe",
                        "subscriptions": [{"id": i, "channelId": channels[t]["id"]} for i, t in subs.items()]}))
    return subs


def drain(ws: ClientConnection, subs: dict[int, str], got: dict[str, list[tuple[int, bytes]]]) -> None:
    """Read what has arrived (binary message data: opcode 1, subscription id, log time, payload)."""
    while True:
        try:
            message = ws.recv(timeout=0.05)
        except TimeoutError:
            return
        if isinstance(message, bytes) and message[0] == 1:
            sub, log_time = struct.unpack_from("<IQ", message, 1)
            got.setdefault(subs[sub], []).append((log_time, message[13:]))


@pytest.fixture
def live_robot(tmp_path):
    config = load_config(environ={}, overrides={
        "data_dir": str(tmp_path), "can.channel": unique_channel("fox"), "ui.enabled": False,
        "secondary.portal_serve": False, "trace.enabled": False, "ui.foxglove.enabled": True,
        "ui.foxglove.port": 0, "trace.camera_hz": 10.0})
    robot = build_robot(config, realtime=False, clock=SimClock())
    with robot:
        yield robot


def test_a_client_receives_scans_and_the_agent_state_while_a_stalled_one_does_not_slow_the_robot(live_robot):
    robot = live_robot
    live = robot.parts.foxglove
    assert live is not None and live.host == "127.0.0.1"
    stack = ExitStack()
    good, channels = open_client(stack, live.port)
    assert channels["/scan"]["schemaName"] == "sensor_msgs/msg/LaserScan" and channels["/scan"]["encoding"] == "cdr"
    subs = subscribe(good, channels, ["/scan", "/agent/state", "/map"])
    # The stalled client reads one frame, then leaves its socket (a 4 kB receive buffer) unread.
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", live.port))
    stalled, _ = open_client(stack, live.port, max_queue=1, sock=sock)
    subscribe(stalled, channels, ["/scan", "/camera/image/compressed", "/map"])
    got: dict[str, list[tuple[int, bytes]]] = {}
    t = 0.0
    while t < 8.0:  # eight robot seconds: 80 scans and 80 camera frames (about 3 MB) towards the stalled client
        t += 0.5
        robot.run(until=t)
        drain(good, subs, got)
    for _ in range(20):
        drain(good, subs, got)
    # The stalled client goes as a frozen tab does when it is killed: its connection ends without a closing
    # handshake (which it could not finish: the server's closing frame waits behind the 3 MB it never read).
    sock.shutdown(socket.SHUT_RDWR)
    stack.close()
    scans = got["/scan"]
    assert len(scans) > 70, "the live client kept receiving while the other one stalled"
    assert scans[-1][0] >= 7.0e9
    schema = Schema(id=1, name=SCAN.schema_name, encoding="ros2msg", data=SCAN.schema_data)
    decode = DecoderFactory().decoder_for("cdr", schema)
    assert decode is not None
    scan = decode(scans[-1][1])
    assert len(scan.ranges) == 360 and scan.header.frame_id == "laser"
    states = [json.loads(data) for _, data in got["/agent/state"]]
    assert states and states[-1]["state"].startswith("IDLE")
    assert got["/map"], "the map is sent to a client as it subscribes (latched)"
    stats = {s.name: s for s in robot.scheduler.stats()}
    assert stats["recorder"].ticks == pytest.approx(8.0 * 20, abs=2), "every tick of the recorder ran"
