"""Lifecycle state names → the CAN 0x153 state code (DESIGN.md §3), using the codec's `StateCode`.

A nested state reports its top-level state's code (``IDLE.AUTO`` → IDLE 0x02); the secondary core's OPS
screen only knows the top level.
"""

from __future__ import annotations

from atemr.io.can import StateCode

SEPARATOR = "."

#: The top-level states a document may declare: every code except UNDEFINED.
TOP_LEVEL_STATES = tuple(s.name for s in StateCode if s is not StateCode.UNDEFINED)


def top_level(state: str) -> str:
    """``IDLE.AUTO`` → ``IDLE``."""
    return state.split(SEPARATOR, 1)[0]


def state_code(state: str) -> StateCode:
    """The 0x153 code for a (possibly nested) state name; UNDEFINED for an empty or unknown name."""
    try:
        return StateCode[top_level(state)]
    except KeyError:
        return StateCode.UNDEFINED
