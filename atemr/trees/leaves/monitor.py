"""The Monitor's leaves: the agent's hub to the outside, ticked every agent tick whatever the state.

They never finish (RUNNING forever under the Monitor's Parallel) and keep their memory between ticks:
the status publisher sends CAN 0x153 at ``period_s`` and at once on any change; the watchers turn
edges (a power-off request, a lost heartbeat, a component going bad, the battery crossing a limit) into
events for the machine.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import py_trees

from atemr.clock import due
from atemr.domain.status import AgentBits, BatteryLevel, BatteryStatus, HardwareBits, state_code
from atemr.errors import ConfigError, HardwareError
from atemr.io.can import PrimaryStatus
from atemr.trees.behaviours import Leaf, behaviours
from atemr.trees.context import MONITOR_NS
from atemr.trees.ports import HARDWARE_COMPONENTS

if TYPE_CHECKING:
    from atemr.trees.missions import Mission

Status = py_trees.common.Status


def compose_status(leaf: Leaf) -> PrimaryStatus:
    """The 0x153 status from the port's health, the link's heartbeat, the mode and the state."""
    ctx = leaf.ctx
    health = ctx.port.health()
    hardware = HardwareBits.NONE
    for name, bit in HARDWARE_COMPONENTS.items():
        h = health.get(name)
        if h is not None and h.ok:
            hardware |= bit
    agent = AgentBits.NONE
    if ctx.link is not None and ctx.link.heartbeat_ok():
        agent |= AgentBits.HEARTBEAT
    if all(h.ok for n, h in health.items() if n in HARDWARE_COMPONENTS) and hardware:
        agent |= AgentBits.HARDWARE
    if ctx.mode == "AUTO":
        agent |= AgentBits.AUTO
    connectivity = health.get("connectivity")
    if connectivity is not None and connectivity.ok:
        agent |= AgentBits.CONNECTIVITY
    localization = ctx.port.localization_status()
    if localization is not None and localization.localized:
        agent |= AgentBits.LOCALIZATION
    return PrimaryStatus(agent, hardware, state_code(ctx.state))


#: Where `PublishStatus` leaves the last status on the blackboard.
_STATUS_KEY = f"{MONITOR_NS}/status"


@dataclass(frozen=True)
class PublishStatusParams:
    period_s: float = field(default=0.5, metadata={"min": 0.05, "max": 10.0, "help": "0.5 s = 2 Hz"})


@behaviours.register("PublishStatus")
class PublishStatus(Leaf):
    """Send CAN 0x153 every ``period_s`` and whenever a bit or the state code changes."""

    Params = PublishStatusParams
    summary = "send CAN 0x153 (agent bits, hardware bits, state code) periodically and on change"

    def setup(self, **kwargs: object) -> None:
        super().setup(**kwargs)
        self.last: PrimaryStatus | None = None
        self._last_t = float("-inf")
        self.sent = 0
        self.bb = self.attach_blackboard_client(self.name, MONITOR_NS)
        self.bb.register_key("status", access=py_trees.common.Access.WRITE)
        self._written: tuple[PrimaryStatus, dict[str, object]] | None = None

    def update(self) -> py_trees.common.Status:
        status = compose_status(self)
        periodic = due(self.ctx.now, self._last_t + self.params.period_s)
        if self.ctx.link is not None and (periodic or status != self.last):
            self.ctx.link.publish_status(status)
            self.last, self._last_t = status, self.ctx.now
            self.sent += 1
        # Written when it changes (or the blackboard no longer holds what this leaf wrote), not at every tick: the
        # same value again costs py_trees an activity record and the blackboard's watch a JSON rendering.
        written = self._written
        if (written is None or status != written[0]
                or py_trees.blackboard.Blackboard.storage.get(_STATUS_KEY) is not written[1]):
            fields = status.fields()
            self.bb.status = fields
            self._written = (status, fields)
        self.feedback_message = f"0x153 {status.agent.value:02X} {status.hardware.value:02X} {status.state.value:02X}"
        return Status.RUNNING


@behaviours.register("WatchPowerRequest")
class WatchPowerRequest(Leaf):
    """Post ``power_off`` once when the secondary core requests power-off (0x150 byte 1 = 1)."""

    summary = "turn a 0x150 power-off request into the power_off event"

    def setup(self, **kwargs: object) -> None:
        super().setup(**kwargs)
        self._posted = False

    def update(self) -> py_trees.common.Status:
        requested = self.ctx.link is not None and self.ctx.link.power_off_requested()
        if requested and not self._posted:
            self.ctx.post("power_off", "secondary core requested power-off (0x150 byte 1 = 1)", self.name)
        self._posted = requested
        self.feedback_message = "power-off requested" if requested else "no request"
        return Status.RUNNING


@dataclass(frozen=True)
class WatchParams:
    in_states: tuple[str, ...] = field(
        default=("IDLE", "EXEC", "MAPPING"),
        metadata={"help": "top-level states in which a failure is reported as a fault"},
    )


@dataclass(frozen=True)
class WatchHealthParams(WatchParams):
    components: tuple[str, ...] = field(default=(), metadata={"required": True})
    critical: bool = False


def _active(leaf: Leaf, in_states: tuple[str, ...]) -> bool:
    return leaf.ctx.state.split(".", 1)[0] in in_states


@behaviours.register("WatchHeartbeat")
class WatchHeartbeat(Leaf):
    """Post ``fault`` (non-critical `HardwareError`) when the 0x157 heartbeat is lost.

    Both cores already stop the motors on their own when it fails (docs/testing.md#what-the-robot-promises);
    the fault takes the agent out of Exec/Mapping so it does not carry on as if nothing happened.
    """

    Params = WatchParams
    summary = "turn a lost 0x157 heartbeat into a fault event"

    def setup(self, **kwargs: object) -> None:
        super().setup(**kwargs)
        self._was_ok = True

    def update(self) -> py_trees.common.Status:
        ok = self.ctx.link is None or self.ctx.link.heartbeat_ok()
        if not ok and self._was_ok and _active(self, self.params.in_states):
            error = HardwareError("heartbeat 0x157 lost", component="secondary_core", critical=False)
            self.ctx.post("fault", str(error), self.name, error=error)
        self._was_ok = ok or not _active(self, self.params.in_states)
        self.feedback_message = "heartbeat ok" if ok else "heartbeat lost"
        return Status.RUNNING


@behaviours.register("WatchHealth")
class WatchHealth(Leaf):
    """Post ``fault`` when one of ``components`` turns unhealthy (or disappears) while active, or is found
    unhealthy on becoming active again when it turned bad meanwhile (as `WatchHeartbeat` does).

    The error carries the component and ``critical``; the Error state decides Idle or Shutdown from it.
    """

    Params = WatchHealthParams
    summary = "turn a component going unhealthy into a fault event"

    def setup(self, **kwargs: object) -> None:
        super().setup(**kwargs)
        self._bad: set[str] = set()

    def update(self) -> py_trees.common.Status:
        health = self.ctx.port.health()
        bad = {c for c in self.params.components if not (health.get(c) is not None and health[c].ok)}
        if _active(self, self.params.in_states):
            for component in sorted(bad - self._bad):
                h = health.get(component)
                detail = "not reported" if h is None else (h.detail or "not healthy")
                error = HardwareError(detail, component=component, critical=self.params.critical)
                self.ctx.post("fault", str(error), self.name, error=error)
            self._bad = bad  # only a new onset is a fault: a component still bad after recovery does not loop
        else:
            # Inactive (in Error for another cause): one that heals is forgotten, one that turns bad is not taken
            # as known, so it is reported once the agent is back. Otherwise a CAN bus-off during a motor fault's
            # Error would never be a fault of its own: nothing would clear its latched stop, and the robot would
            # stand in Idle, held stopped, for good.
            self._bad &= bad
        self.feedback_message = f"unhealthy: {', '.join(sorted(bad))}" if bad else "all healthy"
        return Status.RUNNING


#: The levels from the least to the most urgent, and the limit (a `BatteryStatus` field) below which each holds.
SEVERITY: tuple[BatteryLevel, ...] = ("ok", "low", "return", "critical")
LIMITS: dict[BatteryLevel, str] = {"low": "warn_percent", "return": "return_percent", "critical": "critical_percent"}
#: Points above a limit the charge must climb back (on the dock) before that limit acts again, so a reading
#: that wobbles round a limit does not repeat the reaction.
REARM_POINTS = 5.0


@behaviours.register("WatchBattery")
class WatchBattery(Leaf):
    """React to the state of charge (`RobotPort.battery`) at the limits it carries (``battery.*`` settings).

    * below ``warn_percent`` it warns (`RobotPort.report`: the dashboard's alerts and the recording);
    * below ``return_percent`` it ends the task as ``at_return`` says (``cancel``: at once; ``finish``: the task
      completes first) and then, in IDLE.AUTO, starts a one-step mission to the active map's dock (``home``),
      through ``start_mission`` like any mission (so its autonomy level applies); in MANUAL or MAPPING it asks
      the operator to drive the robot home;
    * below ``critical_percent`` it stops the robot where it is (the task cancelled, MANUAL) and reports critical.

    Each limit acts once on the way down (a lower one marks the higher ones done, so a robot charging from 8 %
    is not warned at 12 %) and again only once the charge is `REARM_POINTS` above it. Outside ``in_states``
    nothing acts; a limit crossed there acts when the agent comes back.
    """

    Params = WatchParams
    summary = "warn at the battery's warning limit, end the task and go home at its return limit, stop at critical"

    def setup(self, **kwargs: object) -> None:
        super().setup(**kwargs)
        self._done: set[BatteryLevel] = set()
        self._going_home = False
        self.bb = self.attach_blackboard_client(self.name, MONITOR_NS)
        self.bb.register_key("battery", access=py_trees.common.Access.WRITE)

    def update(self) -> py_trees.common.Status:
        status = self.ctx.port.battery()
        if status is None:
            self.feedback_message = "no battery reading yet"
            return Status.RUNNING
        self._rearm(status)
        level = status.level
        if level != "ok" and level not in self._done and _active(self, self.params.in_states):
            self._done.update(SEVERITY[1:SEVERITY.index(level) + 1])
            self._react(level, status)
        if self._going_home:
            self._go_home_when_idle(status)
        self.bb.battery = {"percent": round(status.percent, 1), "level": level, "going_home": self._going_home}
        self.feedback_message = f"{status.percent:.0f} % ({level})" + (", going home" if self._going_home else "")
        return Status.RUNNING

    def _rearm(self, status: BatteryStatus) -> None:
        for level in list(self._done):
            if status.percent >= float(getattr(status, LIMITS[level])) + REARM_POINTS:
                self._done.discard(level)

    def _react(self, level: BatteryLevel, status: BatteryStatus) -> None:
        state, percent = self.ctx.state, f"{status.percent:.0f} %"
        executing = state.startswith("EXEC")
        if level == "low":
            self.ctx.port.report("battery", f"Battery low: {percent}. Let it charge soon: at "
                                            f"{status.return_percent:.0f} % it ends its task and goes home")
        elif level == "critical":
            self._going_home = False
            if executing:
                self.ctx.post("cancel", f"battery critical ({percent})", self.name)
            if executing or state == "IDLE.AUTO":
                self.ctx.post("set_manual", f"battery critical ({percent}): stopped where it is", self.name)
            self.ctx.port.report("battery", f"Battery critical: {percent}, stopped where it is; charge it now")
        elif executing and status.at_return == "finish":
            self._going_home = True
            self.ctx.port.report("battery", f"Battery {percent}: the task finishes, then the robot goes home to "
                                            "charge")
        elif executing or state == "IDLE.AUTO":
            self._going_home = True
            if executing:
                self.ctx.post("cancel", f"battery {percent}: going home to charge", self.name)
            self.ctx.port.report("battery", f"Battery {percent}: the task ends and the robot goes home to charge"
                                 if executing else f"Battery {percent}: the robot goes home to charge")
        else:
            self.ctx.port.report("battery", f"Battery {percent}: drive the robot to its dock to charge")

    def _go_home_when_idle(self, status: BatteryStatus) -> None:
        """Start the way home once the task is over and the robot idles in AUTO; an operator who took the robot
        in MANUAL meanwhile is asked to drive it home instead."""
        state = self.ctx.state
        if state == "IDLE.MANUAL":
            self._going_home = False
            self.ctx.port.report("battery", f"Battery {status.percent:.0f} %: drive the robot to its dock to charge")
        if state != "IDLE.AUTO":
            return
        self._going_home = False
        mission = self._home_mission()
        if isinstance(mission, str):
            self.ctx.port.report("battery", f"Battery {status.percent:.0f} %: cannot go home: {mission}")
            return
        self.ctx.post("start_mission", f"battery {status.percent:.0f} %: going home to charge", self.name,
                      mission=mission)

    def _home_mission(self) -> Mission | str:
        """A one-step mission to the active map's dock, or why there is none."""
        # Imported here: missions are built from the leaves, so this module cannot import them at load time.
        from atemr.trees.missions import parse_mission

        navigation = self.ctx.navigation
        dock = None if navigation is None else navigation.places().dock()
        if dock is None:
            return "no dock on this map (a place of kind dock, or 'home'): drive the robot to charge"
        try:
            return parse_mission({"mission": {"name": f"to {dock.name} to charge",
                                              "steps": [{"go_to": {"place": dock.name}}]}})
        except ConfigError as exc:
            return exc.reason
