"""Mapping leaves: start SLAM, save the map under a name, stop and drop it.

The MAPPING state starts and ends its session through transition callbacks (the operator's BEGIN MAP,
SAVE, DISCARD: a refusal then reaches the dashboard as the transition's reason); these leaves let a tree
or a mission do the same on its own, e.g. a mission that re-maps a room after the furniture moved while it
drives a route. Both paths go through `start_mapping` and `finish_mapping`, so the agent context's
``mapping_active`` always tells whether a session runs, whoever started it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import py_trees

from atemr.errors import AtemrError
from atemr.trees.behaviours import Leaf, behaviours
from atemr.trees.context import AgentContext

Status = py_trees.common.Status

#: A map name that is safe as a file name (it becomes ``name.pgm`` + ``name.yaml``).
MAP_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


def map_name_problem(name: object) -> str | None:
    """Why ``name`` cannot name a stored map, or None."""
    if not isinstance(name, str) or not MAP_NAME.match(name):
        return f"map name must be 1-64 letters, digits, '_', '.' or '-' (not starting with one), got {name!r}"
    return None


def start_mapping(ctx: AgentContext) -> None:
    """Start a SLAM session unless one runs; raises the port's `AtemrError` when mapping is not available."""
    if not ctx.mapping_active:
        ctx.port.begin_mapping()
        ctx.mapping_active = True


def finish_mapping(ctx: AgentContext, save_as: str | None) -> None:
    """End the session: save it as ``save_as`` (the map becomes active) or drop it (None). A failed save
    raises and leaves the session running (the robot's map service keeps it), so nothing is lost."""
    ctx.port.end_mapping(save_as)
    ctx.mapping_active = False


@behaviours.register("StartMapping")
class StartMapping(Leaf):
    """Start SLAM at the current pose (SUCCESS; already running is fine), FAILURE when the robot cannot map."""

    summary = "start a SLAM session (mapping) at the current pose"

    def update(self) -> py_trees.common.Status:
        try:
            start_mapping(self.ctx)
        except AtemrError as exc:
            return self.fail(f"cannot start mapping: {exc}")
        self.feedback_message = "mapping"
        return Status.SUCCESS


@dataclass(frozen=True)
class SaveMapParams:
    name: str = field(default="", metadata={"required": True,
                                            "help": "file-name-safe map name: letters, digits, _ . -"})

    def validate(self) -> None:
        problem = map_name_problem(self.name)
        if problem:
            raise ValueError(problem)


@behaviours.register("SaveMap")
class SaveMap(Leaf):
    """Stop SLAM and store the map as ``name`` (it becomes the active map); FAILURE when no session runs or
    the save fails. A failed save leaves the session running (a tree may retry, e.g. under a Retry decorator);
    a mission that fails here ends Exec, whose exit drops the unsaved map (logged)."""

    Params = SaveMapParams
    summary = "stop mapping and save the map under a name (it becomes active)"

    def update(self) -> py_trees.common.Status:
        if not self.ctx.mapping_active:
            return self.fail("no mapping session to save")
        try:
            finish_mapping(self.ctx, self.params.name)
        except AtemrError as exc:
            return self.fail(f"saving map '{self.params.name}' failed: {exc}")
        self.feedback_message = f"saved as '{self.params.name}'"
        return Status.SUCCESS


@behaviours.register("StopMapping")
class StopMapping(Leaf):
    """Stop SLAM and drop the unsaved map (SUCCESS, also when no session runs)."""

    summary = "stop mapping and drop the unsaved map"

    def update(self) -> py_trees.common.Status:
        if not self.ctx.mapping_active:
            self.feedback_message = "no mapping session"
            return Status.SUCCESS
        try:
            finish_mapping(self.ctx, None)
        except AtemrError as exc:
            return self.fail(f"cannot stop mapping: {exc}")
        self.feedback_message = "map dropped"
        return Status.SUCCESS
