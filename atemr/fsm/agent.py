"""The agent: lifecycle machine + the current state's behaviour tree + the Monitor tree, one scheduler component.

Each ``tick(now)`` (10 Hz on the robot, any rate in simulation) does, in this order:

1. take the commands submitted since the last tick (`Agent.submit`, thread-safe) and fire them;
2. tick the Monitor tree (status 0x153 out at 2 Hz and on every change, power-off requests and faults in)
   and fire the events it posted;
3. tick the current state's tree, unless the state was entered after this tick's Monitor ran; when the
   tree finishes, fire the state's ``on_success``/``on_failure`` trigger;
4. write the agent's keys to the blackboard.

Changing state stops the old tree (its driving leaves command zero in ``terminate``) and builds the new
one. A new state's tree first runs after the Monitor has published the state, so every state the agent
passes through appears in 0x153, even one (like Error) whose tree finishes in a single tick.

Operator autonomy (`atemr.fsm.autonomy`): while a transition waits for the operator's confirmation, step 3
is replaced by holding still (zero motion), and each tick first applies the operator's answer or the
timeout. Hot reload (`atemr.fsm.reload`): a new agent document is applied in IDLE only (deferred from any
other state), a running mission's later steps are swapped between steps; both keep the blackboard.

Time comes only from ``now``; nothing here blocks or reads a clock. A refused trigger becomes a
`CommandOutcome` (for commands) and a `TransitionRecord` in the trace (for everything), never an exception.
"""

from __future__ import annotations

import itertools
import logging
import queue
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import py_trees

from atemr.config import Config
from atemr.domain.places import NO_PLACES
from atemr.domain.status import state_code, top_level
from atemr.errors import AtemrError, ConfigError
from atemr.fsm.autonomy import DEFAULT_LEVEL, DEFAULT_TIMEOUT_S, Answer, AutonomyGate, Level
from atemr.fsm.machine import Lifecycle, TransitionRecord
from atemr.fsm.reload import ReloadReport, swap_pending_steps
from atemr.fsm.spec import AgentSpec, StateSpec, load_agent
from atemr.msgs import Twist
from atemr.trees.behaviours import Leaf
from atemr.trees.blackboard_watch import BlackboardWatch, BlackboardWrite
from atemr.trees.builder import build, setup_tree
from atemr.trees.context import AGENT_NS, AgentContext, Event
from atemr.trees.missions import Mission
from atemr.trees.ports import LinkPort, NavigationPort, RobotPort
from atemr.trees.progress import TaskProgress, deepest_failure

log = logging.getLogger(__name__)
Status = py_trees.common.Status

#: The agent document shipped with the package checkout.
DEFAULT_AGENT_FILE = Path(__file__).resolve().parents[2] / "trees" / "agent.yaml"
RELOAD = "__reload__"
RELOAD_MISSION = "__reload_mission__"
_OUTCOMES = {"reached": "reached", "failed": "failed", "cancel": "cancelled"}
#: Where the agent's state lies on the blackboard (`Agent._write_blackboard` checks it is still there).
_STATE_KEY = f"{AGENT_NS}/state"


@dataclass(frozen=True)
class CommandOutcome:
    """What became of one submitted command (the dashboard shows ``reason`` when refused)."""

    id: int
    t: float
    trigger: str
    accepted: bool
    source: str
    dest: str | None
    reason: str
    origin: str
    #: "requested" when the command's transition waits for the operator (`atemr.fsm.autonomy`).
    decision: str = ""

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def jsonable(value: Any) -> Any:
    """A JSON-friendly rendering of a blackboard or event value."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if hasattr(value, "__dataclass_fields__"):
        return {k: jsonable(v) for k, v in asdict(value).items()}
    return str(value)


class Agent:
    """The agent as a scheduler component (``name``, ``start``, ``tick(now)``, ``shutdown``).

    ``port``, ``link`` and ``navigation`` are the robot, secondary-core and navigation ports
    (`atemr.trees.ports`; without navigation, goals and missions that drive to a pose are refused with that
    reason); ``on_halt`` is called once when the power-off sequence has finished (the robot then stops its
    scheduler). ``autonomy`` is the robot's starting autonomy level and ``confirm_timeout_s`` how long (robot
    time) a gated transition waits for the operator (`atemr.fsm.autonomy`).
    """

    def __init__(self, spec: AgentSpec, port: RobotPort, link: LinkPort | None = None, *, name: str = "agent",
                 navigation: NavigationPort | None = None, history: int = 200,
                 on_halt: Callable[[], None] | None = None, autonomy: str = DEFAULT_LEVEL,
                 confirm_timeout_s: float = DEFAULT_TIMEOUT_S) -> None:
        self.name = name
        self.spec = spec
        self.context = AgentContext(port=port, link=link, navigation=navigation)
        self.gate = AutonomyGate(autonomy, confirm_timeout_s)
        self.lifecycle = Lifecycle(spec, self.context, gate=self.gate)
        self.on_halt = on_halt
        self.results: deque[CommandOutcome] = deque(maxlen=history)
        self.errors: deque[str] = deque(maxlen=history)
        self.listeners: list[Callable[[TransitionRecord], None]] = []
        #: Hooks for observers (the trace recorder): a tree just ticked (state or Monitor tree), and a tick
        #: ended with these blackboard writes. Called on the agent's thread; a failing one is reported.
        self.tree_listeners: list[Callable[[py_trees.behaviour.Behaviour], None]] = []
        self.tick_listeners: list[Callable[[float, list[BlackboardWrite]], None]] = []
        self.blackboard_watch = BlackboardWatch(jsonable)
        self.ticks = 0
        self._inbox: queue.SimpleQueue[tuple[int, str, dict[str, Any], str]] = queue.SimpleQueue()
        self._ids = itertools.count(1)
        self._lock = threading.RLock()
        self._started = False
        self._tree: py_trees.behaviour.Behaviour | None = None
        self._tree_state: StateSpec | None = None
        self._tree_done = False
        self._monitor: py_trees.behaviour.Behaviour | None = None
        self._counts: dict[Any, int] = {}
        self._halt_reported = False
        self._unpublished = False
        self._progress: TaskProgress | None = None
        self._tick_error: str | None = None
        #: Reports of finished tasks (missions and goals), newest last: outcome, steps, times, errors.
        self.task_reports: deque[dict[str, Any]] = deque(maxlen=history)
        #: Hot-reload requests and what became of them, newest last (`ReloadReport`).
        self.reloads: deque[ReloadReport] = deque(maxlen=20)
        self._deferred: tuple[AgentSpec, ReloadReport] | None = None
        self._bb = py_trees.blackboard.Client(name=f"{name}/agent", namespace=AGENT_NS)
        for key in ("state", "code", "mode", "task", "error", "last_transition", "now"):
            self._bb.register_key(key, access=py_trees.common.Access.WRITE)
        #: What `_write_blackboard` wrote last (state, mode, task, error, last transition).
        self._written: tuple[Any, ...] | None = None

    @classmethod
    def from_file(cls, path: str | Path, port: RobotPort, link: LinkPort | None = None, **kwargs: Any) -> Agent:
        """An agent from a validated document (raises `ConfigError` before anything is built)."""
        return cls(load_agent(path), port, link, **kwargs)

    @classmethod
    def from_config(cls, config: Config, port: RobotPort, link: LinkPort | None = None, **kwargs: Any) -> Agent:
        """The agent as the robot wires it: ``config.agent.file`` or the shipped ``trees/agent.yaml``."""
        kwargs.setdefault("autonomy", config.agent.autonomy)
        kwargs.setdefault("confirm_timeout_s", config.agent.confirm_timeout_s)
        return cls.from_file(config.agent.file or DEFAULT_AGENT_FILE, port, link, **kwargs)

    # -- read-only views ---------------------------------------------------------------------------
    @property
    def state(self) -> str:
        return self.lifecycle.state

    @property
    def halted(self) -> bool:
        """True once the power-off sequence has finished."""
        return self.context.halted

    @property
    def trace(self) -> list[TransitionRecord]:
        """Every transition attempt so far (bounded), oldest first."""
        return list(self.lifecycle.trace)

    @property
    def tree(self) -> py_trees.behaviour.Behaviour | None:
        """The current state's tree (None in a state without one)."""
        return self._tree

    @property
    def monitor(self) -> py_trees.behaviour.Behaviour | None:
        return self._monitor

    # -- commands ----------------------------------------------------------------------------------
    def submit(self, trigger: str, *, origin: str = "dashboard", **kwargs: Any) -> int:
        """Queue ``trigger`` (goal, cancel, set_auto, begin_mapping, save_map, shutdown, start_mission, ...).

        Thread-safe; handled at the start of the next tick. Returns an id to look the outcome up with
        `result`. Keyword arguments are what the guards read (``goal=Pose2D``, ``mission=Mission``,
        ``name="kitchen"``).
        """
        command_id = next(self._ids)
        self._inbox.put((command_id, trigger, kwargs, origin))
        return command_id

    def precheck(self, trigger: str) -> str | None:
        """Why ``trigger`` would be refused in the current state (None: it may be accepted).

        Thread-safe and immediate, for a dashboard that must answer at once; the guards still decide at
        the next tick, so None is "queued", not "accepted".
        """
        with self._lock:
            valid = self.lifecycle.valid_triggers()
            if trigger in valid:
                return None
            return f"'{trigger}' is not valid in state {self.state} (valid here: {', '.join(valid) or 'none'})"

    def refusal(self, trigger: str, **kwargs: Any) -> str | None:
        """Why ``trigger`` would be refused now, guards included (None: it would be taken now). Thread-safe;
        nothing fires: the dashboard answers a refused MANUAL/AUTO switch or mission with the reason at once
        instead of accepting it and reporting the refusal a tick later."""
        with self._lock:
            return self.lifecycle.refusal(trigger, **kwargs)

    def submit_reload(self, path: str | Path, *, origin: str = "dashboard") -> int:
        """Queue a reload of the agent document; applied only if it validates, in IDLE (deferred until then)."""
        return self.submit(RELOAD, origin=origin, path=str(path))

    def request_reload(self, spec: AgentSpec, report: ReloadReport) -> int:
        """Queue a validated agent document (from the file watcher); ``report`` follows what becomes of it."""
        with self._lock:
            self.reloads.append(report)
        return self.submit(RELOAD, origin=report.origin or "reload", spec=spec, report=report)

    def request_mission_reload(self, mission: Mission, report: ReloadReport) -> int:
        """Queue a validated mission: swapped into the running mission between steps, if it is the one running."""
        with self._lock:
            self.reloads.append(report)
        return self.submit(RELOAD_MISSION, origin=report.origin or "reload", mission=mission, report=report)

    def note_reload(self, report: ReloadReport) -> None:
        """Keep a reload that never reached the agent (an invalid file) beside the others, for the dashboard."""
        with self._lock:
            self.reloads.append(report)

    # -- operator autonomy -------------------------------------------------------------------------
    def set_autonomy(self, level: str, *, by: str = "") -> Level:
        """Set the robot's autonomy level (thread-safe; `ConfigError` for an unknown level)."""
        applied = self.gate.set_level(level)
        log.info("autonomy level %s%s", applied, f" (set by {by})" if by else "")
        return applied

    def autonomy_state(self) -> dict[str, Any]:
        """The level, the pending request and the agent's time (for the deadline), JSON-able; thread-safe."""
        return {**self.gate.snapshot(), "now": self.context.now}

    def answer(self, request_id: int, confirm: bool, *, by: str) -> str | None:
        """The operator confirms or denies the pending transition (thread-safe; applied at the next tick).

        Returns why the answer cannot be taken (no such pending request), else None.
        """
        return self.gate.answer(request_id, confirm, by)

    def result(self, command_id: int) -> CommandOutcome | None:
        """The outcome of a submitted command, once its tick has run."""
        return next((r for r in reversed(self.results) if r.id == command_id), None)

    def task_progress(self) -> dict[str, Any] | None:
        """The running task's report so far (each step's status), None when no task runs.

        Cheaper than `snapshot` for a caller that follows a mission tick by tick.
        """
        with self._lock:
            return self._progress.report() if self._progress is not None else None

    # -- scheduler component -----------------------------------------------------------------------
    def start(self) -> None:
        """Build the Monitor and enter the initial state's tree (also done by the first tick)."""
        with self._lock:
            if self._started:
                return
            self._started = True
            if self.spec.monitor is not None:
                self._monitor = build(self.spec.monitor)
                setup_tree(self._monitor, self.context)
            self._enter_state()
            self._write_blackboard()

    def tick(self, now: float) -> None:
        """One agent period at time ``now``."""
        with self._lock:
            self.context.now = now
            if not self._started:
                self.start()
            if self.context.halted:
                return
            self._drain_commands()
            self._resolve_autonomy()
            self._fire_events()
            if self._monitor is not None:
                self._tick(self._monitor)
                self._unpublished = False
                self._fire_events()
            if self.gate.pending is not None:
                self._hold_still()
            elif self._tree is not None and not self._tree_done and not self._unpublished:
                status = self._tick(self._tree)
                if self._progress is not None:
                    self._progress.update(self.context.now, self.context.port.pose())
                if status in (Status.SUCCESS, Status.FAILURE):
                    self._tree_done = True
                    self._on_outcome(status)
                self._fire_events()
            self._apply_deferred_reload()
            self._write_blackboard()
            self.ticks += 1
            writes = self.blackboard_watch.drain(now)
            self._notify(self.tick_listeners, "tick", now, writes)
            if self.context.halted and not self._halt_reported:
                self._halt_reported = True
                log.info("agent halted: power-off acknowledged")
                if self.on_halt is not None:
                    self.on_halt()

    def shutdown(self) -> None:
        """Stop every running tree (driving leaves command zero in their terminate)."""
        with self._lock:
            for tree in (self._tree, self._monitor):
                if tree is not None and tree.status == Status.RUNNING:
                    tree.stop(Status.INVALID)

    # -- reload ------------------------------------------------------------------------------------
    def reload(self, spec: AgentSpec) -> str | None:
        """Swap in a validated document; returns None when applied, else why not (the old one stays).

        Only in IDLE (never mid-Exec or mid-Mapping), with no transition waiting for the operator, and only
        if the new document has the current state. The blackboard, the trace, the autonomy level and the
        context (mode, ports) are kept.
        """
        with self._lock:
            if top_level(self.state) != "IDLE":
                return f"a new agent document is applied only in IDLE (now {self.state})"
            if self.gate.pending is not None:
                return "a transition is waiting for the operator's confirmation"
            if self.state not in spec.states or spec.states[self.state].children:
                return f"the new document has no state {self.state} to continue in"
            lifecycle = Lifecycle(spec, self.context, initial=self.state, gate=self.gate)
            lifecycle.trace.extendleft(reversed(self.lifecycle.trace))
            self._stop_tree()
            if self._monitor is not None and self._monitor.status == Status.RUNNING:
                self._monitor.stop(Status.INVALID)
            self.spec, self.lifecycle = spec, lifecycle
            self._monitor = None
            if spec.monitor is not None:
                self._monitor = build(spec.monitor)
                setup_tree(self._monitor, self.context)
            self._enter_state()
            return None

    # -- internals ---------------------------------------------------------------------------------
    def _drain_commands(self) -> None:
        while True:
            try:
                command_id, trigger, kwargs, origin = self._inbox.get_nowait()
            except queue.Empty:
                return
            if trigger == RELOAD:
                self.results.append(self._reload_command(command_id, kwargs, origin))
                continue
            if trigger == RELOAD_MISSION:
                self.results.append(self._reload_mission(command_id, kwargs["mission"], kwargs["report"], origin))
                continue
            record = self._fire(Event(trigger, kwargs, "", origin))
            self.results.append(CommandOutcome(command_id, record.t, trigger, record.accepted, record.source,
                                              record.dest, record.reason, origin, record.decision))

    def _reload_command(self, command_id: int, kwargs: dict[str, Any], origin: str) -> CommandOutcome:
        """Apply a new agent document now (IDLE), defer it until IDLE (any other state), or refuse it."""
        source, now = self.state, self.context.now
        report: ReloadReport | None = kwargs.get("report")
        spec: AgentSpec | None = kwargs.get("spec")
        path = str(kwargs.get("path") or (report.file if report else ""))
        if spec is None:
            try:
                spec = load_agent(path)
            except ConfigError as exc:
                invalid = ReloadReport.invalid("agent", path, now, exc, origin=origin)
                self.reloads.append(invalid)
                return CommandOutcome(command_id, now, RELOAD, False, source, None, invalid.reason, origin)
            report = ReloadReport("agent", path, now, origin=origin)
            self.reloads.append(report)
        assert report is not None
        if self._deferred is not None:  # a newer version replaces one still waiting for IDLE
            self._deferred[1].status, self._deferred[1].reason = "superseded", "a newer version was requested"
            self._deferred = None
        if top_level(source) != "IDLE" or self.gate.pending is not None:
            self._deferred = (spec, report)
            report.status = "deferred"
            report.reason = (f"deferred: applied when IDLE is reached (now {source})" if top_level(source) != "IDLE"
                             else f"deferred: applied once the operator has answered the waiting transition "
                                  f"(now {source})")
            return CommandOutcome(command_id, now, RELOAD, True, source, None, report.reason, origin)
        refused = self.reload(spec)
        self._settle_reload(report, refused)
        return CommandOutcome(command_id, now, RELOAD, refused is None, source,
                             self.state if refused is None else None, report.reason, origin)

    def _settle_reload(self, report: ReloadReport, why: str | None) -> None:
        report.status = "applied" if why is None else "refused"
        report.reason = f"reloaded {report.file} in {self.state}" if why is None else why
        report.applied_t = self.context.now if why is None else None
        log.info("agent document %s: %s", report.status, report.reason)

    def _apply_deferred_reload(self) -> None:
        """A deferred document goes in on the first tick in IDLE (nothing waiting for the operator)."""
        if self._deferred is None or top_level(self.state) != "IDLE" or self.gate.pending is not None:
            return
        spec, report = self._deferred
        self._deferred = None
        self._settle_reload(report, self.reload(spec))

    def _reload_mission(self, command_id: int, mission: Mission, report: ReloadReport,
                        origin: str) -> CommandOutcome:
        """Swap the running mission's later steps (between steps), or note the file for its next start."""
        source, now = self.state, self.context.now
        task = self.context.task
        running = (top_level(source) == "EXEC" and isinstance(task, Mission) and self._progress is not None
                   and task.file is not None and task.file == mission.file)
        if not running:
            report.status, report.reason = "saved", f"'{mission.name}' is not running: its next start uses the new file"
        else:
            assert self._progress is not None
            try:
                note = swap_pending_steps(self._progress, mission, self.context)
            except AtemrError as exc:
                report.status, report.reason = "refused", f"not swapped, the running mission stays: {exc}"
            else:
                report.status, report.reason, report.applied_t = "applied", f"between steps: {note}", now
        log.info("mission %s: %s", report.status, report.reason)
        return CommandOutcome(command_id, now, RELOAD_MISSION, report.status != "refused", source, None,
                             report.reason, origin)

    def _resolve_autonomy(self) -> None:
        """Apply the operator's answer to the pending request, or the safe default once it timed out."""
        request = self.gate.pending
        if request is None:
            return
        answer = self.gate.take_answer()
        if answer is None and not self.gate.gates(request.level):
            # The operator raised the robot's level to the transition's own: it no longer needs a confirmation.
            answer = Answer(request.id, True, f"level {self.gate.level}")
        if answer is None and self.context.now < request.deadline:
            return
        self.gate.close()
        if answer is not None and answer.confirm:
            self.gate.confirmed = (request, answer.by)
            try:
                self._fire(Event(request.trigger, request.kwargs, f"confirmed by {answer.by}", request.origin))
            finally:
                self.gate.confirmed = None
            return
        if answer is None:
            decision, by = "timed_out", "timeout"
            why = f"no answer within {self.gate.timeout_s:g} s: the safe default (deny) applies"
        else:
            decision, by, why = "denied", answer.by, f"denied by {answer.by}"
        why += f"; '{request.trigger}' not taken, " + (f"fires '{request.on_deny}'" if request.on_deny
                                                       else f"stays in {request.source}")
        self._notify(self.listeners, "transition", self.lifecycle.resolve(request, decision, by, why))
        if request.on_deny:
            self.context.post(request.on_deny, why, f"autonomy:{decision}")

    def _hold_still(self) -> None:
        """While the operator decides the robot does not move: zero on every motion input, every tick."""
        self.context.port.stop_motors()
        self.context.port.command_velocity("joystick", Twist(), self.context.now)

    def _fire_events(self) -> None:
        for _ in range(100):  # bounded: a burst of events cannot spin the tick forever
            events = self.context.take_events()
            if not events:
                return
            for event in events:
                self._fire(event)
        self.errors.append("event storm: more than 100 rounds of events in one tick")

    def _fire(self, event: Event) -> TransitionRecord:
        record = self.lifecycle.fire(event.trigger, reason=event.reason, origin=event.origin, **event.kwargs)
        if record.accepted:
            log.info("%s --%s--> %s %s", record.source, record.trigger, record.dest, record.reason)
        else:
            log.debug("refused %s in %s: %s", record.trigger, record.source, record.reason)
        if record.state_changed:
            if self._progress is not None:
                outcome = _OUTCOMES.get(record.trigger, record.trigger)
                self._progress.finish(outcome, self.context.now, self.context.port.pose(), record.reason)
                self.task_reports.append(self._progress.report())
                self._progress = None
            self._enter_state()
        self._notify(self.listeners, "transition", record)
        if record.state_changed and self.gate.pending is not None:
            request = self.gate.close()
            assert request is not None
            why = f"the state changed to {self.state} before the operator answered"
            self._notify(self.listeners, "transition", self.lifecycle.resolve(request, "superseded", "agent", why))
        return record

    def _notify(self, listeners: list[Callable[..., None]], what: str, *args: Any) -> None:
        for listener in listeners:
            try:
                listener(*args)
            except Exception as exc:  # a broken listener must not stop the agent
                self.errors.append(f"{what} listener failed: {exc!r}")

    def _stop_tree(self) -> None:
        if self._tree is None:
            return
        if self._tree.status == Status.RUNNING:
            self._tree.stop(Status.INVALID)
        for node in self._tree.iterate():
            self._counts.pop(node.id, None)

    def _enter_state(self) -> None:
        """Stop the old state's tree and build, set up and start the new state's."""
        self._stop_tree()
        self._tree, self._tree_state, self._tree_done = None, None, False
        self._unpublished = self._monitor is not None
        tree_state = self.spec.tree_state(self.state)
        if tree_state is None or tree_state.tree is None:
            return
        task = getattr(self.context.task, "spec", None)
        built_tasks: list[py_trees.behaviour.Behaviour] = []
        try:
            root = build(tree_state.tree, task=task, built_tasks=built_tasks)
            setup_tree(root, self.context)
        except AtemrError as exc:
            self.errors.append(f"cannot build the tree of {self.state}: {exc}")
            if tree_state.on_failure:
                self.context.post(tree_state.on_failure, f"tree not built: {exc}", f"tree:{tree_state.name}",
                                  error=exc)
            return
        self._tree, self._tree_state = root, tree_state
        if built_tasks and isinstance(self.context.task, Mission):
            navigation = self.context.navigation
            self._progress = TaskProgress(self.context.task, built_tasks[0], self.context.now,
                                          navigation.places() if navigation is not None else NO_PLACES)

    def _tick(self, root: py_trees.behaviour.Behaviour) -> Status:
        try:
            for node in root.tick():
                self._counts[node.id] = self._counts.get(node.id, 0) + 1
        except Exception as exc:  # a leaf bug becomes the tree's failure, not a dead agent
            text = str(exc) if isinstance(exc, AtemrError) else f"internal error: {exc!r}"
            self.errors.append(f"{root.name}: {text}")
            if root is self._tree:
                self._tick_error = text
            log.exception("tree %s raised", root.name)
            if root.status == Status.RUNNING:
                root.stop(Status.INVALID)
            if self.context.error is None:
                self.context.error = exc if isinstance(exc, AtemrError) else AtemrError(text)
            root.status = Status.FAILURE
        self._notify(self.tree_listeners, "tree", root)
        return root.status

    def node_ticks(self, node: py_trees.behaviour.Behaviour) -> int:
        """How often ``node`` of the current trees has been ticked since its tree was built."""
        return self._counts.get(node.id, 0)

    def _on_outcome(self, status: Status) -> None:
        state = self._tree_state
        assert state is not None and self._tree is not None
        origin = f"tree:{state.name}"
        if status == Status.SUCCESS:
            if state.on_success:
                self.context.post(state.on_success, f"{self._tree.name} succeeded", origin)
            return
        why = failure_reason(self._tree)
        if self._tick_error is not None:
            why, self._tick_error = f"{why}: {self._tick_error}", None
        if state.on_failure:
            error = self.context.error or AtemrError(why)
            self.context.post(state.on_failure, why, origin, error=error)

    def _write_blackboard(self) -> None:
        """The agent's keys; those that did not change since the last tick are not written again (a write costs
        py_trees an activity record and the watch a JSON rendering, ten times a second), unless the blackboard
        lost them (`atemr.trees.context.clear_blackboard`)."""
        last = self.lifecycle.trace[-1] if self.lifecycle.trace else None
        written = (self.state, self.context.mode, getattr(self.context.task, "name", None),
                   str(self.context.error) if self.context.error else None, last)
        if written != self._written or _STATE_KEY not in py_trees.blackboard.Blackboard.storage:
            state, mode, task, error, _ = written
            self._bb.state = state
            self._bb.code = int(state_code(state))
            self._bb.mode = mode
            self._bb.task = task
            self._bb.error = error
            self._bb.last_transition = last.as_dict() if last else None
            self._written = written
        self._bb.now = self.context.now

    # -- snapshot ----------------------------------------------------------------------------------
    def snapshot(self, *, transitions: int = 20) -> dict[str, Any]:
        """A JSON-able picture of the agent now, for the dashboard and tests."""
        with self._lock:
            return {
                "name": self.name,
                "t": self.context.now,
                "ticks": self.ticks,
                "state": self.state,
                "code": int(state_code(self.state)),
                "mode": self.context.mode,
                "halted": self.context.halted,
                "valid_triggers": self.lifecycle.valid_triggers(),
                "task": getattr(self.context.task, "name", None),
                "task_progress": self.task_progress(),
                "last_task": self.task_reports[-1] if self.task_reports else None,
                "error": str(self.context.error) if self.context.error else None,
                "tree": self._node_dict(self._tree) if self._tree is not None else None,
                "monitor": self._node_dict(self._monitor) if self._monitor is not None else None,
                "blackboard": self.blackboard_watch.view(),
                "transitions": [r.as_dict() for r in list(self.lifecycle.trace)[-transitions:]],
                "commands": [r.as_dict() for r in list(self.results)[-transitions:]],
                "errors": list(self.errors)[-transitions:],
                "autonomy": self.autonomy_state(),
                "reloads": [r.as_dict() for r in self.reloads],
                "machine": {
                    "states": list(self.spec.states),
                    "transitions": [{"trigger": t.trigger, "source": list(t.sources), "dest": t.dest,
                                     **({"autonomy": t.autonomy} if t.autonomy else {})}
                                    for t in self.spec.transitions],
                },
            }

    def _node_dict(self, node: py_trees.behaviour.Behaviour) -> dict[str, Any]:
        out: dict[str, Any] = {
            "name": node.name,
            "type": type(node).__name__,
            "status": node.status.name,
            "ticks": self._counts.get(node.id, 0),
            "feedback": node.feedback_message,
        }
        if isinstance(node, Leaf) and node.reason:
            out["reason"] = node.reason
        if node.children:
            out["children"] = [self._node_dict(c) for c in node.children]
        return out


def failure_reason(root: py_trees.behaviour.Behaviour) -> str:
    """The deepest failed node's name and words (`deepest_failure`), for a transition's reason."""
    found = deepest_failure(root)
    if found is None:
        return f"{root.name} failed"
    node, text = found
    return f"{node.name}: {text}" if text else f"{node.name} failed"
