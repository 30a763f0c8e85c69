"""Leaves about time: waiting on the agent's injected clock."""

from __future__ import annotations

from dataclasses import dataclass, field

import py_trees

from atemr.clock import due
from atemr.trees.behaviours import Leaf, behaviours

Status = py_trees.common.Status


@dataclass(frozen=True)
class WaitParams:
    duration_s: float = field(default=0.0, metadata={"min": 0.0, "max": 86_400.0, "required": True})


@behaviours.register("Wait")
class Wait(Leaf):
    """RUNNING until ``duration_s`` of agent time has passed since it started, then SUCCESS."""

    Params = WaitParams
    summary = "wait duration_s seconds of robot time"

    def initialise(self) -> None:
        self._until = self.ctx.now + self.params.duration_s

    def update(self) -> py_trees.common.Status:
        left = self._until - self.ctx.now
        self.feedback_message = f"{max(left, 0.0):.1f} s left"
        return Status.SUCCESS if due(self.ctx.now, self._until) else Status.RUNNING
