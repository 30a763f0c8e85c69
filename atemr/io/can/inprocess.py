"""An in-process CAN bus that hands frames over without copying them: the simulated robot's bus.

python-can's ``virtual`` interface deep-copies every frame once for each receiver (``copy.deepcopy`` of a
`can.Message`, several microseconds) and every receiver reads a locked `queue.Queue`. The simulated robot has
five participants on its bus (the primary, two motor emulators, the secondary core, the recorder's tap) that
poll it from their ticks, so most of the bus's cost was copies and locks: 13 ms of CPU per simulated second.

`InProcessBus` is a python-can interface (a `can.BusABC`: filters, ``send_periodic``, iteration and context
management come from python-can), registered with python-can as ``atemr`` through its ``can.interface`` entry
points (``can.Bus(interface="atemr", channel=...)``); the robot's ``virtual`` bus kind opens it. A sent frame is
stamped once (``timestamp``, ``channel``, ``is_rx``) and that one `can.Message` goes to every receiver: frames
are immutable once sent, and a receiver that wants to change one copies it. A receiver reads a deque, which
needs no lock; one that waits (a python-can Notifier thread) sleeps on an event that a sender sets, so nothing
polls.

It joins python-can's own table of virtual channels (``can.interfaces.virtual.channels``, under its lock), so a
python-can `VirtualBus` on the same channel name hears this bus and is heard by it; python-can's receivers get
their copies as python-can makes them. Tools and tests that open ``interface="virtual"`` on the robot's
channel keep working (``tests/io/can/test_inprocess.py`` checks both directions).
"""

from __future__ import annotations

import copy
import queue
import threading
import time
from collections import deque
from typing import Any

import can
from can.interfaces import virtual

__all__ = ["InProcessBus"]


class _Inbox:
    """One bus's received frames, as an entry of python-can's channel table (python-can calls ``put``)."""

    __slots__ = ("frames", "ready")

    def __init__(self) -> None:
        self.frames: deque[can.Message] = deque()
        #: Set when a frame arrives for a receiver that may be waiting; a polling receiver never clears it, so
        #: senders then skip the event's lock.
        self.ready = threading.Event()

    def put(self, msg: can.Message, block: bool = True, timeout: float | None = None) -> None:
        """Receive ``msg`` (the interface of `queue.Queue` that python-can's `VirtualBus.send` uses)."""
        self.frames.append(msg)
        if not self.ready.is_set():
            self.ready.set()


class InProcessBus(can.BusABC):
    """Every `InProcessBus` and python-can `VirtualBus` on the same ``channel`` in this process hears the
    others' frames (not its own, unless ``receive_own_messages``). ``preserve_timestamps`` keeps the
    sender's timestamp instead of the time of sending, as python-can's virtual bus does."""

    def __init__(self, channel: Any = "channel-0", *, receive_own_messages: bool = False,
                 preserve_timestamps: bool = False, **kwargs: Any) -> None:
        super().__init__(channel=channel, receive_own_messages=receive_own_messages, **kwargs)
        self.channel_id = channel
        self.channel_info = f"in-process bus channel {channel}"
        self.receive_own_messages = receive_own_messages
        self.preserve_timestamps = preserve_timestamps
        self._inbox = _Inbox()
        self._open = True
        with virtual.channels_lock:
            self._members = virtual.channels.setdefault(channel, [])
            self._members.append(self._inbox)  # type: ignore[arg-type]  # duck-typed: python-can calls put()

    def _check_if_open(self) -> None:
        if not self._open:
            raise can.CanOperationError("Cannot operate on a closed bus")

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Stamp one copy of ``msg`` and hand it to every other bus on the channel."""
        self._check_if_open()
        frame = can.Message(
            timestamp=msg.timestamp if self.preserve_timestamps else time.time(), arbitration_id=msg.arbitration_id,
            is_extended_id=msg.is_extended_id, is_remote_frame=msg.is_remote_frame, is_error_frame=msg.is_error_frame,
            channel=self.channel_id, dlc=msg.dlc, data=bytes(msg.data), is_fd=msg.is_fd, is_rx=True,
            bitrate_switch=msg.bitrate_switch, error_state_indicator=msg.error_state_indicator, check=False,
        )
        all_sent = True
        for member in self._members:
            if member is self._inbox:
                if self.receive_own_messages:
                    echo = copy.copy(frame)
                    echo.is_rx = False
                    member.put(echo)
            elif type(member) is _Inbox:
                member.frames.append(frame)
                if not member.ready.is_set():
                    member.ready.set()
            else:  # a python-can VirtualBus: its receivers get their own copy, as python-can makes them
                try:
                    member.put(copy.deepcopy(frame), block=True, timeout=timeout)
                except queue.Full:
                    all_sent = False
        if not all_sent:
            raise can.CanOperationError("Could not send message to one or more recipients")

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        self._check_if_open()
        inbox = self._inbox
        try:
            return inbox.frames.popleft(), False
        except IndexError:
            if timeout is not None and timeout <= 0:
                return None, False
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            inbox.ready.clear()  # then look again: a frame put before the clear is in the deque already
            try:
                return inbox.frames.popleft(), False
            except IndexError:
                pass
            remaining = None if deadline is None else deadline - time.monotonic()
            if not self._open or (remaining is not None and remaining <= 0):  # closed while waiting: as a timeout
                return None, False
            inbox.ready.wait(remaining)

    def shutdown(self) -> None:
        """Leave the channel (and wake a receiver waiting on this bus); idempotent."""
        super().shutdown()
        if not self._open:
            return
        self._open = False
        with virtual.channels_lock:
            self._members.remove(self._inbox)  # type: ignore[arg-type]
            if not self._members and virtual.channels.get(self.channel_id) is self._members:
                del virtual.channels[self.channel_id]
        self._inbox.ready.set()
