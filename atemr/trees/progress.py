"""What Exec reports while a task runs and when it ends: each mission step's status, times and errors.

`TaskProgress` watches the built task tree (one child per mission step, in order) after every agent tick:
a step is ``pending`` until it first runs, ``running`` (with the distance left to its target pose, if it
drives to one), then ``reached`` or ``failed``; steps after a failure stay ``not run``. When a step ends,
the robot's pose is recorded and, for steps that drive to a pose, the distance and heading error to that
pose. A step that drives to a named place is measured against the place's pose on the active map
(``places``), as it was when the task began. `TaskProgress.report` is the JSON the dashboard shows and
that a mission run prints.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import py_trees

from atemr.domain.places import NO_PLACES, Places
from atemr.msgs import Pose2D
from atemr.trees.behaviours import Leaf
from atemr.trees.leaves.motion import wrap_angle
from atemr.trees.leaves.navigation import FollowPathParams, PlaceParams
from atemr.trees.missions import Mission
from atemr.trees.params import PoseParams

Status = py_trees.common.Status


@dataclass
class StepRecord:
    """One step's outcome so far."""

    index: int
    kind: str
    name: str
    status: str = "pending"
    started_s: float | None = None
    finished_s: float | None = None
    target: Pose2D | None = None
    final_pose: Pose2D | None = None
    position_error_m: float | None = None
    heading_error_rad: float | None = None
    distance_left_m: float | None = None
    reason: str | None = None

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["duration_s"] = (None if self.started_s is None or self.finished_s is None
                             else self.finished_s - self.started_s)
        return out


def _target(step_spec: Any, places: Places) -> Pose2D | None:
    poses: list[Pose2D | None] = []
    for node in step_spec.walk():
        if isinstance(node.options, (PoseParams, FollowPathParams)):
            poses.append(node.options.pose())
        elif isinstance(node.options, PlaceParams):
            poses.append(places[node.options.place].pose if node.options.place in places else None)
    return poses[-1] if poses else None


def deepest_failure(root: py_trees.behaviour.Behaviour) -> tuple[py_trees.behaviour.Behaviour, str] | None:
    """The deepest failed node under ``root`` (py_trees iterates children before parents) and its words: a
    leaf's reason, else the node's feedback (a timeout decorator's "timed out after N s", its child having been
    stopped, not failed); None when nothing failed."""
    for node in root.iterate():
        if node.status == Status.FAILURE:
            return node, node.reason if isinstance(node, Leaf) and node.reason else str(node.feedback_message or "")
    return None


def _why_failed(node: py_trees.behaviour.Behaviour) -> str | None:
    """Why a step failed: its deepest failed node's words (a leaf's own, e.g. the navigator's), else the
    step's feedback."""
    found = deepest_failure(node)
    return (found[1] if found is not None else "") or node.feedback_message or None


def step_record(step: Any, places: Places = NO_PLACES) -> StepRecord:
    """A fresh (pending) record for a mission step (``places``: the active map's, for steps that name one)."""
    return StepRecord(step.index, step.kind, step.name, target=_target(step.spec, places))


class TaskProgress:
    """Follows ``root`` (the built task: a Sequence with one child per step of ``mission``)."""

    def __init__(self, mission: Mission, root: py_trees.behaviour.Behaviour, started_s: float,
                 places: Places = NO_PLACES) -> None:
        self.mission = mission
        self.places = places
        self.root = root
        self.started_s = started_s
        self.finished_s: float | None = None
        self.outcome = "running"
        self.reason: str | None = None
        self.steps = [step_record(s, places) for s in mission.steps]
        self._nodes = list(root.children) if len(root.children) == len(self.steps) else [root]

    def retarget(self, mission: Mission, steps: list[StepRecord]) -> None:
        """Follow an edited ``mission`` whose later steps were swapped into ``root`` (hot reload)."""
        self.mission, self.steps = mission, steps
        self._nodes = list(self.root.children) if len(self.root.children) == len(steps) else [self.root]

    def update(self, now: float, pose: Pose2D | None) -> None:
        """Read the step nodes' statuses after a tick."""
        for record, node in zip(self.steps, self._nodes, strict=False):
            if node.status == Status.RUNNING and record.started_s is None:
                record.started_s, record.status = now, "running"
            if node.status == Status.RUNNING and pose is not None and record.target is not None:
                record.distance_left_m = pose.distance_to(record.target)  # feedback while driving
            elif node.status in (Status.SUCCESS, Status.FAILURE) and record.finished_s is None:
                if record.started_s is None:
                    record.started_s = now
                record.finished_s = now
                record.status = "reached" if node.status == Status.SUCCESS else "failed"
                if node.status == Status.FAILURE:
                    record.reason = _why_failed(node)
                self._measure(record, pose)

    def _measure(self, record: StepRecord, pose: Pose2D | None) -> None:
        record.final_pose = pose
        if pose is not None and record.target is not None:
            record.position_error_m = record.distance_left_m = pose.distance_to(record.target)
            record.heading_error_rad = abs(wrap_angle(pose.yaw_rad - record.target.yaw_rad))

    def finish(self, outcome: str, now: float, pose: Pose2D | None, reason: str | None = None) -> None:
        """The task ended (``reached``, ``failed``, ``cancelled``, or the trigger that interrupted it) and why
        (the reason of the transition that ended it; kept unless it was reached)."""
        self.outcome, self.finished_s = outcome, now
        self.reason = None if outcome == "reached" else (reason or None)
        for record in self.steps:
            if record.status == "running":
                record.status, record.finished_s = "interrupted", now
                self._measure(record, pose)
            elif record.status == "pending":
                record.status = "not run"

    def report(self) -> dict[str, Any]:
        """JSON-able: the outcome, each step, and how long it all took."""
        end = self.finished_s
        return {
            "mission": self.mission.name,
            "file": self.mission.file,
            "outcome": self.outcome,
            "reason": self.reason,
            "started_s": self.started_s,
            "finished_s": end,
            "duration_s": None if end is None else end - self.started_s,
            "steps": [s.as_dict() for s in self.steps],
        }

