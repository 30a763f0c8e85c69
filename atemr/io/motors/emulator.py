"""An RMD-L-7015 on the CAN bus, emulated: answers the driver exactly as the real motor would.

It speaks either protocol version the RMD-L ships with (``protocol``: ``v1`` = V1.61, replies on
``0x140 + id``; ``v4`` = V4.2, replies on ``0x240 + id``, see `atemr.io.motors.rmd_protocol`). A command
its version does not have (0x88 or 0x9B to a V4.2 motor, 0x76 to a V1.61 one) is ignored like any frame
it cannot decode. A V4.2 motor clears its level-2 errors (under-voltage, over-temperature, ...) by itself
once the cause is gone and its level-1 errors (stall, over-current) only on a 0x76 system reset, after
which it sends no reply; a V1.61 motor keeps every flag until 0x9B. A flag V1.61 has no bit for (a
V4.2-only one such as ``MOTOR_STALL`` injected into the model) switches the output off but is not reported.

A scheduler component: every `tick` advances its `RmdMotorModel` to ``now`` and drains its own bus
with ``recv(timeout=0)`` (polled, no threads, so a simulation is repeatable), applies each request
addressed to its ID and sends the reply. When the model is unplugged it reads and ignores everything,
as a motor without power would. Frames it cannot decode are ignored, as the real firmware does.

CAN communication-timeout protection (the RMD's "communication interruption protection", configured in the
motor): when no speed command (0xA2) has arrived for ``comm_timeout_s`` (0.5 s by default, 0 = off) the
motor stops by itself (`RmdMotorModel.comm_timeout`: brake to zero, command forgotten, ``comm_timed_out``
set) until the next speed command, so a motor cut off from its driver never drives on a stale command
(docs/testing.md#what-the-robot-promises). Only speed commands count: status reads and MOTOR_STOP/RUN do
not keep a motor driving.
"""

from __future__ import annotations

import logging
import math
from typing import Self

import can

from atemr.clock import due
from atemr.errors import HardwareError, ProtocolError
from atemr.io.can.endpoint import MAX_FRAMES_PER_TICK
from atemr.io.motors.driver import check_motor_ids
from atemr.io.motors.model import RmdMotorModel
from atemr.io.motors.rmd_codec import RmdCommand, RmdRequest
from atemr.io.motors.rmd_protocol import AnyReply, MotorReading, RmdProtocol, rmd_protocol

log = logging.getLogger(__name__)

#: Default CAN communication timeout of the motor, s (no fresh command for 0.5 s → stop:
#: docs/testing.md#what-the-robot-promises).
COMM_TIMEOUT_S = 0.5


class RmdMotorEmulator:
    """Motor ``motor_id`` on ``bus`` (its own Bus instance on the robot's channel; closed by `shutdown`).

    ``model`` is the physics it reports; the simulator drives the wheel from the same object, so
    what the driver reads over CAN is what the simulated robot does. Exactly one owner may step a model:
    the emulator does (``steps_model=True``, standalone and in tests) unless the simulator already
    steps it, in which case pass ``steps_model=False`` and the emulator only answers.
    ``comm_timeout_s``: no speed command for this long → the motor stops by itself (0 = protection off).
    ``protocol``: the version it speaks, ``v1`` or ``v4`` (the ``devices.motors.protocol`` setting).
    """

    def __init__(self, bus: can.BusABC, motor_id: int, model: RmdMotorModel | None = None, *,
                 name: str | None = None, close_bus: bool = True, steps_model: bool = True,
                 comm_timeout_s: float = COMM_TIMEOUT_S, protocol: str | RmdProtocol = "v1") -> None:
        self.bus = bus
        self.motor_id = motor_id
        self.protocol = rmd_protocol(protocol)
        check_motor_ids((motor_id,), component=name or f"rmd_motor_{motor_id}", protocol=self.protocol)
        #: Where its requests arrive, and where it answers (the same ID in V1.61).
        self.can_id = self.protocol.request_id(motor_id)
        self.reply_id = self.protocol.reply_id(motor_id)
        self.model = model or RmdMotorModel()
        self.name = name or f"rmd_motor_{motor_id}"
        self.close_bus = close_bus
        self.steps_model = steps_model
        if not (math.isfinite(comm_timeout_s) and comm_timeout_s >= 0):
            raise HardwareError(f"comm_timeout_s must be a finite number >= 0 (0 = off), got {comm_timeout_s!r}",
                                component=self.name)
        self.comm_timeout_s = comm_timeout_s
        self.comm_timeouts = 0
        self.requests = 0
        self.ignored = 0
        self._last_t: float | None = None
        self._last_speed_t: float | None = None
        self._closed = False

    def start(self) -> None:
        """Nothing to start; present so a `Scheduler` also calls `shutdown` (it stops what it started)."""

    def tick(self, now: float) -> None:
        """Advance the physics to ``now`` and answer every pending request."""
        if self.steps_model and self._last_t is not None and now > self._last_t:
            self.model.step(now - self._last_t)
        self._clear_self_clearing()
        # a frame found now arrived after the previous tick: the protection counts from then, the earliest it can
        # have arrived, so a motor never drives longer than comm_timeout_s on one command whatever the tick rate
        # (a gap longer than the timeout itself, an emulator not ticked for a while, counts from now)
        prev = self._last_t
        arrived = prev if prev is not None and now - prev < self.comm_timeout_s else now
        self._last_t = now if self._last_t is None else max(self._last_t, now)
        for _ in range(MAX_FRAMES_PER_TICK):
            msg = self.bus.recv(timeout=0)
            if msg is None:
                break
            if msg.arbitration_id != self.can_id or msg.is_extended_id:
                continue
            if not self.model.plugged:
                continue
            try:
                request = self.protocol.decode_request(msg)
            except ProtocolError as exc:
                self.ignored += 1
                log.debug("%s ignores a frame: %s", self.name, exc)
                continue
            self.requests += 1
            if request.command is RmdCommand.SPEED_CONTROL:
                self._last_speed_t = arrived
            reply = self.answer(request)
            if reply is not None:
                self.bus.send(self.protocol.encode_reply(reply))
        self._comm_watchdog(now)

    def _clear_self_clearing(self) -> None:
        """A V4.2 motor drops its level-2 errors by itself once their cause is gone (nothing in V1.61)."""
        clearing = self.protocol.self_clearing(self.model.error_flags)
        if clearing:
            self.model.clear_errors(only=clearing)

    def _comm_watchdog(self, now: float) -> None:
        if self.comm_timeout_s <= 0:
            return
        if self._last_speed_t is None:
            self._last_speed_t = now  # powered up: the protection counts from the first tick
        if due(now, self._last_speed_t + self.comm_timeout_s) and not self.model.comm_timed_out:
            self.comm_timeouts += 1
            if self.model.target_radps != 0.0:
                log.warning("%s: no speed command for %.2f s: stopping (communication timeout)",
                            self.name, now - self._last_speed_t)
            self.model.comm_timeout()

    def answer(self, request: RmdRequest) -> AnyReply | None:
        """Apply ``request`` to the model and return the reply the real motor sends (None: it sends none)."""
        model, command = self.model, request.command
        if command is RmdCommand.MOTOR_OFF:
            model.off()
        elif command is RmdCommand.MOTOR_STOP:
            model.stop()
        elif command is RmdCommand.MOTOR_RUN:
            model.run()
        elif command is RmdCommand.SPEED_CONTROL:
            model.set_speed(request.speed_radps)
        elif command is RmdCommand.CLEAR_ERRORS:
            model.clear_errors()
        elif command is RmdCommand.SYSTEM_RESET:
            model.reset()
        return self.protocol.reply(self.motor_id, command, self.reading())

    def reading(self) -> MotorReading:
        """What the motor reports now, in SI units, before its protocol puts it on the wire."""
        model = self.model
        return MotorReading(temperature_c=model.temperature_c, voltage_v=model.voltage_v, errors=model.error_flags,
                            current_a=model.current_a, speed_radps=model.speed_radps, encoder=model.encoder,
                            angle_rad=model.position_rad)

    def shutdown(self) -> None:
        """Close the bus (when owned); idempotent."""
        if not self._closed:
            self._closed = True
            if self.close_bus:
                self.bus.shutdown()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()
