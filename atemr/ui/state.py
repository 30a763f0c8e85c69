"""The dashboard's state contract: the snapshot `RobotGateway.state` returns at 10 Hz, as one type.

The same `RobotState` is built by the robot (`atemr.robot.gateway.RobotGatewayImpl.state`), sent as the
``state`` Socket.IO event and ``GET /api/state``, read by the pages' scripts and checked by the tests, so
a key renamed or retyped on one side is a type error or a failed test on the other instead of a "—" on a
carer's screen. Every key is always present; a value the robot does not know yet is None (or empty), and
the page shows "—" for it. Everything is plain JSON: str, bool, int, float, lists and dicts.

The ``state`` event adds ``sent_unix_s``, the wall-clock time it was sent (`atemr.ui.sockets.state_message`),
and a dashboard with no robot answers only ``{"connected": false}`` on ``GET /api/state``.
"""

from __future__ import annotations

import types
from typing import Any, Literal, TypedDict, Union, get_args, get_origin, get_type_hints, is_typeddict

from atemr.domain.status import LocalizationState

#: How often the robot sends its state; a page that hears nothing for two periods says the picture is old.
STATE_RATE_HZ = 10.0

AgentState = Literal["UNDEFINED", "STARTUP", "IDLE", "EXEC", "MAPPING", "SHUTDOWN", "ERROR"]
AGENT_STATES: tuple[AgentState, ...] = get_args(AgentState)
Mode = Literal["MANUAL", "AUTO"]
#: Why a safety layer holds the robot stopped, the most urgent first (see `STOP_CAUSES`).
StopCause = Literal["cliff", "floor_sensors", "obstacle", "heartbeat", "motor", "bus"]
#: ``[[x_m, y_m], ...]`` in the map frame, decimated and rounded to millimetres (`atemr.ui.snapshot.points_json`).
Points = list[list[float]]


class PoseJson(TypedDict):
    """A map-frame pose, rounded for the wire."""

    x_m: float
    y_m: float
    yaw_rad: float


class WheelSpeeds(TypedDict):
    left_radps: float
    right_radps: float


class SystemJson(TypedDict):
    """The robot computer's 1 Hz sample (`atemr.io.system_monitor.SystemSample`) for the graph."""

    t: float
    cpu_percent: float
    memory_percent: float
    disk_percent: float


class LimitsJson(TypedDict):
    """The speed limits in force."""

    linear_mps: float
    angular_radps: float


class MissionJson(TypedDict):
    """The running (or last) mission: its name, the share of steps done (0 to 1), and its outcome so far. A single
    goal (GO HERE, a place) is not one: the state's ``goal`` and ``navigation`` say where it goes."""

    name: str | None
    progress: float
    state: str | None


class NavigationJson(TypedDict):
    """How far the goal being driven to still is: along the planned path, and the time at the planned speed
    (None while the planner does not know yet)."""

    distance_left_m: float | None
    eta_s: float | None


class EventJson(TypedDict):
    """Something an operator should see (`atemr.robot.core.RobotEvent`): robot time, kind, text, and the
    wall-clock time it happened (Unix seconds), which the Events list shows as a time of day."""

    t: float
    kind: str
    text: str
    unix_s: float


class AutonomyJson(TypedDict):
    """The robot's autonomy level (`atemr.fsm.autonomy`), the transition waiting for the operator (``{"id",
    "trigger", "source", "dest", "level", "deadline", ...}``) or None, and the agent's time (for the
    deadline's countdown)."""

    level: str
    levels: list[str]
    timeout_s: float
    pending: dict[str, Any] | None
    now: float


class PlaceJson(TypedDict):
    """A named place of the active map (`atemr.domain.places.Place`): where "Go to" sends the robot."""

    name: str
    x_m: float
    y_m: float
    yaw_rad: float
    #: ``dock`` where the robot charges (``home``), else ``place``.
    kind: str


class BatteryJson(TypedDict):
    """The state of charge estimated from the motors' supply voltage (`atemr.robot.battery.BatteryGauge`)."""

    percent: float
    voltage_v: float
    #: ``ok``, ``low`` (below the warning limit), ``return`` (below the return limit: home to charge),
    #: ``critical`` (below the critical limit: stopped); `atemr.domain.status.BatteryStatus.level`.
    level: str


class CandidateJson(TypedDict):
    """A place global localization could not rule out, and the share of the scan on the map there."""

    x_m: float
    y_m: float
    yaw_rad: float
    agreement: float


class LocalizationJson(TypedDict):
    """Localization as every consumer shows it (`atemr.domain.status.LocalizationStatus`): the one confidence
    number (0 to 1), the limit it must reach, whether it does (localized), what the localizer is doing, and
    while global localization is ambiguous, the places it cannot tell apart, best first."""

    confidence: float
    limit: float
    localized: bool
    state: LocalizationState
    candidates: list[CandidateJson]
    #: The robot turns in place by itself to tell those places apart (after the operator's FIND POSITION).
    looking_around: bool


class RobotState(TypedDict):
    """One snapshot of the robot as the dashboard shows it."""

    #: The robot's name (``secondary.robot_name``): tells robots apart on a shared ``ui.message_queue``.
    robot: str
    agent_state: AgentState
    mode: Mode
    #: The simulation panel is shown when true.
    simulation: bool
    #: The map in use, by name (None: no map).
    active_map: str | None
    #: Changes whenever `RobotGateway.map_image` would return a different image.
    map_version: int
    #: None when the robot does not know where it is.
    pose: PoseJson | None
    #: How sure the robot is of that pose: the number AUTO, goals and missions wait for.
    localization: LocalizationJson
    #: Valid lidar returns in the map frame (empty when not localized).
    scan: Points
    #: Cells the depth camera's obstacle layer holds now (a table top, a shoe: what the lidar's plane may miss),
    #: map frame; empty without a depth camera or a pose.
    depth_obstacles: Points
    global_path: Points
    local_path: Points
    #: The goal being driven to (EXEC only), or None.
    goal: PoseJson | None
    #: Progress towards that goal, or None when there is none.
    navigation: NavigationJson | None
    wheel_speeds: WheelSpeeds
    #: Low-level brakes applied (emergency or cliff stop).
    emergency: bool
    #: Why the robot is held stopped (the page says it in plain words with what to do), None when nothing holds it.
    stop_cause: StopCause | None
    #: Agent bits of CAN 0x153 byte 0 (heartbeat, hardware, auto, connectivity, localization); True is OK.
    level1: dict[str, bool]
    #: Hardware bits of 0x153 byte 1 (left_motor, right_motor, imu, lidar, camera, webserver, ir_front, ir_rear).
    level2: dict[str, bool]
    #: None until the first 1 Hz sample.
    system: SystemJson | None
    limits: LimitsJson
    #: The reactive engine is enabled (the robot moves away from people by itself).
    awareness: bool
    wifi_ssid: str | None
    #: A mapping session is running.
    mapping: bool
    #: A video is being recorded.
    recording: bool
    mission: MissionJson | None
    #: The missions that can be started, by name.
    missions: list[str]
    #: The stored maps, by name.
    maps: list[str]
    #: The active map's named places, in their order.
    places: list[PlaceJson]
    #: None until the motors have reported a plausible supply voltage.
    battery: BatteryJson | None
    #: The latest events, oldest first.
    events: list[EventJson]
    autonomy: AutonomyJson


def top_state(state: str) -> AgentState:
    """The agent's top-level state as the pages show it (``IDLE.MANUAL`` → ``IDLE``); UNDEFINED if unknown."""
    top = state.split(".", maxsplit=1)[0]
    return next((s for s in AGENT_STATES if s == top), "UNDEFINED")


#: Every key of the snapshot, for checks that a state is whole.
STATE_KEYS: frozenset[str] = RobotState.__required_keys__


def state_problems(state: Any) -> list[str]:
    """What in ``state`` breaks the `RobotState` contract (a missing or extra key, a value of the wrong
    type, at any depth), each naming the key path; empty when it holds. For tests and for fakes of a
    robot, which must keep to the contract the pages read."""
    return _problems(state, RobotState, "state")


def _problems(value: Any, tp: Any, where: str) -> list[str]:
    origin = get_origin(tp)
    if origin in (Union, types.UnionType):
        if any(not _problems(value, arg, where) for arg in get_args(tp)):
            return []
        return [f"{where}: expected {_name(tp)}, got {value!r:.80}"]
    if origin is Literal:
        choices = get_args(tp)
        if value in choices:
            return []
        return [f"{where}: expected one of {', '.join(map(repr, choices))}, got {value!r:.80}"]
    if is_typeddict(tp):
        return _mapping_problems(value, tp, where)
    if origin is list:
        if not isinstance(value, list):
            return [f"{where}: expected a list, got {value!r:.80}"]
        return [p for i, item in enumerate(value) for p in _problems(item, get_args(tp)[0], f"{where}[{i}]")]
    if origin is dict:
        if not isinstance(value, dict):
            return [f"{where}: expected a mapping, got {value!r:.80}"]
        key_tp, value_tp = get_args(tp)
        return [p for k, v in value.items() for p in _problems(k, key_tp, f"{where} key") + _problems(
            v, value_tp, f"{where}.{k}")]
    return [] if _is_a(value, tp) else [f"{where}: expected {_name(tp)}, got {value!r:.80}"]


def _mapping_problems(value: Any, tp: Any, where: str) -> list[str]:
    if not isinstance(value, dict):
        return [f"{where}: expected a mapping, got {value!r:.80}"]
    hints = get_type_hints(tp)
    out = [f"{where}: missing key {k!r}" for k in hints if k not in value]
    out += [f"{where}: unexpected key {k!r}" for k in value if k not in hints]
    for key, hint in hints.items():
        if key in value:
            out += _problems(value[key], hint, f"{where}.{key}")
    return out


def _is_a(value: Any, tp: Any) -> bool:
    """A plain JSON value's check: a float may be written as an integer, a bool is never a number."""
    if tp is Any:
        return True
    if tp in (int, float):
        return isinstance(value, int if tp is int else (int, float)) and not isinstance(value, bool)
    return isinstance(value, tp)


def _name(tp: Any) -> str:
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")
