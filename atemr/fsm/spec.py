"""The agent document (``trees/agent.yaml``): the lifecycle machine in transitions' own dict shape plus one
behaviour tree per state and the Monitor tree, validated as a whole before anything is built.

Shape (the `StateDict`/`TransitionDict` TypedDicts are what transitions receives)::

    version: 1
    initial: STARTUP
    states:
      - name: IDLE                 # top-level names are the 0x153 state codes: STARTUP, IDLE, EXEC, ...
        initial: MANUAL            # nested states: children + initial, named IDLE.MANUAL
        children: [{name: MANUAL, tree: {...}}, {name: AUTO, tree: {...}}]
        tree: {...}                # a state's tree; a child without one runs its parent's
        on_success: trigger        # fired when the state's tree succeeds / fails
        on_failure: trigger
        on_enter: [callback]       # callbacks from atemr.fsm.guards.callbacks
        on_exit: [callback]
    transitions:
      - {trigger: goal, source: IDLE.AUTO, dest: EXEC, conditions: [goal_valid], after: [set_goal_task],
         autonomy: high, on_deny: null}   # autonomy: off|low|high|full; on_deny: trigger fired on a denial
    monitor: {...}                 # the tree ticked every tick, whatever the state

Checked: unknown keys, wrong types, duplicate or badly named states, an initial or ``dest`` that does not
exist, unknown guards/callbacks (closest names), an ``autonomy`` level that is not one of off/low/high/full
or sits on a safety transition (never gated), an ``on_deny`` without a level or with no ungated transition
out of every source, an ``on_success``/``on_failure`` trigger with no
transition out of its state, a state no transition can reach, and every tree (see `atemr.trees.builder`).
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NotRequired, TypedDict

from atemr.domain.status import SEPARATOR, TOP_LEVEL_STATES
from atemr.errors import ConfigError
from atemr.fsm.autonomy import LEVELS, Level, safety_reason
from atemr.fsm.guards import callbacks, guards
from atemr.registry import Registry
from atemr.trees.builder import NodeSpec, parse_node
from atemr.typed import Source
from atemr.yamlsafe import load_yaml, mark_of


class StateDict(TypedDict):
    """A state as transitions' ``HierarchicalMachine`` takes it."""

    name: str
    children: NotRequired[list[StateDict]]
    initial: NotRequired[str]


class TransitionDict(TypedDict):
    """A transition as transitions takes it (guards and callbacks already resolved to callables)."""

    trigger: str
    source: str | list[str]
    dest: str
    conditions: NotRequired[list[Any]]
    unless: NotRequired[list[Any]]
    before: NotRequired[list[Any]]
    after: NotRequired[list[Any]]


_NAME = re.compile(r"^[A-Z][A-Z0-9_]*$")
_TRIGGER = re.compile(r"^[a-z][a-z0-9_]*$")
_TOP_KEYS = ("version", "description", "initial", "states", "transitions", "monitor")
_STATE_KEYS = ("name", "description", "children", "initial", "tree", "on_success", "on_failure", "on_enter",
               "on_exit")
_TRANSITION_KEYS = ("trigger", "source", "dest", "conditions", "unless", "before", "after", "description", "autonomy",
                    "on_deny")


@dataclass(frozen=True)
class Where:
    """Where something was written, for errors raised after parsing."""

    file: str | None = None
    line: int | None = None
    column: int | None = None
    path: str = ""

    def error(self, message: str) -> ConfigError:
        return ConfigError(message, file=self.file, line=self.line, column=self.column, path=self.path)


@dataclass(frozen=True)
class StateSpec:
    """One state; ``name`` is the full dotted name (``IDLE.AUTO``)."""

    name: str
    children: tuple[str, ...] = ()
    initial: str | None = None
    tree: NodeSpec | None = None
    on_success: str | None = None
    on_failure: str | None = None
    on_enter: tuple[str, ...] = ()
    on_exit: tuple[str, ...] = ()
    description: str = ""
    where: Where = field(default_factory=Where)

    @property
    def parent(self) -> str | None:
        return self.name.rsplit(SEPARATOR, 1)[0] if SEPARATOR in self.name else None


@dataclass(frozen=True)
class TransitionSpec:
    """One transition; ``sources`` are full state names, or ``("*",)`` for every state."""

    trigger: str
    sources: tuple[str, ...]
    dest: str
    conditions: tuple[str, ...] = ()
    unless: tuple[str, ...] = ()
    before: tuple[str, ...] = ()
    after: tuple[str, ...] = ()
    description: str = ""
    index: int = 0
    where: Where = field(default_factory=Where)
    #: The autonomy level the robot needs to take this transition on its own (`atemr.fsm.autonomy`).
    autonomy: Level | None = None
    #: The trigger fired when the operator denies it or the confirmation times out (None: stay).
    on_deny: str | None = None


@dataclass(frozen=True)
class AgentSpec:
    """The validated agent document."""

    initial: str
    states: dict[str, StateSpec]
    roots: tuple[str, ...]
    transitions: tuple[TransitionSpec, ...]
    monitor: NodeSpec | None
    file: str | None = None
    description: str = ""

    # -- queries -----------------------------------------------------------------------------------
    def leaf_of(self, state: str) -> str:
        """The leaf state entered when entering ``state`` (following ``initial``)."""
        spec = self.states[state]
        while spec.children:
            assert spec.initial is not None
            spec = self.states[spec.initial]
        return spec.name

    def ancestors(self, state: str) -> list[str]:
        """``state`` and its parents, innermost first (``IDLE.AUTO`` → [IDLE.AUTO, IDLE])."""
        parts = state.split(SEPARATOR)
        return [SEPARATOR.join(parts[:i]) for i in range(len(parts), 0, -1)]

    def leaves(self) -> list[str]:
        """Every state without children, in document order."""
        return [n for n, s in self.states.items() if not s.children]

    def covers(self, transition: TransitionSpec, state: str) -> bool:
        """Whether ``transition`` can fire while the machine is in (leaf) ``state``."""
        return transition.sources == ("*",) or any(a in transition.sources for a in self.ancestors(state))

    def tree_state(self, state: str) -> StateSpec | None:
        """The state whose tree runs in ``state``: its own, else the nearest ancestor's."""
        for name in self.ancestors(state):
            if self.states[name].tree is not None:
                return self.states[name]
        return None

    def triggers_from(self, state: str) -> list[str]:
        """Triggers with at least one transition out of ``state``."""
        return sorted({t.trigger for t in self.transitions if self.covers(t, state)})

    def state_dicts(self) -> list[StateDict]:
        """The states in the nested dict shape transitions takes."""

        def one(name: str) -> StateDict:
            spec = self.states[name]
            out: StateDict = {"name": name.rsplit(SEPARATOR, 1)[-1]}
            if spec.children:
                out["children"] = [one(c) for c in spec.children]
                assert spec.initial is not None
                out["initial"] = spec.initial.rsplit(SEPARATOR, 1)[-1]
            return out

        return [one(r) for r in self.roots]


# -- parsing ---------------------------------------------------------------------------------------
def load_agent(path: str | Path) -> AgentSpec:
    """Read and validate an agent document from a file."""
    return parse_agent(load_yaml(path), str(path))


def parse_agent(document: Any, file: str | None = None) -> AgentSpec:
    """Validate a loaded agent document (from `atemr.yamlsafe.load_yaml`) into an `AgentSpec`."""
    source = Source("file", file) if file else Source("argument")
    if not isinstance(document, Mapping):
        raise ConfigError("an agent document is a mapping with 'initial', 'states' and 'transitions'", file=file)
    _check_keys(document, _TOP_KEYS, source, "", "the agent document")
    version = document.get("version", 1)
    if version != 1:
        raise source.error(f"unsupported version {version!r}; this build reads version 1", "version", document,
                           "version")
    description = _opt_str(document, "description", source, "description")
    states: dict[str, StateSpec] = {}
    raw_states = document.get("states")
    if not isinstance(raw_states, list) or not raw_states:
        raise source.error("'states' must be a non-empty list of states", "states", document,
                           "states" if "states" in document else None)
    roots = _parse_states(raw_states, None, source, "states", states)
    for root in roots:
        if root not in TOP_LEVEL_STATES:
            s = states[root]
            raise s.where.error(f"top-level state '{root}' has no CAN 0x153 state code; top-level states are "
                                f"{', '.join(TOP_LEVEL_STATES)}")
    initial = document.get("initial")
    if not isinstance(initial, str):
        raise source.error("'initial' must name the state the agent starts in", "initial", document,
                           "initial" if "initial" in document else None)
    if initial not in states:
        raise source.error(_unknown("state", initial, states), "initial", document, "initial")
    raw_transitions = document.get("transitions")
    if not isinstance(raw_transitions, list) or not raw_transitions:
        raise source.error("'transitions' must be a non-empty list", "transitions", document,
                           "transitions" if "transitions" in document else None)
    transitions = tuple(
        _parse_transition(t, i, source, raw_transitions, states) for i, t in enumerate(raw_transitions)
    )
    monitor = None
    if "monitor" in document:
        monitor = parse_node(document["monitor"], source, "monitor", parent=document, key="monitor",
                             allow_task=False)
    spec = AgentSpec(initial, states, tuple(roots), transitions, monitor, file, description)
    _check_outcome_triggers(spec)
    _check_on_deny(spec)
    _check_reachable(spec)
    return spec


def _unknown(what: str, name: object, known: Sequence[str] | Mapping[str, Any]) -> str:
    close = difflib.get_close_matches(str(name), list(known), n=3, cutoff=0.5)
    hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
    return f"unknown {what} '{name}'{hint}; known: {', '.join(known)}"


def _check_keys(node: Mapping[str, Any], allowed: Sequence[str], source: Source, path: str, what: str) -> None:
    for key in node:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), list(allowed), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise source.error(f"unknown key '{key}' in {what}{hint}; allowed: {', '.join(allowed)}",
                               f"{path}.{key}" if path else str(key), node, key, on_key=True)


def _opt_str(node: Mapping[str, Any], key: str, source: Source, path: str) -> str:
    value = node.get(key, "")
    if not isinstance(value, str):
        raise source.error(f"'{key}' must be a string, got {value!r}", path, node, key)
    return value


def _names(node: Mapping[str, Any], key: str, source: Source, path: str, registry: Registry[Any] | None, *,
           what: str) -> tuple[str, ...]:
    """A name or list of names under ``key``, each known to ``registry`` (if given)."""
    if key not in node:
        return ()
    raw = node[key]
    items = [raw] if isinstance(raw, str) else raw
    if not isinstance(items, list) or not all(isinstance(i, str) for i in items):
        raise source.error(f"'{key}' must be a {what} name or a list of them, got {raw!r}", f"{path}.{key}",
                           node, key)
    if registry is not None:
        for i, item in enumerate(items):
            if item not in registry:
                container, k = (raw, i) if isinstance(raw, list) else (node, key)
                raise source.error(registry.unknown_message(item), f"{path}.{key}", container, k)
    return tuple(items)


def _where(node: Any, source: Source, path: str) -> Where:
    line, column = mark_of(node)
    return Where(source.name, line, column, path)


def _parse_states(raw: list[Any], parent: str | None, source: Source, path: str,  # noqa: PLR0912  checks one state's keys in document order, one error each
                  out: dict[str, StateSpec]) -> list[str]:
    names: list[str] = []
    for i, node in enumerate(raw):
        p = f"{path}[{i}]"
        if not isinstance(node, Mapping):
            raise source.error(f"a state is a mapping with a 'name', got {node!r}", p, raw, i)
        _check_keys(node, _STATE_KEYS, source, p, "a state")
        local = node.get("name")
        if not isinstance(local, str) or not _NAME.match(local):
            raise source.error(f"a state needs a 'name' in capitals (A-Z, 0-9, _), got {local!r}", f"{p}.name",
                               node, "name" if "name" in node else None)
        full = f"{parent}{SEPARATOR}{local}" if parent else local
        if full in out:
            raise source.error(f"state '{full}' is declared twice", f"{p}.name", node, "name")
        children: tuple[str, ...] = ()
        initial = None
        # Reserve the name first so a child cannot reuse it, then parse children.
        out[full] = StateSpec(full)
        if "children" in node:
            kids = node["children"]
            if not isinstance(kids, list) or not kids:
                raise source.error("'children' must be a non-empty list of states", f"{p}.children", node,
                                   "children")
            children = tuple(_parse_states(kids, full, source, f"{p}.children", out))
            init = node.get("initial")
            if not isinstance(init, str):
                raise source.error("a state with children needs 'initial': the child entered first",
                                   f"{p}.initial", node, "initial" if "initial" in node else None)
            initial = f"{full}{SEPARATOR}{init}"
            if initial not in children:
                local_children = [c.rsplit(SEPARATOR, 1)[-1] for c in children]
                raise source.error(_unknown(f"child of {full}", init, local_children), f"{p}.initial", node,
                                   "initial")
        elif "initial" in node:
            raise source.error("'initial' only makes sense with 'children'", f"{p}.initial", node, "initial",
                               on_key=True)
        tree = None
        if "tree" in node:
            tree = parse_node(node["tree"], source, f"{p}.tree", parent=node, key="tree")
        outcome: dict[str, str | None] = {}
        for key in ("on_success", "on_failure"):
            value = node.get(key)
            if value is not None and (not isinstance(value, str) or not _TRIGGER.match(value)):
                raise source.error(f"'{key}' must be a trigger name (lower case), got {value!r}", f"{p}.{key}",
                                   node, key)
            if value is not None and tree is None:
                raise source.error(f"'{key}' needs a 'tree' in the same state", f"{p}.{key}", node, key,
                                   on_key=True)
            outcome[key] = value
        out[full] = StateSpec(
            full, children, initial, tree, outcome["on_success"], outcome["on_failure"],
            _names(node, "on_enter", source, p, callbacks, what="callback"),
            _names(node, "on_exit", source, p, callbacks, what="callback"),
            _opt_str(node, "description", source, f"{p}.description"), _where(node, source, p),
        )
        names.append(full)
    return names


def _parse_transition(node: Any, i: int, source: Source, raw: list[Any], states: dict[str, StateSpec]
                      ) -> TransitionSpec:
    p = f"transitions[{i}]"
    if not isinstance(node, Mapping):
        raise source.error(f"a transition is a mapping with trigger, source and dest, got {node!r}", p, raw, i)
    _check_keys(node, _TRANSITION_KEYS, source, p, "a transition")
    for key in ("trigger", "source", "dest"):
        if key not in node:
            raise source.error(f"a transition needs '{key}'", p, node)
    trigger = node["trigger"]
    if not isinstance(trigger, str) or not _TRIGGER.match(trigger):
        raise source.error(f"'trigger' must be a lower-case name (a-z, 0-9, _), got {trigger!r}", f"{p}.trigger",
                           node, "trigger")
    raw_source = node["source"]
    sources = [raw_source] if isinstance(raw_source, str) else raw_source
    if not isinstance(sources, list) or not sources or not all(isinstance(s, str) for s in sources):
        raise source.error(f"'source' must be a state name, a list of them or '*', got {raw_source!r}",
                           f"{p}.source", node, "source")
    if "*" in sources and len(sources) > 1:
        raise source.error("'*' (every state) cannot be combined with other sources", f"{p}.source", node, "source")
    for k, s in enumerate(sources):
        if s != "*" and s not in states:
            where: tuple[Any, Any] = (raw_source, k) if isinstance(raw_source, list) else (node, "source")
            raise source.error(_unknown("source state", s, states), f"{p}.source", *where)
    dest = node["dest"]
    if not isinstance(dest, str) or dest not in states:
        raise source.error(f"transition to a missing state: {_unknown('state', dest, states)}", f"{p}.dest", node,
                           "dest")
    autonomy, on_deny = _autonomy(node, p, source, trigger, dest)
    return TransitionSpec(
        trigger, tuple(sources), dest,
        _names(node, "conditions", source, p, guards, what="guard"),
        _names(node, "unless", source, p, guards, what="guard"),
        _names(node, "before", source, p, callbacks, what="callback"),
        _names(node, "after", source, p, callbacks, what="callback"),
        _opt_str(node, "description", source, f"{p}.description"), i, _where(node, source, p), autonomy, on_deny,
    )


def _autonomy(node: Mapping[str, Any], p: str, source: Source, trigger: str, dest: str
              ) -> tuple[Level | None, str | None]:
    """The transition's ``autonomy`` level and ``on_deny`` trigger, checked (a safety transition has none)."""
    level = node.get("autonomy")
    if level is not None:
        if level not in LEVELS:
            raise source.error(f"'autonomy' must be one of {', '.join(LEVELS)}, got {level!r}", f"{p}.autonomy",
                               node, "autonomy")
        why = safety_reason(trigger, dest)
        if why is not None:
            raise source.error(f"transition '{trigger}' to {dest} is a safety transition ({why}) and is never "
                               "gated: remove 'autonomy'", f"{p}.autonomy", node, "autonomy", on_key=True)
    on_deny = node.get("on_deny")
    if on_deny is not None:
        if level is None:
            raise source.error("'on_deny' needs an 'autonomy' level on the same transition", f"{p}.on_deny", node,
                               "on_deny", on_key=True)
        if not isinstance(on_deny, str) or not _TRIGGER.match(on_deny):
            raise source.error(f"'on_deny' must be a trigger name (lower case), got {on_deny!r}", f"{p}.on_deny",
                               node, "on_deny")
    return level, on_deny


def _check_on_deny(spec: AgentSpec) -> None:
    """A denial's trigger must lead out of every leaf the gated transition covers, never through a gate."""
    for t in spec.transitions:
        if t.on_deny is None:
            continue
        covered = [leaf for leaf in spec.leaves() if spec.covers(t, leaf)]
        for leaf in covered:
            ways = [o for o in spec.transitions if o.trigger == t.on_deny and spec.covers(o, leaf)]
            if not ways:
                raise t.where.error(f"on_deny trigger '{t.on_deny}' has no transition out of {leaf}")
            gated = [o for o in ways if o.autonomy is not None]
            if gated:
                raise t.where.error(f"on_deny trigger '{t.on_deny}' out of {leaf} carries an autonomy level "
                                    f"(transitions[{gated[0].index}]): the safe path must never wait")


def _check_outcome_triggers(spec: AgentSpec) -> None:
    for state in spec.states.values():
        for key, trigger in (("on_success", state.on_success), ("on_failure", state.on_failure)):
            if trigger is None:
                continue
            covered = [leaf for leaf in spec.leaves() if state.name in spec.ancestors(leaf)]
            missing = [leaf for leaf in covered if trigger not in spec.triggers_from(leaf)]
            if missing:
                raise state.where.error(f"{key} trigger '{trigger}' has no transition out of "
                                        f"{', '.join(missing)}")


def _check_reachable(spec: AgentSpec) -> None:
    """Every state must be reachable from the initial state (guards ignored: a static check)."""
    start = spec.leaf_of(spec.initial)
    seen = {start}
    frontier = [start]
    while frontier:
        state = frontier.pop()
        for t in spec.transitions:
            if spec.covers(t, state):
                leaf = spec.leaf_of(t.dest)
                if leaf not in seen:
                    seen.add(leaf)
                    frontier.append(leaf)
    reached = {a for leaf in seen for a in spec.ancestors(leaf)}
    for name, declared in spec.states.items():
        if name not in reached:
            raise declared.where.error(f"state '{name}' is unreachable: no transition leads to it from "
                                    f"the initial state '{spec.initial}'")
