"""One exception hierarchy for the whole framework.

Callers catch what they mean (a `HardwareError` is not a `ConfigError`), and the agent's Error state
classifies a failure by its type and its ``critical`` flag instead of parsing messages.
"""

from __future__ import annotations

import reprlib
from pathlib import Path
from typing import Any

#: Longest value shown in an error message (`brief`).
BRIEF_LIMIT = 80


def _brief_repr() -> reprlib.Repr:
    r = reprlib.Repr()
    r.maxlevel = 3
    r.maxtuple = r.maxlist = r.maxarray = r.maxdeque = r.maxset = r.maxfrozenset = r.maxdict = 4
    r.maxstring = r.maxother = BRIEF_LIMIT
    r.maxlong = 40
    return r


_REPR = _brief_repr()


def brief(value: Any, limit: int = BRIEF_LIMIT) -> str:
    """``repr(value)`` cut to at most ``limit`` characters, for error messages about input from outside.

    Never builds the whole repr: containers show their first few items and at most three levels (a YAML
    document whose aliases expand to millions of items costs as little as a short one), strings and
    numbers are cut. An error message that quotes what it was given uses this, so its size is bounded
    whatever the input (it may end up in a log line, an event or a session cookie).
    """
    try:
        text = _REPR.repr(value)
    except Exception:  # a broken __repr__ must not hide the error being reported
        text = f"<{type(value).__name__}>"
    if len(text) > limit:
        text = text[: max(limit - 3, 0)] + "..."
    return text


def brief_text(text: str, limit: int = 300) -> str:
    """``text`` itself (not its repr) cut to at most ``limit`` characters: a message built elsewhere."""
    return text if len(text) <= limit else text[: max(limit - 3, 0)] + "..."


class AtemrError(Exception):
    """Root of every error the framework raises on purpose.

    ``critical`` tells the agent's Error state whether the robot can go back to Idle (False) or must
    shut down (True).
    """

    critical: bool = False


class ConfigError(AtemrError):
    """A configuration, YAML, map or mission document is invalid.

    Carries where the problem is, so the message points at the exact place an operator must edit:
    ``agent.yaml:42:7 states.EXEC.tree.children[2]: unknown behaviour 'GoTo' (did you mean 'GoToPose'?)``.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        line: int | None = None,
        column: int | None = None,
        path: str | None = None,
    ) -> None:
        self.reason = message
        self.file = str(file) if file is not None else None
        self.line = line
        self.column = column
        self.path = path
        super().__init__(self._format())

    def _format(self) -> str:
        where = ""
        if self.file is not None:
            where = self.file
            if self.line is not None:
                where += f":{self.line}"
                if self.column is not None:
                    where += f":{self.column}"
        if self.path:
            where = f"{where} {self.path}" if where else self.path
        return f"{where}: {self.reason}" if where else self.reason


class ProtocolError(AtemrError):
    """A CAN frame or other wire message is malformed: wrong ID, wrong length, bad value."""


class HardwareError(AtemrError):
    """A hardware component (motor, sensor, bus) failed or stopped answering."""

    critical = False

    def __init__(self, message: str, *, component: str | None = None, critical: bool = False) -> None:
        self.component = component
        self.critical = critical
        super().__init__(f"{component}: {message}" if component else message)


class BusError(HardwareError):
    """The CAN bus itself failed: bus-off, a dead receive side, send failures."""


class ControlError(AtemrError):
    """The robot's local control channel: no robot is running, the connection was lost, a request was refused."""


class NavigationError(AtemrError):
    """A goal cannot be accepted or reached (outside the map, in an obstacle, no path, stuck, lost)."""


class SafetyError(AtemrError):
    """Motion was refused or stopped by a safety rule (stop zone, cliff, watchdog, emergency)."""


class RegistryError(AtemrError):
    """A plugin name is unknown or registered twice."""
