"""One end of the inter-core protocol on a polled python-can bus: the part both cores share.

The primary's `atemr.io.secondary_link.SecondaryLink` and the emulated board
`atemr.io.secondary_emulator.board.SecondaryCore` talk to each other over the same codec, the same way: each
owns a bus, reads it with ``recv(timeout=0)`` from its own ``tick`` (no thread, so a simulation is
deterministic), counts what came and went, and must survive a bus that fails. `PolledCanEndpoint` holds that
once, as template methods in the manner of python-can's ``BusABC`` (``send``/``_recv_internal``): the base
drains and decodes, a subclass says what a message means (`PolledCanEndpoint._on_message`) and, if it cares,
what to do with a frame outside the protocol or one that does not decode. Written twice, the two copies had
started to drift.

The motors' side (`atemr.io.motors.driver.RmdDriver`, `atemr.io.motors.emulator.RmdMotorEmulator`) is not
an endpoint of this kind: it speaks the RMD protocol, not this one, and a failing bus is a fault there (it
stops the motors), where here it is counted and the heartbeat decides.
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from dataclasses import dataclass

import can

from atemr.errors import ProtocolError
from atemr.io.can.protocol import Message, decode, is_protocol_id

#: Frames read per tick at most, so a flooded bus cannot stall the scheduler.
MAX_FRAMES_PER_TICK = 256


@dataclass
class EndpointCounters:
    """What an endpoint saw on its bus (diagnostics and tests read them; nothing decides on them)."""

    frames_in: int = 0
    frames_out: int = 0
    bad_frames: int = 0
    bus_errors: int = 0
    last_bad_frame: str | None = None


class PolledCanEndpoint(ABC):
    """``bus`` read and written from the owner's tick; the bus belongs to the caller.

    `_send` never raises: a failed send is counted in ``bus_errors`` and logged once when sending starts
    failing and once when it works again, because a bus-off lasts many ticks and the periodic frames are
    repeated anyway (the heartbeat notices a link that stays down). `_receive` reads at most
    `MAX_FRAMES_PER_TICK` frames and hands each decoded one to `_on_message`.

    ``logger`` is the subclass's module logger, so its records keep the name they had before the two
    cores shared this code (log levels and filters are set by those names).
    """

    logger: logging.Logger = logging.getLogger(__name__)

    def __init__(self, bus: can.BusABC, *, name: str, counters: EndpointCounters | None = None) -> None:
        self.bus = bus
        self.name = name
        #: A subclass with counters of its own passes a subclass of `EndpointCounters`.
        self.counters = counters if counters is not None else EndpointCounters()
        self._send_failing = False

    def _send(self, msg: can.Message) -> bool:
        """Put ``msg`` on the bus; False (counted, logged) if the bus refused it."""
        try:
            self.bus.send(msg)
        except can.CanError as exc:
            self.counters.bus_errors += 1
            # Warn when sending starts failing, not on every frame of a bus-off at 50 Hz.
            level = logging.DEBUG if self._send_failing else logging.WARNING
            self._send_failing = True
            self.logger.log(level, "%s: cannot send 0x%03X: %s", self.name, msg.arbitration_id, exc)
            return False
        if self._send_failing:
            self._send_failing = False
            self.logger.warning("%s: sending works again", self.name)
        self.counters.frames_out += 1
        return True

    def _receive(self, now: float) -> None:
        """Read what the bus holds now, up to `MAX_FRAMES_PER_TICK`; a failing ``recv`` ends this tick's read."""
        for _ in range(MAX_FRAMES_PER_TICK):  # a flooded bus cannot stall the scheduler
            try:
                frame = self.bus.recv(timeout=0)
            except can.CanError as exc:
                self.counters.bus_errors += 1
                self.logger.warning("%s: receive failed: %s", self.name, exc)
                return
            if frame is None:
                return
            if not is_protocol_id(frame.arbitration_id):
                self._on_foreign_frame(frame, now)
                continue
            self.counters.frames_in += 1
            try:
                msg = decode(frame)
            except ProtocolError as exc:
                self.counters.bad_frames += 1
                self.counters.last_bad_frame = str(exc)
                self.logger.debug("%s: bad frame ignored: %s", self.name, exc)
                self._on_bad_frame(frame, now)
                continue
            self._on_message(msg, now)

    @abstractmethod
    def _on_message(self, msg: Message, now: float) -> None:
        """Act on one decoded protocol message that arrived by ``now``."""

    def _on_foreign_frame(self, frame: can.Message, now: float) -> None:  # noqa: B027  # optional hook
        """A frame outside the protocol's IDs: the motors share the bus, so by default it is none of ours."""

    def _on_bad_frame(self, frame: can.Message, now: float) -> None:  # noqa: B027  # optional hook
        """A frame on a protocol ID that did not decode (already counted): by default nothing more to do."""
