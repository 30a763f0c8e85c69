"""The lifecycle machine: transitions' ``HierarchicalMachine`` built from an `AgentSpec`.

`Lifecycle.fire` is the only way in. It never raises into the agent's loop: a trigger that is not valid in
the current state, guards that all say no, or a callback that fails, each come back as a refused
`TransitionRecord` with the reason, and every attempt (accepted or not) is kept in the trace.

With an `AutonomyGate`, a transition whose ``autonomy`` level is above the robot's gets one more condition,
checked after its own guards: it holds only for the request the operator confirmed; otherwise it opens a
`ConfirmRequest` and the attempt is refused as ``decision="requested"`` (see `atemr.fsm.autonomy`).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from typing import Any

from transitions import EventData
from transitions.extensions import HierarchicalMachine
from transitions.extensions.nesting import NestedState

from atemr.domain.status import SEPARATOR, state_code
from atemr.errors import AtemrError
from atemr.fsm.autonomy import AutonomyGate, ConfirmRequest, safety_reason
from atemr.fsm.guards import Callback, Guard, GuardInput, callbacks, guards
from atemr.fsm.spec import AgentSpec, TransitionDict, TransitionSpec
from atemr.registry import Registry
from atemr.trees.context import AgentContext


class _DottedState(NestedState):
    """Nested states named ``IDLE.AUTO`` (the default separator '_' would clash with names like POWER_OFF)."""

    separator = SEPARATOR


class _Machine(HierarchicalMachine):
    state_cls = _DottedState


@dataclass(frozen=True)
class TransitionRecord:
    """One attempt to fire a trigger: what happened and why (JSON-able with `as_dict`)."""

    t: float
    trigger: str
    source: str
    dest: str | None
    accepted: bool
    reason: str = ""
    origin: str = ""
    #: Operator autonomy: "requested", "confirmed", "denied", "timed_out" or "superseded" ("" otherwise).
    decision: str = ""
    #: Who decided: the operator's user name, or "timeout" / "agent".
    decided_by: str = ""

    @property
    def state_changed(self) -> bool:
        return self.accepted and self.dest is not None and self.dest != self.source

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["code"] = int(state_code(self.dest)) if self.dest else None
        return out


class _Model:
    """The object transitions decorates with ``state`` and ``trigger``."""

    state: str
    trigger: Callable[..., bool]


class Lifecycle:
    """The agent's state machine over ``context``; guards and callbacks come from the given registries."""

    def __init__(self, spec: AgentSpec, context: AgentContext, *, guard_registry: Registry[Guard] = guards,
                 callback_registry: Registry[Callback] = callbacks, initial: str | None = None,
                 trace_size: int = 1000, gate: AutonomyGate | None = None) -> None:
        self.spec = spec
        self.context = context
        self.gate = gate
        self._firing: tuple[str, str, str] = ("", "", "")  # source, origin, reason of the trigger being fired
        self._opened: ConfirmRequest | None = None
        self._guards = guard_registry
        self._callbacks = callback_registry
        self.trace: deque[TransitionRecord] = deque(maxlen=trace_size)
        self._reasons: list[str] = []
        self._kwargs: dict[str, Any] = {}
        self.model = _Model()
        start = spec.leaf_of(initial or spec.initial)
        self.machine = _Machine(
            model=self.model, states=spec.state_dicts(), transitions=self._transition_dicts(), initial=start,
            auto_transitions=False, send_event=True, ignore_invalid_triggers=False, queued=False,
        )
        for name, state in spec.states.items():
            for cb in state.on_enter:
                self.machine.get_state(name).add_callback("enter", self._callback(cb))
            for cb in state.on_exit:
                self.machine.get_state(name).add_callback("exit", self._callback(cb))
        context.state = self.state
        self.trace.append(TransitionRecord(context.now, "(initial)", "", self.state, True, "agent started"))

    @property
    def state(self) -> str:
        """The current (leaf) state's full name, e.g. ``IDLE.MANUAL``."""
        return str(self.model.state)

    def valid_triggers(self, state: str | None = None) -> list[str]:
        """Triggers with a transition out of ``state`` (default: the current state)."""
        return self.spec.triggers_from(state or self.state)

    def fire(self, trigger: str, *, reason: str = "", origin: str = "", **kwargs: Any) -> TransitionRecord:
        """Try ``trigger`` now; returns what happened, never raises for a refusal."""
        source = self.state
        now = self.context.now
        if trigger not in self.valid_triggers(source):
            valid = ", ".join(self.valid_triggers(source)) or "none"
            why = f"'{trigger}' is not valid in state {source} (valid here: {valid})"
            return self._record(TransitionRecord(now, trigger, source, None, False, why, origin))
        self._reasons = [reason] if reason else []
        self._kwargs = kwargs
        self._firing, self._opened = (source, origin, reason), None
        confirmed = self.gate.confirmed if self.gate is not None else None
        decision, by = ("confirmed", confirmed[1]) if confirmed is not None else ("", "")
        try:
            moved = self.model.trigger(trigger, **kwargs)
        except AtemrError as exc:
            return self._after_error(trigger, source, origin, f"{type(exc).__name__}: {exc}")
        except Exception as exc:  # a callback bug must not take the agent loop down
            return self._after_error(trigger, source, origin, f"internal error in a callback: {exc!r}")
        self.context.state = self.state
        text = "; ".join(r for r in self._reasons if r)
        if self._opened is not None:
            decision, by = "requested", ""
        if not moved:
            return self._record(TransitionRecord(now, trigger, source, None, False, text or "guards refused",
                                                 origin, decision, by))
        return self._record(TransitionRecord(now, trigger, source, self.state, True, text, origin, decision, by))

    def refusal(self, trigger: str, **kwargs: Any) -> str | None:
        """Why the guards would refuse ``trigger`` now (None: a transition of it would be taken), without
        firing it: no callback runs, no autonomy request opens. For a caller that must answer at once."""
        source = self.state
        if trigger not in self.valid_triggers(source):
            valid = ", ".join(self.valid_triggers(source)) or "none"
            return f"'{trigger}' is not valid in state {source} (valid here: {valid})"
        reasons: list[str] = []
        for t in self.spec.transitions:
            if t.trigger != trigger or not self.spec.covers(t, source):
                continue
            g = GuardInput(self.context, kwargs)
            why = [w for w in (self._guards.get(name)(g) for name in t.conditions) if w is not None]
            why += [f"{name} holds" for name in t.unless if self._guards.get(name)(g) is None]
            if not why:
                return None
            reasons.extend(w for w in why if w not in reasons)
        return "; ".join(reasons)

    def resolve(self, request: ConfirmRequest, decision: str, by: str, why: str) -> TransitionRecord:
        """Record how a pending request ended without being taken (denied, timed out, superseded)."""
        return self._record(TransitionRecord(self.context.now, request.trigger, request.source, None, False, why,
                                             request.origin, decision, by))

    def _after_error(self, trigger: str, source: str, origin: str, why: str) -> TransitionRecord:
        self.context.state = self.state
        changed = self.state != source
        text = "; ".join([*(r for r in self._reasons if r), why])
        return self._record(TransitionRecord(self.context.now, trigger, source, self.state if changed else None,
                                             changed, text, origin))

    def _record(self, record: TransitionRecord) -> TransitionRecord:
        self.trace.append(record)
        return record

    # -- wiring guards and callbacks ---------------------------------------------------------------
    def _guard(self, name: str, negated: bool) -> Callable[[EventData], bool]:
        guard = self._guards.get(name)

        def check(event: EventData) -> bool:
            why = guard(GuardInput(self.context, event.kwargs, self._reasons))
            note = why if why is not None else (f"{name} holds" if negated else None)
            if note is not None and note not in self._reasons:
                self._reasons.append(note)
            return why is None

        return check

    def _callback(self, name: str) -> Callable[[EventData], None]:
        callback = self._callbacks.get(name)

        def run(event: EventData) -> None:
            callback(GuardInput(self.context, event.kwargs, list(self._reasons)))

        return run

    def _autonomy(self, t: TransitionSpec) -> Callable[[EventData], bool]:
        """The gate condition of a transition with a level (checked after its own guards)."""

        def check(event: EventData) -> bool:
            gate = self.gate
            if gate is None or t.autonomy is None or not gate.gates(t.autonomy):
                return True
            confirmed = gate.confirmed
            if confirmed is not None and confirmed[0].index == t.index:
                return True
            source, origin, reason = self._firing
            dest = self.spec.leaf_of(t.dest)
            if gate.pending is not None:
                self._reasons.append(f"'{t.trigger}' to {dest} needs autonomy {t.autonomy} and another "
                                     f"transition ('{gate.pending.trigger}') is waiting for the operator")
                return False
            self._opened = gate.open(now=self.context.now, trigger=t.trigger, source=source, dest=dest,
                                     level=t.autonomy, index=t.index, origin=origin, reason=reason,
                                     on_deny=t.on_deny, kwargs=dict(event.kwargs))
            self._reasons.append(f"waits for the operator: '{t.trigger}' to {dest} needs autonomy {t.autonomy}, "
                                 f"the robot is at {self._opened.robot_level} (request {self._opened.id}, "
                                 f"{gate.timeout_s:g} s)")
            return False

        return check

    def _transition_dicts(self) -> list[TransitionDict]:
        out: list[TransitionDict] = []
        for t in self.spec.transitions:
            d: TransitionDict = {"trigger": t.trigger, "source": list(t.sources) if t.sources != ("*",) else "*",
                                 "dest": t.dest}
            d["conditions"] = [self._guard(g, negated=False) for g in t.conditions]
            d["unless"] = [self._guard(g, negated=True) for g in t.unless]
            if t.autonomy is not None and safety_reason(t.trigger, t.dest) is None:
                # transitions checks `conditions`, then `unless`: the gate goes last, as a negated check.
                gate = self._autonomy(t)
                d["unless"].append(lambda event, gate=gate: not gate(event))
            d["before"] = [self._callback(c) for c in t.before]
            d["after"] = [self._callback(c) for c in t.after]
            out.append(d)
        return out


def trace_dicts(records: Iterable[TransitionRecord]) -> list[dict[str, Any]]:
    """The trace as JSON-able dicts."""
    return [r.as_dict() for r in records]


def replay(spec: AgentSpec, records: Iterable[TransitionRecord]) -> list[TransitionRecord]:
    """Re-run the accepted transitions of a recorded trace on a fresh machine and return its records.

    For each step the guards are set to what makes the recorded transition the one transitions picks
    (its ``conditions`` hold, its ``unless`` guards do not); callbacks are not run. A trace recorded
    from a different document, or edited, comes back with a refused or different record at that step.
    """
    recorded = list(records)
    steps = [r for r in recorded if r.accepted and r.trigger != "(initial)"]
    first = next((r for r in recorded if r.trigger == "(initial)"), None)
    inputs: dict[str, bool] = {}

    def answer(name: str) -> Guard:
        def guard(g: GuardInput) -> str | None:
            return None if inputs.get(name, True) else f"{name} was false when recorded"

        return guard

    guard_registry: Registry[Guard] = Registry("replay-guards")
    for name in {g for t in spec.transitions for g in (*t.conditions, *t.unless)}:
        guard_registry.add(name, answer(name))
    callback_registry: Registry[Callback] = Registry("replay-callbacks")
    names = {c for t in spec.transitions for c in (*t.before, *t.after)}
    names |= {c for s in spec.states.values() for c in (*s.on_enter, *s.on_exit)}
    def skip(g: GuardInput) -> None:
        return None

    for name in names:
        callback_registry.add(name, skip)
    context = AgentContext(port=None)  # type: ignore[arg-type]  # guards and callbacks here never use it
    machine = Lifecycle(spec, context, guard_registry=guard_registry, callback_registry=callback_registry,
                        initial=first.dest if first and first.dest else None)
    out: list[TransitionRecord] = []
    for record in steps:
        context.now = record.t
        inputs.clear()
        for t in spec.transitions:
            if t.trigger == record.trigger and spec.covers(t, machine.state) and spec.leaf_of(t.dest) == record.dest:
                inputs.update({g: True for g in t.conditions})
                inputs.update({g: False for g in t.unless})
                break
        out.append(machine.fire(record.trigger, reason=record.reason, origin=record.origin))
    return out
