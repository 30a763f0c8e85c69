"""What every leaf, guard and callback of one agent shares: the ports, the injected time, the event outbox.

Leaves receive the context once, in ``setup(context=...)`` (py_trees passes setup keyword arguments to
every node). They read time from ``context.now`` (set by the agent at the start of each tick, never from
the wall clock) and ask for state changes only by posting an `Event`; the agent fires the events on the
lifecycle machine after the trees have ticked, so a leaf never changes state in the middle of a tick.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import py_trees

from atemr.errors import AtemrError, ConfigError
from atemr.trees.ports import LinkPort, NavigationPort, RobotPort

#: Blackboard namespaces. py_trees keeps storage at class level, so every key lives under one of these
#: and `clear_blackboard` wipes them between agents and between tests.
AGENT_NS = "/agent"
MONITOR_NS = "/monitor"
NAMESPACES = (AGENT_NS, MONITOR_NS)


@dataclass(frozen=True)
class Event:
    """A request to fire ``trigger`` on the lifecycle machine, with the keyword arguments guards read."""

    trigger: str
    kwargs: dict[str, Any] = field(default_factory=dict)
    reason: str = ""
    origin: str = ""


@dataclass
class AgentContext:
    """The shared, per-agent state that is not a tree node's own.

    ``error`` is the failure the Error state classifies (an `AtemrError`, whose ``critical`` flag decides
    Idle or Shutdown); ``task`` is what Exec runs (a built mission or goal); ``state`` is the lifecycle
    state name, kept here so Monitor leaves can encode it without reaching into the machine.
    """

    port: RobotPort
    link: LinkPort | None = None
    navigation: NavigationPort | None = None
    now: float = 0.0
    state: str = ""
    mode: str = "MANUAL"
    error: AtemrError | None = None
    #: The error being handled is a goal or a mission that failed in AUTO (not a fault): once it is handled the
    #: robot may go back to AUTO, holding still, ready for the next (`recover` with ``task_failed``).
    task_failed: bool = False
    task: Any = None
    mapping_active: bool = False
    halted: bool = False
    outbox: list[Event] = field(default_factory=list)

    def post(self, trigger: str, reason: str = "", origin: str = "", **kwargs: Any) -> None:
        """Ask for ``trigger`` to be fired after this tick."""
        self.outbox.append(Event(trigger, dict(kwargs), reason, origin))

    def take_events(self) -> list[Event]:
        """The posted events, oldest first, emptying the outbox."""
        events, self.outbox = self.outbox, []
        return events


def context_from_setup(node: py_trees.behaviour.Behaviour, kwargs: dict[str, Any]) -> AgentContext:
    """The `AgentContext` passed to ``setup``; a node set up without one is a wiring error."""
    context = kwargs.get("context")
    if not isinstance(context, AgentContext):
        raise ConfigError(f"behaviour '{node.name}' needs setup(context=AgentContext(...))")
    return context


def clear_blackboard() -> None:
    """Forget every key and client under the agent's namespaces and the activity stream (py_trees keeps
    both at class level; `atemr.trees.blackboard_watch` enables the stream again when it next drains)."""
    py_trees.blackboard.Blackboard.disable_activity_stream()
    storage = py_trees.blackboard.Blackboard.storage
    for key in [k for k in storage if k.startswith(NAMESPACES)]:
        del storage[key]
    metadata = py_trees.blackboard.Blackboard.metadata
    for key in [k for k in metadata if k.startswith(NAMESPACES)]:
        del metadata[key]
