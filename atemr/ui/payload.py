"""Checking what a browser sends in a Socket.IO event: every field typed, finite and in range.

A bad payload raises `ProtocolError` naming the event and the field; the event wrapper turns it into
a refusal the page shows (and logs one WARNING line), and nothing reaches the robot.

`PacketJSON` reads the Socket.IO packets: an integer literal of more than `MAX_INT_DIGITS` digits becomes
a `TooLargeInteger` (which every check here refuses) instead of an exception that the Socket.IO server
would log as an ERROR with a traceback for each such packet.
"""

from __future__ import annotations

import json
import math
from typing import Any

from atemr.errors import ProtocolError
from atemr.msgs import Pose2D

#: Longest integer literal read as a number (python-engineio's own limit; longer ones cost quadratic time).
MAX_INT_DIGITS = 100


class TooLargeInteger:
    """An integer literal too long to read (its digits are never converted)."""

    __slots__ = ("digits",)

    def __init__(self, digits: int) -> None:
        self.digits = digits

    def __repr__(self) -> str:
        return f"<an integer of {self.digits} digits>"


def _parse_int(literal: str) -> int | TooLargeInteger:
    digits = len(literal.lstrip("-"))
    return TooLargeInteger(digits) if digits > MAX_INT_DIGITS else int(literal)


class PacketJSON:
    """The ``json`` module given to the Socket.IO server (``dumps`` and ``loads``)."""

    @staticmethod
    def dumps(*args: Any, **kwargs: Any) -> str:
        return json.dumps(*args, **kwargs)

    @staticmethod
    def loads(*args: Any, **kwargs: Any) -> Any:
        kwargs.setdefault("parse_int", _parse_int)
        return json.loads(*args, **kwargs)


def mapping(event: str, data: Any) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise ProtocolError(f"{event}: expected an object, got {type(data).__name__}")
    return data


def number(event: str, data: Any, key: str, *, lo: float = -math.inf, hi: float = math.inf) -> float:
    """``data[key]`` as a finite float within [lo, hi]."""
    value = mapping(event, data).get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProtocolError(f"{event}.{key}: expected a number, got {value!r}")
    try:
        result = float(value)
    except OverflowError:
        raise ProtocolError(f"{event}.{key}: expected a finite number, got an integer too large") from None
    if not math.isfinite(result):
        raise ProtocolError(f"{event}.{key}: expected a finite number, got {value!r}")
    if not lo <= result <= hi:
        raise ProtocolError(f"{event}.{key}: expected a value within [{lo}, {hi}], got {result}")
    return result


def flag(event: str, data: Any, key: str) -> bool:
    value = mapping(event, data).get(key)
    if not isinstance(value, bool):
        raise ProtocolError(f"{event}.{key}: expected true or false, got {value!r}")
    return value


def text(event: str, data: Any, key: str, *, max_len: int = 128) -> str:
    value = mapping(event, data).get(key)
    if not isinstance(value, str) or not value.strip():
        raise ProtocolError(f"{event}.{key}: expected a non-empty string, got {value!r}")
    if len(value) > max_len:
        raise ProtocolError(f"{event}.{key}: at most {max_len} characters")
    return value.strip()


def pose(event: str, data: Any) -> Pose2D:
    """``{"x_m", "y_m", "yaw_rad"}`` as a `Pose2D` (yaw wrapped to (-pi, pi])."""
    x = number(event, data, "x_m", lo=-1e6, hi=1e6)
    y = number(event, data, "y_m", lo=-1e6, hi=1e6)
    yaw = number(event, data, "yaw_rad", lo=-1e3, hi=1e3)
    return Pose2D(x, y, math.atan2(math.sin(yaw), math.cos(yaw)))
