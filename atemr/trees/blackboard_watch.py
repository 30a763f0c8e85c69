"""Who wrote what on the blackboard, and when: py_trees' activity stream turned into a per-key log.

py_trees can log every blackboard access (``Blackboard.enable_activity_stream``) with the client that
made it, but not the time, and its stream keeps reads too and drops the *newest* item when full. The
agent drains the stream once per tick (`BlackboardWatch.drain`), so each write gets the robot time of the
tick it happened in; reads, refused accesses and writes of the value a key already has are dropped there
(the agent rewrites its keys every tick: "when" is when the key got its value). The watch keeps the last
change of every key (for the live view) and returns the tick's changes (for the recorder). No key or node
limit.

py_trees keeps the stream at class level, like the storage: one process has one stream, so one agent per
process drains it (the robot has one; tests build one at a time).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import py_trees

#: Activities that change a key's value (py_trees ``ActivityType`` values).
WRITES = frozenset({"INITIALISED", "WRITE", "UNSET"})
#: Room in the stream between two drains (reads are logged too; a tick makes a few hundred at most).
STREAM_SIZE = 100_000


@dataclass(frozen=True)
class BlackboardWrite:
    """One change of a key: its new value rendered JSON-able (None when unset), the client's name, the robot
    time, the kind."""

    key: str
    value: Any
    by: str
    t: float
    kind: str = "WRITE"


class BlackboardWatch:
    """The last write of every key, fed from py_trees' activity stream (see the module docstring)."""

    def __init__(self, render: Callable[[Any], Any]) -> None:
        self.render = render
        self.last: dict[str, BlackboardWrite] = {}
        self._text: dict[str, str] = {}
        self._enable()

    @staticmethod
    def _enable() -> py_trees.blackboard.ActivityStream:
        blackboard = py_trees.blackboard.Blackboard
        if blackboard.activity_stream is None:
            blackboard.enable_activity_stream(maximum_size=STREAM_SIZE)
        assert blackboard.activity_stream is not None
        return blackboard.activity_stream

    def drain(self, now: float) -> list[BlackboardWrite]:
        """The writes since the last drain, stamped ``now`` (the stream is emptied; reads are dropped)."""
        stream = self._enable()  # again: `Blackboard.clear()` deletes the stream
        items, stream.data = stream.data, []
        writes: list[BlackboardWrite] = []
        for item in items:
            if item.activity_type not in WRITES:
                continue
            if item.activity_type == "UNSET":
                self.last.pop(item.key, None)
                self._text.pop(item.key, None)
                writes.append(BlackboardWrite(item.key, None, item.client_name, now, "UNSET"))
                continue
            value = self.render(item.current_value)
            text = json.dumps(value, sort_keys=True, default=str)
            if self._text.get(item.key) == text:
                continue
            self._text[item.key] = text
            write = BlackboardWrite(item.key, value, item.client_name, now, item.activity_type)
            writes.append(write)
            self.last[item.key] = write
        return writes

    def view(self) -> dict[str, dict[str, Any]]:
        """Every key on the blackboard: ``{key: {"value", "by", "t"}}``, sorted by key (``by`` and ``t``: who
        gave the key its value, and when). A key set before the watch began has ``by`` "" and ``t`` None."""
        out: dict[str, dict[str, Any]] = {}
        for key, value in sorted(py_trees.blackboard.Blackboard.storage.items()):
            write = self.last.get(key)
            out[key] = {"value": self.render(value), "by": write.by if write else "", "t": write.t if write else None}
        return out
