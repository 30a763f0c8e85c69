"""The in-process bus: python-can's virtual bus semantics without a copy per receiver, receivers woken without
polling, and python-can's own virtual buses on the same channel hearing it and heard by it."""

from __future__ import annotations

import configparser
import os
import subprocess
import sys
import threading
from pathlib import Path

import can
import pytest
from can.interfaces import virtual

from atemr.io.can.bus import unique_channel
from atemr.io.can.inprocess import InProcessBus

ROOT = Path(__file__).resolve().parents[3]


def frame(can_id: int, *data: int) -> can.Message:
    return can.Message(arbitration_id=can_id, data=bytes(data), is_extended_id=False)


def test_every_other_bus_on_the_channel_gets_each_frame_in_order_and_the_same_object():
    ch = unique_channel("inproc")
    elsewhere = unique_channel("inproc")
    with InProcessBus(ch) as a, InProcessBus(ch) as b, InProcessBus(ch) as c, InProcessBus(elsewhere) as other:
        sent = frame(0x141, 1, 2)
        a.send(sent)
        a.send(frame(0x142, 3))
        got_b = [b.recv(timeout=0), b.recv(timeout=0)]
        got_c = [c.recv(timeout=0), c.recv(timeout=0)]
        assert [m.arbitration_id for m in got_b] == [0x141, 0x142] and bytes(got_b[0].data) == b"\x01\x02"
        assert got_b[0] is got_c[0]  # one frame for all receivers: no copy per receiver
        assert got_b[0] is not sent and got_b[0].is_rx and got_b[0].channel == ch
        assert a.recv(timeout=0) is None and b.recv(timeout=0) is None and other.recv(timeout=0) is None


def test_a_sent_frame_does_not_change_when_the_sender_reuses_its_message():
    ch = unique_channel("inproc")
    with InProcessBus(ch) as a, InProcessBus(ch) as b:
        msg = frame(0x150, 1)
        a.send(msg)
        msg.data[0] = 99
        assert bytes(b.recv(timeout=0).data) == b"\x01"


def test_own_messages_come_back_only_when_asked_and_marked_as_sent():
    ch = unique_channel("inproc")
    with InProcessBus(ch, receive_own_messages=True) as a, InProcessBus(ch) as b:
        a.send(frame(0x151))
        echo = a.recv(timeout=0)
        assert echo is not None and not echo.is_rx and b.recv(timeout=0).is_rx


def test_a_waiting_receiver_is_woken_by_the_send():
    ch = unique_channel("inproc")
    with InProcessBus(ch) as tx, InProcessBus(ch) as rx:
        waiting = threading.Event()
        got: list[can.Message | None] = []

        def receive() -> None:
            waiting.set()
            got.append(rx.recv(timeout=60))

        thread = threading.Thread(target=receive)
        thread.start()
        waiting.wait()
        tx.send(frame(0x152, 7))
        thread.join(timeout=60)
        assert not thread.is_alive() and got[0] is not None and got[0].arbitration_id == 0x152


def test_a_notifier_delivers_and_stops():
    ch = unique_channel("inproc")
    with InProcessBus(ch) as tx, InProcessBus(ch) as rx:
        done = threading.Event()
        heard: list[int] = []

        def listener(msg: can.Message) -> None:
            heard.append(msg.arbitration_id)
            if len(heard) == 3:
                done.set()

        notifier = can.Notifier(rx, [listener], timeout=0.1)
        for can_id in (0x141, 0x142, 0x143):
            tx.send(frame(can_id))
        assert done.wait(timeout=60)
        notifier.stop()
        assert heard == [0x141, 0x142, 0x143]


def test_python_can_virtual_buses_on_the_channel_hear_it_and_are_heard():
    ch = unique_channel("inproc")
    with InProcessBus(ch) as ours, can.Bus(interface="virtual", channel=ch) as theirs:
        ours.send(frame(0x153, 1))
        heard = theirs.recv(timeout=0)
        assert heard is not None and heard.arbitration_id == 0x153 and heard.is_rx
        theirs.send(frame(0x154, 2))
        back = ours.recv(timeout=0)
        assert back is not None and back.arbitration_id == 0x154 and bytes(back.data) == b"\x02"


def test_filters_and_closing():
    ch = unique_channel("inproc")
    tx = InProcessBus(ch)
    rx = InProcessBus(ch, can_filters=[{"can_id": 0x150, "can_mask": 0x7F0}])
    tx.send(frame(0x141))
    tx.send(frame(0x152))
    assert rx.recv(timeout=60).arbitration_id == 0x152 and rx.recv(timeout=0) is None  # 0x141 filtered out
    rx.shutdown()
    rx.shutdown()  # idempotent
    with pytest.raises(can.CanOperationError):
        rx.send(frame(0x150))
    tx.shutdown()
    assert ch not in virtual.channels


def test_python_can_finds_the_interface_by_its_entry_point(tmp_path):
    """setup.cfg registers the bus in python-can's ``can.interface`` group as ``atemr``. A fresh interpreter that
    sees that declaration as installed metadata (a distribution written to ``tmp_path``, as pip would) opens it
    with ``can.Bus(interface="atemr")``: python-can's own entry-point loading, not a stand-in."""
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    declared = cfg["options.entry_points"]["can.interface"].strip()
    dist = tmp_path / "atemr_entry_points-0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: atemr-entry-points\nVersion: 0\n")
    (dist / "entry_points.txt").write_text(f"[can.interface]\n{declared}\n")
    code = ("import can; from atemr.io.can.inprocess import InProcessBus\n"
            "with can.Bus(interface='atemr', channel='probe') as bus: print(type(bus) is InProcessBus)")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROOT)]))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env, check=True)
    assert out.stdout.strip() == "True", out.stderr
