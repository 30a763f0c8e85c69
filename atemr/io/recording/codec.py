"""Messages to the bytes of their channel: CDR (`atemr.io.recording.cdr`: the bytes `mcap-ros2-support` writes,
compiled per type), JSON through the standard library.

One `Codec` per recording or live server: it keeps the encoder each ROS 2 schema compiles to, so a topic's
definition is compiled once. JSON has no NaN or infinity, so they become null: a record stays valid JSON for
any reader (Foxglove included).
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable
from typing import Any

from atemr.io.recording.cdr import compile_encoder
from atemr.io.recording.ros2_types import short_name
from atemr.io.recording.topics import Topic, topic

Encoder = Callable[[Any], bytes]


def finite(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None (recursively through dicts and lists)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    return value


_compact_json = functools.partial(json.dumps, separators=(",", ":"), ensure_ascii=False, allow_nan=False,
                                  default=str)


def encode_json(message: Any) -> bytes:
    """``message`` as compact UTF-8 JSON, non-finite floats as null. Almost every message has none, so it is
    encoded as it is first and walked by `finite` only when the encoder refuses a NaN or an infinity."""
    try:
        text = _compact_json(message)
    except ValueError:
        text = _compact_json(finite(message))
    return text.encode("utf-8")


class Codec:
    """Encodes messages for the topics of `atemr.io.recording.topics`."""

    def __init__(self) -> None:
        self._encoders: dict[str, Encoder] = {}

    def encoder(self, t: Topic) -> Encoder:
        found = self._encoders.get(t.name)
        if found is None:
            found = compile_encoder(short_name(t.schema_name)) if t.is_ros2 else encode_json
            self._encoders[t.name] = found
        return found

    def encode(self, name: str, message: Any) -> bytes:
        """The bytes of ``message`` on topic ``name``."""
        return self.encoder(topic(name))(message)


__all__ = ["Codec", "encode_json", "finite"]
