"""Who wrote what on the blackboard, and when: py_trees' activity stream turned into a per-key log.

py_trees can log every blackboard access (``Blackboard.enable_activity_stream``) with the client that
made it, but not the time, and its stream keeps reads too and drops the *newest* item when full. The
agent drains the stream once per tick (`BlackboardWatch.drain`), so each write gets the robot time of the
tick it happened in; reads and refused accesses are dropped there. The watch keeps the last write of every
key (for the live view) and returns the tick's writes (for the recorder). No key or node limit.

py_trees keeps the stream at class level, like the storage: one process has one stream, so one agent per
process drains it (the robot has one; tests build one at a time).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import py_trees

#: Activities that change a key's value (py_trees ``ActivityType`` values).
WRITES = frozenset({"INITIALISED", "WRITE", "UNSET"})
#: Room in the stream between two drains (reads are logged too; a tick makes a few hundred at most).
STREAM_SIZE = 100_000


@dataclass(frozen=True)
class BlackboardWrite:
    """One change of a key: its new value (None when unset), the client's name, the robot time, the kind."""

    key: str
    value: Any
    by: str
    t: float
    kind: str = "WRITE"


class BlackboardWatch:
    """The last write of every key, fed from py_trees' activity stream (see the module docstring)."""

    def __init__(self) -> None:
        self.last: dict[str, BlackboardWrite] = {}
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
            value = None if item.activity_type == "UNSET" else item.current_value
            write = BlackboardWrite(item.key, value, item.client_name, now, item.activity_type)
            writes.append(write)
            if item.activity_type == "UNSET":
                self.last.pop(item.key, None)
            else:
                self.last[item.key] = write
        return writes

    def view(self, jsonable: Any) -> dict[str, dict[str, Any]]:
        """Every key on the blackboard: ``{key: {"value", "by", "t"}}``, sorted by key.

        A key written before the watch began has ``by`` "" and ``t`` None. ``jsonable`` renders values.
        """
        out: dict[str, dict[str, Any]] = {}
        for key, value in sorted(py_trees.blackboard.Blackboard.storage.items()):
            write = self.last.get(key)
            out[key] = {"value": jsonable(value), "by": write.by if write else "", "t": write.t if write else None}
        return out
