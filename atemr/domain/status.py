"""What the robot reports about itself, as plain values: lifecycle state codes, the agent's and the hardware's
status bits, the power handshake, a component's health, and how sure localization is.

These are the domain's words, not the wire's: the agent (`atemr.fsm`, `atemr.trees`) composes them, the
devices report `ComponentHealth`, and the CAN codec (`atemr.io.can.protocol`) carries them in the bytes of
0x150 and 0x153. Keeping them here lets the agent and the devices use them without importing
the codec or each other. `LocalizationStatus` is the one confidence number that localization (a skill)
computes and the guards, the 0x153 LOCALIZATION bit, the dashboard and the command line all show.

Lifecycle state names are nested with `SEPARATOR` (``IDLE.AUTO``); a nested state reports its top-level
state's code (``IDLE.AUTO`` → IDLE 0x02), since the secondary core's OPS screen only knows the top level.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum, IntFlag
from typing import Literal


class StateCode(IntEnum):
    """The agent's lifecycle state, byte 2 of 0x153 (ERROR is this project's extension)."""

    UNDEFINED = 0x00
    STARTUP = 0x01
    IDLE = 0x02
    EXEC = 0x03
    MAPPING = 0x04
    SHUTDOWN = 0x05
    ERROR = 0x06


class AgentBits(IntFlag):
    """Byte 0 of 0x153: primary-core sub-module statuses; a set bit means OK (AUTO: auto mode)."""

    NONE = 0
    HEARTBEAT = 1 << 0
    HARDWARE = 1 << 1
    AUTO = 1 << 2
    CONNECTIVITY = 1 << 3
    LOCALIZATION = 1 << 4


class HardwareBits(IntFlag):
    """Byte 1 of 0x153: hardware statuses; a set bit means OK."""

    NONE = 0
    LEFT_MOTOR = 1 << 0
    RIGHT_MOTOR = 1 << 1
    IMU = 1 << 2
    LIDAR = 1 << 3
    CAMERA = 1 << 4
    WEBSERVER = 1 << 5
    IR_FRONT = 1 << 6
    IR_REAR = 1 << 7


class PowerState(IntEnum):
    """Byte 0 of 0x150, written by the primary core."""

    INITIALISING = 0
    RUNNING = 1
    POWER_OFF_ACK = 2


class PowerRequest(IntEnum):
    """Byte 1 of 0x150, written by the secondary core."""

    NORMAL = 0
    POWER_OFF = 1


@dataclass(frozen=True)
class ComponentHealth:
    """One component's health, as a device reports it and the robot port collects it: ``ok`` and, when not,
    why (for the dashboard)."""

    ok: bool
    detail: str = ""


#: What localization is doing: tracking with the confidence at or above its limit (``localized``) or below it
#: (``lost``); a pose given and not yet checked against a scan (``pose set``); a whole-map search running
#: (``searching``), or finished with several places alike (``ambiguous``) or none (``failed``); nothing to go
#: on yet (``uninitialized``); no map to localize on (``no map``).
LocalizationState = Literal["localized", "lost", "pose set", "searching", "ambiguous", "failed", "uninitialized",
                            "no map"]


@dataclass(frozen=True)
class LocalizationStatus:
    """Localization as every consumer shows it (the dashboard, CAN 0x153 bit 4, ``mission run --json``, the
    agent's guards): the one confidence number (0 to 1), the limit it is compared with, and what the localizer
    is doing. One type, so that no consumer can call the robot localized by another rule: localized means
    ``confidence >= limit``, nothing else."""

    confidence: float
    limit: float
    state: LocalizationState

    @property
    def localized(self) -> bool:
        return self.confidence >= self.limit

    def as_dict(self) -> dict[str, float | bool | str]:
        """``{"confidence", "limit", "localized", "state"}`` for a JSON report."""
        return {"confidence": self.confidence, "limit": self.limit, "localized": self.localized, "state": self.state}

    def why_not(self) -> str:
        """Why the robot is not localized ("" when it is), for a refusal the operator can act on."""
        if self.localized:
            return ""
        if self.state == "no map":
            return "not localized: no map is selected; select or build a map, then set the robot's position"
        return (f"not localized (confidence {self.confidence:.0%}, needs {self.limit:.0%}; {self.state}): set the "
                "robot's position on the map (SET POSITION) or press FIND POSITION")


#: How low the charge is against the limits: above the warning limit, below it, below the return limit (the
#: robot goes home), below the critical limit (it stops where it is).
BatteryLevel = Literal["ok", "low", "return", "critical"]
#: What the robot does with its task at the return limit: cancel it, or let it finish; then it goes home.
AtReturn = Literal["cancel", "finish"]


@dataclass(frozen=True)
class BatteryStatus:
    """The state of charge as every consumer reads it (the Monitor's ``WatchBattery``, the dashboard's BAT
    indicator, the robot's screen, the routines' start check), with the limits it is compared with and what to
    do at the return limit. One type, as for localization, so that no consumer calls the battery low by
    another rule: the level is the charge against these limits, nothing else."""

    percent: float
    voltage_v: float
    warn_percent: float
    return_percent: float
    critical_percent: float
    at_return: AtReturn = "cancel"

    @property
    def level(self) -> BatteryLevel:
        if self.percent < self.critical_percent:
            return "critical"
        if self.percent < self.return_percent:
            return "return"
        if self.percent < self.warn_percent:
            return "low"
        return "ok"

    def forbids_task(self) -> str | None:
        """Why no new task should start on this charge (below the return limit: it would only be cut short on
        the way home), else None."""
        return f"battery {self.percent:.0f} %" if self.level in ("return", "critical") else None


#: Between the levels of a nested lifecycle state name (``IDLE.AUTO``).
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
