"""A recorded trace read back as a timeline: the agent as it was at any moment (pure, no I/O).

`TraceTimeline.frame(t)` gives the same picture as the live `atemr.fsm.agent.Agent.snapshot` (state, mode,
task, error, the state's tree and the Monitor with each node's status, tick count and reason, every
blackboard key with who wrote it and when, the last transitions) plus where the robot was, by applying the
records of `atemr.fsm.recording` up to ``t``. Frames are computed from the nearest checkpoint (one every
`CHECKPOINT_EVERY` records), so seeking in a long trace costs little.
"""

from __future__ import annotations

import bisect
import copy
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from atemr.errors import ConfigError

Record = dict[str, Any]
CHECKPOINT_EVERY = 500
#: Transitions a frame lists (the newest).
FRAME_TRANSITIONS = 20
#: Kinds that change what a frame shows (a step moves to the next of these).
CHANGES = frozenset({"tr", "st", "bb", "tree", "snap"})


@dataclass
class _Tree:
    id: int
    nodes: list[list[Any]]
    status: list[list[Any]]  # per node [status, ticks, why]


@dataclass
class _State:
    state: str = ""
    mode: str | None = None
    blackboard: dict[str, dict[str, Any]] = field(default_factory=dict)
    trees: dict[str, _Tree | None] = field(default_factory=dict)
    pose: dict[str, Any] | None = None
    transitions: list[Record] = field(default_factory=list)


class TraceTimeline:
    """The records of one trace file (`atemr.io.trace_file.read_trace`), ready to be scrubbed through."""

    def __init__(self, records: Sequence[Record], *, name: str = "", warnings: Sequence[str] = ()) -> None:
        self.name = name
        self.warnings = list(warnings)
        self.records = [r for r in records if isinstance(r.get("t"), (int, float))]
        heads = [r for r in self.records if r.get("k") == "head"]
        if not heads:
            raise ConfigError("not a recorded agent trace: no 'head' record", file=name or None)
        self.head = heads[0]
        self.times = [float(r["t"]) for r in self.records]
        if any(b < a for a, b in zip(self.times, self.times[1:], strict=False)):
            order = sorted(range(len(self.records)), key=lambda i: self.times[i])
            self.records = [self.records[i] for i in order]
            self.times = [self.times[i] for i in order]
        self.start_t = self.times[0]
        self.end_t = self.times[-1]
        self.change_times = sorted({t for t, r in zip(self.times, self.records, strict=True) if r["k"] in CHANGES})
        self._checkpoints: list[tuple[int, _State]] = [(0, _State())]
        state = _State()
        for i, record in enumerate(self.records):
            _apply(state, record)
            if (i + 1) % CHECKPOINT_EVERY == 0:
                self._checkpoints.append((i + 1, copy.deepcopy(state)))

    # -- summary -----------------------------------------------------------------------------------
    def transitions(self) -> list[Record]:
        """Every transition attempt recorded (as in ``atemr trace show``), oldest first."""
        out: list[Record] = []
        seen: set[tuple[Any, ...]] = set()
        for record in self.records:
            rows = record.get("transitions", []) if record["k"] == "snap" else [record] if record["k"] == "tr" else []
            for row in rows:
                key = (row.get("t"), row.get("trigger"), row.get("source"), row.get("dest"), row.get("accepted"))
                if key not in seen:
                    seen.add(key)
                    out.append({**{k: row.get(k) for k in ("t", "trigger", "source", "dest", "accepted", "reason",
                                                           "origin")},
                                **{k: row[k] for k in ("decision", "decided_by") if row.get(k)}})
        return out

    def summary(self) -> dict[str, Any]:
        return {"name": self.name, "start_t": self.start_t, "end_t": self.end_t, "records": len(self.records),
                "agent": self.head.get("agent"), "meta": self.head.get("meta", {}),
                "machine": self.head.get("machine"), "transitions": self.transitions(), "warnings": self.warnings,
                "steps": len(self.change_times)}

    # -- frames ------------------------------------------------------------------------------------
    def frame(self, t: float) -> dict[str, Any]:
        """The agent as recorded at robot time ``t`` (clamped to the trace), JSON-able."""
        t = min(max(float(t), self.start_t), self.end_t)
        upto = bisect.bisect_right(self.times, t)
        index = bisect.bisect_right([c[0] for c in self._checkpoints], upto) - 1
        start, checkpoint = self._checkpoints[index]
        state = copy.deepcopy(checkpoint)
        for record in self.records[start:upto]:
            _apply(state, record)
        bb = state.blackboard
        i = bisect.bisect_left(self.change_times, t)
        prev_t = self.change_times[i - 1] if i > 0 else None
        j = bisect.bisect_right(self.change_times, t)
        next_t = self.change_times[j] if j < len(self.change_times) else None
        return {
            "t": t, "name": self.head.get("agent"), "state": state.state, "mode": state.mode,
            "task": _value(bb, "/agent/task"), "error": _value(bb, "/agent/error"),
            "tree": _nested(state.trees.get("tree")), "monitor": _nested(state.trees.get("monitor")),
            "blackboard": dict(sorted(bb.items())), "pose": state.pose,
            "transitions": state.transitions[-FRAME_TRANSITIONS:], "machine": self.head.get("machine"),
            "prev_t": prev_t, "next_t": next_t, "start_t": self.start_t, "end_t": self.end_t,
        }


def _value(bb: dict[str, dict[str, Any]], key: str) -> Any:
    entry = bb.get(key)
    return None if entry is None else entry.get("value")


def _apply(state: _State, r: Record) -> None:  # noqa: PLR0912  one branch per trace record kind
    kind = r["k"]
    if kind == "snap":
        state.state = str(r.get("state") or "")
        state.mode = r.get("mode")
        bb = r.get("blackboard")
        if isinstance(bb, dict):
            state.blackboard = {str(k): dict(v) for k, v in bb.items() if isinstance(v, dict)}
        rows = r.get("transitions")
        if isinstance(rows, list):
            state.transitions = [dict(x) for x in rows if isinstance(x, dict)][-FRAME_TRANSITIONS:]
    elif kind == "tr":
        row = {**{k: r.get(k) for k in ("t", "trigger", "source", "dest", "accepted", "reason", "origin")},
               **{k: r[k] for k in ("decision", "decided_by") if r.get(k)}}
        if not state.transitions or state.transitions[-1] != row:
            state.transitions = [*state.transitions[-(FRAME_TRANSITIONS - 1):], row]
        if r.get("accepted") and r.get("dest"):
            state.state = str(r["dest"])
    elif kind == "bb":
        key = str(r.get("key"))
        if r.get("unset"):
            state.blackboard.pop(key, None)
        else:
            state.blackboard[key] = {"value": r.get("value"), "by": r.get("by", ""), "t": r["t"]}
        if key == "/agent/mode":
            state.mode = r.get("value")
    elif kind == "tree":
        nodes = r.get("nodes")
        slot = str(r.get("slot"))
        if isinstance(nodes, list) and nodes:
            state.trees[slot] = _Tree(int(r.get("id", 0)), nodes, [["INVALID", 0, ""] for _ in nodes])
        else:
            state.trees[slot] = None
    elif kind == "st":
        for tree in state.trees.values():
            if tree is not None and tree.id == r.get("id"):
                for change in r.get("n", []):
                    if isinstance(change, list) and len(change) == 4 and isinstance(change[0], int) \
                            and 0 <= change[0] < len(tree.status):
                        tree.status[change[0]] = [change[1], change[2], change[3]]
    elif kind == "tk":
        for tree in state.trees.values():
            if tree is not None and tree.id == r.get("id"):
                for change in r.get("n", []):
                    if isinstance(change, list) and len(change) == 2 and isinstance(change[0], int) \
                            and 0 <= change[0] < len(tree.status):
                        tree.status[change[0]][1] = change[1]
    elif kind == "pose":
        state.pose = {"x_m": r.get("x"), "y_m": r.get("y"), "yaw_rad": r.get("yaw")}


def _nested(tree: _Tree | None) -> dict[str, Any] | None:
    """The flat pre-order nodes as the live snapshot's nested ``{name, type, status, ticks, ...}``."""
    if tree is None:
        return None
    made: list[dict[str, Any]] = []
    root: dict[str, Any] | None = None
    for (name, kind, parent), (status, ticks, why) in zip(tree.nodes, tree.status, strict=True):
        node: dict[str, Any] = {"name": name, "type": kind, "status": status, "ticks": ticks, "feedback": why}
        made.append(node)
        if isinstance(parent, int) and 0 <= parent < len(made) - 1:
            made[parent].setdefault("children", []).append(node)
        elif root is None:
            root = node
    return root
