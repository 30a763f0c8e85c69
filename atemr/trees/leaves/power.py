"""Leaves of the power handshake with the secondary core (0x150) and the end of the agent."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import py_trees

from atemr.domain.status import PowerState
from atemr.trees.behaviours import Leaf, behaviours

Status = py_trees.common.Status

_STATES = {"initialising": PowerState.INITIALISING, "running": PowerState.RUNNING,
           "poweroff_ack": PowerState.POWER_OFF_ACK}


@dataclass(frozen=True)
class SetPowerStateParams:
    state: Literal["initialising", "running", "poweroff_ack"] = field(
        default="running", metadata={"required": True, "help": "0x150 byte 0: 0, 1 or 2"}
    )


@behaviours.register("SetPowerState")
class SetPowerState(Leaf):
    """Write 0x150 byte 0: ``running`` acknowledges power-on, ``poweroff_ack`` acknowledges power-off."""

    Params = SetPowerStateParams
    summary = "send the 0x150 power byte (running / poweroff_ack)"

    def update(self) -> py_trees.common.Status:
        if self.ctx.link is None:
            return self.fail("no secondary-core link to acknowledge on")
        self.ctx.link.set_power_state(_STATES[self.params.state])
        return Status.SUCCESS


@behaviours.register("Halt")
class Halt(Leaf):
    """Mark the agent halted (power-off finished): the agent stops ticking trees and reports it."""

    summary = "end the agent (after the power-off acknowledgement)"

    def update(self) -> py_trees.common.Status:
        self.ctx.halted = True
        return Status.SUCCESS
