"""The Monitor's leaves: the agent's hub to the outside, ticked every agent tick whatever the state.

They never finish (RUNNING forever under the Monitor's Parallel) and keep their memory between ticks:
the status publisher sends CAN 0x153 at ``period_s`` and at once on any change; the watchers turn
edges (a power-off request, a lost heartbeat, a component going bad) into events for the machine.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import py_trees

from atemr.clock import due
from atemr.domain.status import AgentBits, HardwareBits, state_code
from atemr.errors import HardwareError
from atemr.io.can import PrimaryStatus
from atemr.trees.behaviours import Leaf, behaviours
from atemr.trees.context import MONITOR_NS
from atemr.trees.ports import HARDWARE_COMPONENTS

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

    def update(self) -> py_trees.common.Status:
        status = compose_status(self)
        periodic = due(self.ctx.now, self._last_t + self.params.period_s)
        if self.ctx.link is not None and (periodic or status != self.last):
            self.ctx.link.publish_status(status)
            self.last, self._last_t = status, self.ctx.now
            self.sent += 1
        self.bb.status = status.fields()
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
