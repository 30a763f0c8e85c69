"""`AgentRecorder`: the agent's hooks turned into trace records (no I/O: records go to an injected sink,
on the robot `atemr.io.trace_file.TraceWriter.write`).

What is recorded, each a flat JSON object with ``k`` (kind) and ``t`` (robot time, s):

=========  ==========================================================================================
``head``   first of every file part: format version, agent name, ``meta`` (world, map, seed, ...), the
           machine (states and transitions) for drawing
``snap``   after ``head``: the state, the mode, and every blackboard key ``{value, by, t}`` at that time
``tr``     every transition attempt: ``trigger, source, dest, accepted, reason, origin`` (+ ``decision,
           decided_by`` for an operator autonomy decision: requested, confirmed, denied, timed_out, superseded)
``tree``   a tree was built (``slot`` "tree" for the current state's, "monitor"): ``id`` and ``nodes``, the
           nodes in pre-order as ``[name, type, parent index]`` (parent -1 for the root); ``nodes`` null
           when the state has no tree
``st``     node status changes of tree ``id`` after a tick: ``n`` = ``[[index, status, ticks, why], ...]``
``tk``     tick counts that changed, once a second (`TICKS_PERIOD_S`) per tree: ``id``, ``n`` =
           ``[[index, ticks], ...]`` (a status change carries its count at once)
``bb``     a blackboard key changed value: ``key, value, by`` (``unset`` true when removed); a value longer
           than `MAX_VALUE_CHARS` as JSON is kept as its cut text
``pose``   the robot's pose at ``pose_hz``: ``x, y, yaw`` (map frame, m and rad)
=========  ==========================================================================================

``/agent/now`` is not recorded (it is the tick's time, which every record has). `atemr.fsm.trace_timeline`
reads these back into the picture of any moment.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import py_trees

from atemr.clock import due
from atemr.fsm.machine import TransitionRecord
from atemr.trees.behaviours import Leaf
from atemr.trees.blackboard_watch import BlackboardWrite

if TYPE_CHECKING:
    from atemr.fsm.agent import Agent

VERSION = 1
MAX_VALUE_CHARS = 4000
UNRECORDED_KEYS = frozenset({"/agent/now"})
#: How often the tick counts of running nodes are recorded (robot seconds).
TICKS_PERIOD_S = 1.0
Record = dict[str, Any]


def t3(t: float) -> float:
    return round(float(t), 3)


def why_of(node: py_trees.behaviour.Behaviour) -> str:
    """A node's explanation as the live view shows it: a leaf's reason, else its feedback message."""
    reason = node.reason if isinstance(node, Leaf) else ""
    return str(reason or node.feedback_message or "")


@dataclass
class _Seen:
    root: py_trees.behaviour.Behaviour | None
    id: int
    nodes: list[py_trees.behaviour.Behaviour] = field(default_factory=list)
    last: list[tuple[str, str]] = field(default_factory=list)
    ticks: list[int] = field(default_factory=list)


class AgentRecorder:
    """Subscribes to ``agent``'s hooks and writes records to ``sink`` (module docstring).

    ``meta`` goes into every ``head`` record (the world, the map, the seed: what a replay needs to know);
    ``pose_hz`` is the rate of ``pose`` records (the agent's port pose, for the replay map).
    """

    def __init__(self, agent: Agent, sink: Callable[[Record], None], *, pose_hz: float = 2.0,
                 meta: dict[str, Any] | None = None) -> None:
        self.agent = agent
        self.sink = sink
        self.pose_period = 1.0 / pose_hz if pose_hz > 0 else float("inf")
        self.meta = dict(meta or {})
        self._slots: dict[str, _Seen] = {}
        self._ids = 0
        self._last_pose_t = float("-inf")
        self._last_ticks_t = float("-inf")
        self._pose: Record | None = None
        self.attached = False

    def attach(self) -> AgentRecorder:
        """Start recording (idempotent)."""
        if not self.attached:
            self.attached = True
            self.agent.listeners.append(self.on_transition)
            self.agent.tree_listeners.append(self.on_tree)
            self.agent.tick_listeners.append(self.on_tick)
        return self

    def detach(self) -> None:
        if self.attached:
            self.attached = False
            self.agent.listeners.remove(self.on_transition)
            self.agent.tree_listeners.remove(self.on_tree)
            self.agent.tick_listeners.remove(self.on_tick)

    # -- the preamble of a file part -----------------------------------------------------------------
    def preamble(self) -> list[Record]:
        """``head``, ``snap``, the current trees with all statuses and the last pose: a part's first records."""
        agent = self.agent
        now = t3(agent.context.now)
        spec = agent.spec
        out: list[Record] = [
            {"k": "head", "t": now, "v": VERSION, "agent": agent.name, "meta": self.meta,
             "machine": {"states": list(spec.states),
                         "transitions": [{"trigger": t.trigger, "source": list(t.sources), "dest": t.dest}
                                         for t in spec.transitions]}},
            {"k": "snap", "t": now, "state": agent.state, "mode": agent.context.mode,
             "transitions": [r.as_dict() for r in agent.trace[-20:]],
             "blackboard": {k: {**v, "value": self._cut(v["value"])}
                            for k, v in agent.blackboard_watch.view().items() if k not in UNRECORDED_KEYS}},
        ]
        for slot, seen in self._slots.items():
            out.append(self._tree_record(slot, seen, now))
            if seen.nodes:
                out.append({"k": "st", "t": now, "id": seen.id,
                            "n": [[i, s, agent.node_ticks(n), w] for i, (n, (s, w)) in
                                  enumerate(zip(seen.nodes, seen.last, strict=True)) if s]})
        if self._pose is not None:
            out.append(self._pose)
        return out

    # -- hooks ---------------------------------------------------------------------------------------
    def on_transition(self, record: TransitionRecord) -> None:
        out: Record = {"k": "tr", "t": t3(record.t), "trigger": record.trigger, "source": record.source,
                       "dest": record.dest, "accepted": record.accepted, "reason": record.reason,
                       "origin": record.origin}
        if record.decision:  # an operator autonomy decision (`atemr.fsm.autonomy`): what, and by whom
            out.update(decision=record.decision, decided_by=record.decided_by)
        self.sink(out)

    def on_tree(self, root: py_trees.behaviour.Behaviour) -> None:
        slot = "monitor" if root is self.agent.monitor else "tree"
        self._observe(slot, root)

    def on_tick(self, now: float, writes: list[BlackboardWrite]) -> None:
        self._observe("tree", self.agent.tree)
        self._observe("monitor", self.agent.monitor)
        for write in writes:
            if write.key in UNRECORDED_KEYS:
                continue
            record: Record = {"k": "bb", "t": t3(write.t), "key": write.key, "value": self._cut(write.value),
                              "by": write.by}
            if write.kind == "UNSET":
                record["unset"] = True
            self.sink(record)
        if due(now, self._last_ticks_t + TICKS_PERIOD_S):
            self._last_ticks_t = now
            for seen in self._slots.values():
                counts = [[i, self.agent.node_ticks(n)] for i, n in enumerate(seen.nodes)]
                changed = [c for c in counts if c[1] != seen.ticks[c[0]]]
                if changed:
                    for i, ticks in changed:
                        seen.ticks[i] = ticks
                    self.sink({"k": "tk", "t": t3(now), "id": seen.id, "n": changed})
        if now - self._last_pose_t >= self.pose_period:
            pose = self.agent.context.port.pose()
            if pose is not None:
                self._last_pose_t = now
                self._pose = {"k": "pose", "t": t3(now), "x": round(pose.x_m, 4), "y": round(pose.y_m, 4),
                              "yaw": round(pose.yaw_rad, 4)}
                self.sink(self._pose)

    # -- internals -----------------------------------------------------------------------------------
    @staticmethod
    def _cut(value: Any) -> Any:
        text = json.dumps(value, default=str)
        return value if len(text) <= MAX_VALUE_CHARS else text[:MAX_VALUE_CHARS] + "…"

    def _tree_record(self, slot: str, seen: _Seen, now: float) -> Record:
        nodes = None
        if seen.root is not None:
            index = {id(n): i for i, n in enumerate(seen.nodes)}
            nodes = [[n.name, type(n).__name__, index[id(n.parent)] if n.parent is not None and n is not seen.root
                      else -1] for n in seen.nodes]
        return {"k": "tree", "t": now, "slot": slot, "id": seen.id, "nodes": nodes}

    def _observe(self, slot: str, root: py_trees.behaviour.Behaviour | None) -> None:
        now = t3(self.agent.context.now)
        seen = self._slots.get(slot)
        if seen is None or seen.root is not root:
            self._ids += 1
            seen = _Seen(root, self._ids)
            if root is not None:
                seen.nodes = _preorder(root)
                seen.last = [("", "")] * len(seen.nodes)
                seen.ticks = [0] * len(seen.nodes)
            self._slots[slot] = seen
            self.sink(self._tree_record(slot, seen, now))
        if root is None:
            return
        changes = []
        for i, node in enumerate(seen.nodes):
            now_seen = (node.status.name, why_of(node))
            if now_seen != seen.last[i]:
                seen.last[i] = now_seen
                seen.ticks[i] = self.agent.node_ticks(node)
                changes.append([i, now_seen[0], seen.ticks[i], now_seen[1]])
        if changes:
            self.sink({"k": "st", "t": now, "id": seen.id, "n": changes})


def _preorder(root: py_trees.behaviour.Behaviour) -> list[py_trees.behaviour.Behaviour]:
    out: list[py_trees.behaviour.Behaviour] = []
    stack = [root]
    while stack:
        node = stack.pop()
        out.append(node)
        stack.extend(reversed(node.children))
    return out
