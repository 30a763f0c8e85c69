"""What each screen of the board shows (thesis 3.6.3, figures 3.51–3.54), built from the board's state.

Pure functions: a `BoardView` (a snapshot of what the board knows) in, a `atemr.io.secondary_emulator.display.Screen`
out, so every screen can be tested by comparing text.
"""

from __future__ import annotations

from dataclasses import dataclass

from atemr.io.can import PrimaryStatus
from atemr.io.secondary_emulator.display import Screen

#: The screen shown in each board state (the thesis' names).
SCREEN_NAMES = {
    "power_on_sequence": "POWER-ON SEQUENCE",
    "ready": "BOOT/READY",
    "power_on": "POWER-ON",
    "ops": "OPS",
    "config": "CONFIG",
    "power_off": "POWER-OFF",
    "shutdown": "SHUTDOWN",
}


@dataclass(frozen=True)
class BoardView:
    """Everything a screen may show, at one moment."""

    state: str
    robot_name: str = "KAY"
    #: Seconds spent in the current state.
    in_state_s: float = 0.0
    boot_s: float = 3.0
    primary_boot_estimate_s: float = 30.0
    status: PrimaryStatus | None = None
    robot_ip: str | None = None
    portal_left_s: float | None = None
    ap_ssid: str = "ATEMR-Connect"
    ap_password: str = "123456789"
    portal_url: str = "http://192.168.4.1"
    heartbeat_ok: bool = False
    emergency_reason: str | None = None
    power_off_acknowledged: bool = False
    shutdown_in_s: float = 0.0


#: Soft-emergency reasons as they fit on the OPS screen's last line.
_SHORT_REASONS = {"primary not running": "primary down"}


def _bits(value: int) -> str:
    return f"{value:08b}"


def build_screen(view: BoardView) -> Screen:
    """The screen for ``view.state``."""
    builder = _BUILDERS.get(view.state)
    if builder is None:
        raise KeyError(f"no screen for board state {view.state!r}")
    return builder(view)


def _power_on_sequence(v: BoardView) -> Screen:
    progress = v.in_state_s / v.boot_s if v.boot_s > 0 else 1.0
    return Screen(f"ATEMR - {v.robot_name}", ("Telepresence robot", "by E.-E. G. Asare", "Loading, wait..."),
                  progress=progress)


def _ready(v: BoardView) -> Screen:
    return Screen("SC CORE", ("", "Ready !!", "", "hold 1s: on"), logo=True)


def _power_on(v: BoardView) -> Screen:
    progress = min(0.95, v.in_state_s / v.primary_boot_estimate_s) if v.primary_boot_estimate_s > 0 else 0.95
    return Screen("POWER ON", ("Input received.", "Powering on the", "primary core..."), progress=progress)


def _ops(v: BoardView) -> Screen:
    status = v.status or PrimaryStatus()
    mode = "AUTO" if status.auto_mode else "MANUAL"
    heartbeat = "HB OK" if v.heartbeat_ok else "HB LOST"
    reason = _SHORT_REASONS.get(v.emergency_reason or "", v.emergency_reason)
    last = f"BRAKE {reason}" if reason else f"IP {v.robot_ip or '0.0.0.0'}"
    return Screen(
        status.state.name,
        (f"AGENT {_bits(status.agent)}", f"HDW   {_bits(status.hardware)}", f"{mode:<7}{heartbeat}", last),
    )


def _config(v: BoardView) -> Screen:
    title = f"PORTAL ON {int(v.portal_left_s + 0.999)}s" if v.portal_left_s is not None else "PORTAL OFF"
    return Screen(title, (f"IP {v.robot_ip or '0.0.0.0'}", f"AP {v.ap_ssid}", f"PW {v.ap_password}", v.portal_url))


def _power_off(v: BoardView) -> Screen:
    if v.power_off_acknowledged:
        left = max(0, int(v.shutdown_in_s + 0.999))
        return Screen("POWER OFF", ("Acknowledged.", "Primary core is", "shutting down.", f"Wait {left}s..."))
    return Screen("POWER OFF", ("Power-off request", "sent. Waiting for", "the primary core..."))


def _shutdown(v: BoardView) -> Screen:
    return Screen("SHUTDOWN", ("Primary core off.", "", "Turn the power", "switch OFF now."))


_BUILDERS = {
    "power_on_sequence": _power_on_sequence,
    "ready": _ready,
    "power_on": _power_on,
    "ops": _ops,
    "config": _config,
    "power_off": _power_off,
    "shutdown": _shutdown,
}
