"""Leaves that check the robot and classify failures: component checks (StartUp), error classification
(Error) and the MANUAL/AUTO switch of the twist mux."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import py_trees

from atemr.clock import due
from atemr.errors import AtemrError, HardwareError
from atemr.trees.behaviours import Leaf, behaviours

Status = py_trees.common.Status


@dataclass(frozen=True)
class CheckComponentParams:
    component: str = field(default="", metadata={"required": True, "help": "a name the port reports health for"})
    timeout_s: float = field(default=5.0, metadata={"min": 0.0, "max": 600.0})
    critical: bool = True

    def validate(self) -> None:
        if not self.component:
            raise ValueError("component must be a non-empty name")


@behaviours.register("CheckComponent")
class CheckComponent(Leaf):
    """Wait up to ``timeout_s`` for ``component`` to report healthy.

    SUCCESS as soon as it is; FAILURE after the timeout. A ``critical`` miss leaves a critical
    `HardwareError` in the context for the Error/Shutdown logic; a non-critical one is only this leaf's
    reason (wrap it in ``FailureIsSuccess`` so it does not fail its tree). A component the port does not
    know at all is reported as missing, not as healthy.
    """

    Params = CheckComponentParams
    summary = "wait for a component to report healthy, fail after timeout_s"

    def initialise(self) -> None:
        self._deadline = self.ctx.now + self.params.timeout_s

    def update(self) -> py_trees.common.Status:
        health = self.ctx.port.health().get(self.params.component)
        if health is not None and health.ok:
            self.feedback_message = "ok"
            return Status.SUCCESS
        detail = "not reported by the robot" if health is None else (health.detail or "not healthy")
        self.feedback_message = detail
        if not due(self.ctx.now, self._deadline):
            return Status.RUNNING
        error = HardwareError(
            f"{detail} after {self.params.timeout_s:g} s", component=self.params.component,
            critical=self.params.critical,
        )
        if error.critical and (self.ctx.error is None or not self.ctx.error.critical):
            self.ctx.error = error  # a non-critical miss is only this leaf's reason (and the 0x153 bit)
        return self.fail(str(error))


@behaviours.register("ClassifyError")
class ClassifyError(Leaf):
    """SUCCESS when the error being handled is not critical (back to Idle), FAILURE when it is (Shutdown).

    Classification is by the error's type and its ``critical`` flag (`atemr.errors`), never by its text.
    """

    summary = "succeed for a non-critical error, fail for a critical one"

    def update(self) -> py_trees.common.Status:
        error: AtemrError | None = self.ctx.error
        if error is None:
            self.feedback_message = "no error recorded"
            return Status.SUCCESS
        kind = type(error).__name__
        if error.critical:
            return self.fail(f"critical {kind}: {error}")
        self.feedback_message = f"non-critical {kind}: {error}"
        return Status.SUCCESS


#: The error's component whose cause is the 0x157 heartbeat (`WatchHeartbeat`, `CheckHeartbeat`).
HEARTBEAT_COMPONENT = "secondary_core"


@behaviours.register("AwaitRecovery")
class AwaitRecovery(Leaf):
    """RUNNING while the cause of the error being handled lasts, SUCCESS once it is gone (Error → Idle).

    The cause is the error's component: the secondary core's heartbeat (until `LinkPort.heartbeat_ok`), or a
    component the port reports health for (until it is healthy again; meanwhile `RobotPort.clear_faults`
    is asked every tick to clear what the hardware latched, e.g. the motor driver's fault once both motors
    answer with no error flag). An error without a component, or with one the robot does not report (an
    invalid goal, a failed task), has no lasting cause: SUCCESS at once. So the agent holds ERROR while a
    motor is unplugged or the heartbeat is lost, instead of recovering and failing again every tick.
    """

    summary = "wait until the error's cause is gone (heartbeat back, component healthy, faults cleared)"

    def update(self) -> py_trees.common.Status:
        cause = self._cause(self.ctx.error)
        if cause is None:
            self.feedback_message = "cause gone"
            return Status.SUCCESS
        self.feedback_message = f"waiting: {cause}"
        return Status.RUNNING

    def _cause(self, error: AtemrError | None) -> str | None:
        component = getattr(error, "component", None)
        if not component:
            return None
        if component == HEARTBEAT_COMPONENT:
            link = self.ctx.link
            return None if link is None or link.heartbeat_ok() else "heartbeat 0x157 still lost"
        health = self.ctx.port.health().get(component)
        if health is None or health.ok:
            return None
        why = self.ctx.port.clear_faults()
        if why is None:
            health = self.ctx.port.health().get(component)
            if health is None or health.ok:
                return None
        return f"{component}: {why or health.detail or 'not healthy'}"


@dataclass(frozen=True)
class SetModeParams:
    mode: Literal["MANUAL", "AUTO"] = field(default="MANUAL", metadata={"required": True})


@behaviours.register("SetMode")
class SetMode(Leaf):
    """Put the twist mux in MANUAL or AUTO mode (and record the mode for the 0x153 AUTO bit)."""

    Params = SetModeParams
    summary = "switch the twist mux to MANUAL or AUTO"

    def update(self) -> py_trees.common.Status:
        self.ctx.port.set_mode(self.params.mode)
        self.ctx.mode = self.params.mode
        return Status.SUCCESS


@dataclass(frozen=True)
class CheckHeartbeatParams:
    timeout_s: float = field(default=5.0, metadata={"min": 0.0, "max": 600.0})
    critical: bool = True


@behaviours.register("CheckHeartbeat")
class CheckHeartbeat(Leaf):
    """Wait up to ``timeout_s`` for the secondary core's 0x157 heartbeat exchange to be established."""

    Params = CheckHeartbeatParams
    summary = "wait for the 0x157 heartbeat with the secondary core, fail after timeout_s"

    def initialise(self) -> None:
        self._deadline = self.ctx.now + self.params.timeout_s

    def update(self) -> py_trees.common.Status:
        link = self.ctx.link
        if link is not None and link.heartbeat_ok():
            self.feedback_message = "heartbeat established"
            return Status.SUCCESS
        detail = "no secondary-core link" if link is None else "no heartbeat answer"
        self.feedback_message = detail
        if not due(self.ctx.now, self._deadline):
            return Status.RUNNING
        error = HardwareError(f"{detail} after {self.params.timeout_s:g} s", component="secondary_core",
                              critical=self.params.critical)
        if self.ctx.error is None or (error.critical and not self.ctx.error.critical):
            self.ctx.error = error
        return self.fail(str(error))
