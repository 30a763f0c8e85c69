"""Guards (``conditions``/``unless``) and callbacks (``before``/``after``/``on_enter``/``on_exit``) by name.

The agent YAML names them; the builder resolves them only through these registries (never an import
string from the file). A guard returns None when it holds and a sentence saying why not otherwise, so a
refused or redirected transition always carries a reason the dashboard can show. Guards only read;
callbacks act, through the ports.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from atemr.errors import AtemrError, ConfigError, NavigationError
from atemr.msgs import Pose2D
from atemr.registry import Registry
from atemr.trees.behaviours import behaviours
from atemr.trees.context import AgentContext
from atemr.trees.leaves.mapping import finish_mapping, map_name_problem, start_mapping
from atemr.trees.leaves.navigation import DRIVES, GO_TO_POSE
from atemr.trees.missions import Mission, goal_task
from atemr.trees.ports import HARDWARE_COMPONENTS


@dataclass
class GuardInput:
    """What a guard or callback sees: the agent context, the event's keyword arguments, and (for
    callbacks) the reasons the guards gave while this transition was chosen."""

    context: AgentContext
    kwargs: Mapping[str, Any]
    reasons: list[str] = field(default_factory=list)


Guard = Callable[[GuardInput], "str | None"]
Callback = Callable[[GuardInput], None]

guards: Registry[Guard] = Registry("guards")
callbacks: Registry[Callback] = Registry("callbacks")

log = logging.getLogger(__name__)


# -- guards ----------------------------------------------------------------------------------------
@guards.register("goal_valid")
def goal_valid(g: GuardInput) -> str | None:
    """The goal is a finite pose and navigation accepts it (localized, in the map, in free space).

    The checks that need the map are navigation's own (`NavigationPort.check_goal`), so the agent and the
    navigator can never disagree; a robot without navigation refuses every goal and says so.
    """
    goal = g.kwargs.get("goal")
    if not isinstance(goal, Pose2D):
        return f"a goal must be a Pose2D, got {type(goal).__name__}"
    if not all(math.isfinite(v) for v in (goal.x_m, goal.y_m, goal.yaw_rad)):
        return f"goal has a non-finite coordinate: x={goal.x_m}, y={goal.y_m}, yaw={goal.yaw_rad}"
    if GO_TO_POSE not in behaviours:
        return f"navigation is not available in this build (no '{GO_TO_POSE}' behaviour)"
    navigation = g.context.navigation
    if navigation is None:
        return "navigation is not available on this robot"
    return navigation.check_goal(goal)


@guards.register("auto_mode")
def auto_mode(g: GuardInput) -> str | None:
    """Goals drive the robot by themselves, so they are taken in AUTO mode only (docs/agent.md#the-lifecycle:
    a goal outside AUTO is an invalid goal, it sends the agent to Error with this reason)."""
    if g.context.mode == "AUTO":
        return None
    return f"goals are accepted in AUTO mode only (the robot is in {g.context.mode}): switch to AUTO first"


@guards.register("mission_runnable")
def mission_runnable(g: GuardInput) -> str | None:
    """The event carries a validated mission whose every step has a registered behaviour, navigation exists
    when a step drives to a pose, the active map has every place it names (refused before it starts, with the
    closest names, rather than failing half-way), and the robot is localized (AUTO can outlive the pose: a map
    switched in IDLE.AUTO, a kidnap)."""
    mission = g.kwargs.get("mission")
    if not isinstance(mission, Mission):
        return f"start_mission needs a validated Mission, got {type(mission).__name__}"
    missing = mission.missing_behaviours()
    if missing:
        return f"mission '{mission.name}' cannot run in this build: no behaviour {', '.join(missing)}"
    drives = [s.index for s in mission.steps if set(DRIVES) & set(s.behaviours)]
    if drives and g.context.navigation is None:
        return (f"mission '{mission.name}' drives to poses (steps {', '.join(map(str, drives))}) and "
                "navigation is not available on this robot")
    if mission.place_names() and g.context.navigation is not None:
        try:
            mission.check_places(g.context.navigation.places(), "the active map")
        except ConfigError as exc:
            return exc.reason
    status = g.context.port.localization_status()
    if status is not None and not status.localized:
        return f"mission '{mission.name}' refused: {status.why_not()}"
    return None


@guards.register("level1_ok")
def level1_ok(g: GuardInput) -> str | None:
    """AUTO only when the level-1 statuses are OK: heartbeat alive, every reported hardware part healthy, and
    the robot localized (AUTO drives by the map: a robot that does not know where it is must not)."""
    problems = []
    link = g.context.link
    if link is not None and not link.heartbeat_ok():
        problems.append("heartbeat lost")
    health = g.context.port.health()
    bad = sorted(n for n, h in health.items() if n in HARDWARE_COMPONENTS and not h.ok)
    if bad:
        problems.append(f"unhealthy: {', '.join(bad)}")
    status = g.context.port.localization_status()
    if status is not None and not status.localized:
        problems.append(status.why_not())
    return f"level-1 status not OK ({'; '.join(problems)})" if problems else None


@guards.register("task_failed")
def task_failed(g: GuardInput) -> str | None:
    """The error being handled is a goal or a mission that failed in AUTO (`remember_task_failed`), not a fault:
    leaving Error, the robot may take up AUTO again (a carer's routines start only from AUTO)."""
    return None if g.context.task_failed else "the error was not a failed goal or mission in AUTO"


@guards.register("map_name_valid")
def map_name_valid(g: GuardInput) -> str | None:
    """A map name that is safe as a file name (it becomes ``name.pgm`` + ``name.yaml``)."""
    return map_name_problem(g.kwargs.get("name"))


# -- callbacks -------------------------------------------------------------------------------------
@callbacks.register("begin_mapping")
def begin_mapping(g: GuardInput) -> None:
    """Start SLAM (raises if mapping is not available: the transition is then refused)."""
    start_mapping(g.context)


@callbacks.register("save_map")
def save_map(g: GuardInput) -> None:
    """Stop SLAM and save the map under the event's ``name``."""
    finish_mapping(g.context, str(g.kwargs["name"]))


@callbacks.register("discard_map")
def discard_map(g: GuardInput) -> None:
    """Stop SLAM and drop the map."""
    finish_mapping(g.context, None)


@callbacks.register("abandon_mapping")
def abandon_mapping(g: GuardInput) -> None:
    """Leaving Mapping (or Exec, whose mission may map) any other way than a save (fault, shutdown,
    power-off, a failed or cancelled mission) drops the unsaved map: SLAM never keeps running behind a state
    that does not know about it."""
    if g.context.mapping_active:
        try:
            finish_mapping(g.context, None)
            log.warning("an unsaved map was dropped on leaving %s", g.context.state)
        except AtemrError as exc:  # never block the way out of a state (a fault, a shutdown) over a map
            log.error("could not stop mapping on leaving %s: %s", g.context.state, exc)
        finally:
            g.context.mapping_active = False


@callbacks.register("stop_motors")
def stop_motors(g: GuardInput) -> None:
    """Stop the base at once, before a state's tree gets the chance."""
    g.context.port.stop_motors()


@callbacks.register("set_goal_task")
def set_goal_task(g: GuardInput) -> None:
    """Make the event's goal Exec's task (a single GoToPose step)."""
    g.context.task = goal_task(g.kwargs["goal"])


@callbacks.register("set_mission_task")
def set_mission_task(g: GuardInput) -> None:
    """Make the event's mission Exec's task."""
    g.context.task = g.kwargs["mission"]


@callbacks.register("clear_task")
def clear_task(g: GuardInput) -> None:
    """Forget Exec's task (reached, cancelled or failed)."""
    g.context.task = None


@callbacks.register("record_error")
def record_error(g: GuardInput) -> None:
    """Keep the error the Error state will classify: the event's ``error``, else one from the reasons.

    An invalid goal becomes a non-critical `NavigationError`; anything else without a typed error is a
    plain non-critical `AtemrError` carrying the event's reason.
    """
    error = g.kwargs.get("error")
    if isinstance(error, AtemrError):
        g.context.error = error
        return
    text = "; ".join(r for r in g.reasons if r) or "unspecified error"
    g.context.error = NavigationError(text) if "goal" in g.kwargs else AtemrError(text)


@callbacks.register("remember_task_failed")
def remember_task_failed(g: GuardInput) -> None:
    """A goal or a mission failed in AUTO (no path, stuck, an invalid goal): Error may hand back AUTO once it is
    handled (the ``task_failed`` guard, beside ``level1_ok``, which still refuses AUTO after a fault that came on
    meanwhile). `clear_error` forgets it."""
    g.context.task_failed = True


@callbacks.register("clear_error")
def clear_error(g: GuardInput) -> None:
    """The error is handled: forget it."""
    g.context.error = None
    g.context.task_failed = False
