"""Hot reload of the agent document and of a running mission, at a safe boundary, keeping the blackboard.

What the agent swaps is always already validated (`atemr.fsm.spec.parse_agent`, `atemr.trees.missions
.parse_mission`): an invalid file never reaches it, and the dashboard shows the error with its line and
column. Where the new version goes in:

- the agent document only in IDLE (`Agent.reload`); requested in any other state (mid-EXEC, mapping,
  error) it is *deferred* and applied on the first tick in IDLE. A newer request replaces a deferred one;
- a mission only between its steps: the running step finishes as it was, and the steps after it come from
  the new file (`swap_pending_steps`). Steps that already ran (or the running one) cannot change; a
  mission file that is not running is simply what its next start loads.

Each request is a `ReloadReport` (queued → applied / deferred / refused / invalid), with the unified diff
of the old and new text, kept by the agent for the dashboard.
"""

from __future__ import annotations

import difflib
from dataclasses import asdict, dataclass
from typing import Any, Literal

import py_trees

from atemr.errors import ConfigError
from atemr.trees.builder import NodeSpec, build, setup_tree
from atemr.trees.context import AgentContext
from atemr.trees.missions import Mission
from atemr.trees.progress import StepRecord, TaskProgress, step_record

ReloadKind = Literal["agent", "mission"]
ReloadStatus = Literal["queued", "deferred", "applied", "refused", "invalid", "unchanged", "superseded", "saved"]


@dataclass
class ReloadReport:
    """One reload request and what became of it (JSON-able with `as_dict`)."""

    kind: ReloadKind
    file: str
    t: float
    status: ReloadStatus = "queued"
    reason: str = ""
    diff: str = ""
    origin: str = ""
    #: For an invalid file: ``{"message", "line", "column", "path"}`` of the first error.
    error: dict[str, Any] | None = None
    applied_t: float | None = None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def invalid(cls, kind: ReloadKind, file: str, t: float, exc: ConfigError, *, diff: str = "",
                origin: str = "") -> ReloadReport:
        """A file that did not validate: nothing is swapped; the error keeps its line and column."""
        error = {"message": exc.reason, "line": exc.line, "column": exc.column, "path": exc.path,
                 "text": str(exc)}
        return cls(kind, file, t, "invalid", f"not reloaded, the running version stays: {exc}", diff, origin, error)


def unified_diff(old: str, new: str, file: str) -> str:
    """``diff -u`` of two versions of ``file`` (empty when equal)."""
    lines = difflib.unified_diff(old.splitlines(keepends=True), new.splitlines(keepends=True),
                                 fromfile=f"{file} (running)", tofile=f"{file} (edited)")
    return "".join(line if line.endswith("\n") else line + "\n" for line in lines)


def same_tree(a: NodeSpec, b: NodeSpec) -> bool:
    """Whether two node specs build the same behaviours (where they were written does not count)."""
    return (a.type, a.name, a.kind, a.options, len(a.children)) == (b.type, b.name, b.kind, b.options,
                                                                     len(b.children)) \
        and all(same_tree(x, y) for x, y in zip(a.children, b.children, strict=True))


def swap_pending_steps(progress: TaskProgress, mission: Mission, context: AgentContext) -> str:
    """Replace the steps after the running one by those of ``mission``; returns what was done.

    Raises `ConfigError` (nothing changed) when the running task is not a mission of steps. The
    running step and those before it stay as they are (a running leaf is never swapped under the robot).
    """
    root = progress.root
    nodes = list(root.children)
    if len(nodes) != len(progress.steps) or not isinstance(root, py_trees.composites.Sequence):
        raise ConfigError("the running task is not a mission of steps: nothing to swap")
    running = [i for i, r in enumerate(progress.steps) if r.status in ("running", "reached", "failed")]
    keep = (max(running) + 1) if running else 0
    changed_done = [i for i in range(min(keep, len(mission.steps)))
                    if i >= len(progress.mission.steps) or not same_tree(mission.steps[i].spec,
                                                                         progress.mission.steps[i].spec)]
    built: list[py_trees.behaviour.Behaviour] = []
    for step in mission.steps[keep:]:
        node = build(step.spec)
        setup_tree(node, context)
        built.append(node)
    for node in nodes[keep:]:
        root.remove_child(node)
    for node in built:
        root.add_child(node)
    records: list[StepRecord] = progress.steps[:keep] + [step_record(s, progress.places) for s in mission.steps[keep:]]
    progress.retarget(mission, records)
    context.task = mission
    note = f"steps {keep}-{len(mission.steps) - 1} now come from the new file" if len(mission.steps) > keep \
        else "the new file has no steps after the running one: the mission ends after it"
    if changed_done:
        note += (f"; step(s) {', '.join(map(str, changed_done))} already ran or are running and stay as they "
                 "were (the change applies at the next start)")
    return note
