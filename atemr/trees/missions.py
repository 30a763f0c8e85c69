"""Missions: what Exec runs, written as a list of steps and compiled to a behaviour tree.

A mission file (``trees/missions/*.yaml``)::

    mission:
      name: kitchen-check
      description: drive to the kitchen, take a picture, come back
      world: studio                      # the world it was written for (informational)
      home: {x_m: 0.0, y_m: 0.0, yaw_rad: 0.0}   # or a place: home: {place: home}
      defaults: {timeout_s: 120, retries: 0}
      steps:
        - go_to: {x_m: 3.0, y_m: 1.5, yaw_rad: 1.57}
        - go_to: {place: kitchen}          # a named place of the active map
          timeout_s: 60                  # per step: a Timeout decorator on the agent clock
          retries: 1                     # per step: a Retry decorator (retries + 1 attempts)
        - capture_image: {label: kitchen}
        - wait: {duration_s: 5}
        - rotate: {angle_rad: 3.14}
        - relocalize: {timeout_s: 30}      # global relocalization, wait until localized
        - visit: {waypoints: [{x_m: 1, y_m: 0}, {x_m: 1, y_m: 1}, kitchen, {place: bedroom}]}
        - patrol: {waypoints: [...], loops: 3}   # loops: 0 = forever
        - follow_path: {points: [[1, 0], [1, 2], [3, 2]], yaw_rad: 0}   # along this route, in order
        - start_mapping: {}                # SLAM from here on (a map of what the robot sees on its way)
        - save_map: {name: flat-2026}      # stop SLAM, store the map (it becomes active)
        - stop_mapping: {}                 # stop SLAM, drop the map
        - return_home: {}

Step kinds are a fixed grammar (a typo is an error with the closest kinds); each kind names the
behaviour it compiles to (``go_to``, ``visit``, ``patrol`` and ``return_home`` → ``GoToPose``, or
``GoToPlace`` for a named place;
``follow_path`` → ``FollowPath``; ``wait`` → ``Wait``; ``capture_image`` → ``CaptureImage``; ``rotate`` →
``Rotate``; ``relocalize`` → ``Relocalize``; ``start_mapping``, ``save_map``, ``stop_mapping`` → the leaves
of those names). A mission that ends without saving the map it started drops it (Exec's exit).
A kind whose behaviour is not registered (a build without a leaf, a plugin removed) still validates, its
parameters fully checked, and is reported as *not runnable here*: the file is right, the build is not
ready for it. The agent refuses to start such a mission with that reason, and one that drives to poses on
a robot without navigation.

Places are names, not poses, in the mission: a mission file is valid on its own, and `Mission.check_places`
says whether a map has every place it names (file:line:col of the step, and the closest names). ``atemr
mission validate`` checks them against the mission's map, the agent against the active map before the
mission starts, and ``GoToPlace`` looks the pose up when its step begins.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from atemr.domain.places import Places
from atemr.errors import ConfigError
from atemr.msgs import Pose2D
from atemr.trees.behaviours import NoParams, behaviours, parse_params
from atemr.trees.builder import NodeSpec, marked_subset
from atemr.trees.leaves.mapping import SaveMapParams
from atemr.trees.leaves.media import CaptureImageParams
from atemr.trees.leaves.motion import RotateParams
from atemr.trees.leaves.navigation import GO_TO_PLACE, GO_TO_POSE, FollowPathParams, PlaceParams, RelocalizeParams
from atemr.trees.leaves.timing import WaitParams
from atemr.trees.nodes import RepeatOptions, RetryOptions, SequenceOptions, TimeoutOptions
from atemr.trees.params import PoseParams
from atemr.typed import Source
from atemr.yamlsafe import load_yaml, mark_of


@dataclass(frozen=True)
class StepDefaults:
    timeout_s: float | None = field(default=None, metadata={"min": 0.1, "max": 86_400.0})
    retries: int = field(default=0, metadata={"min": 0, "max": 100})


@dataclass(frozen=True)
class Step:
    """One step as written: its kind, the behaviours it needs, and where it is."""

    index: int
    kind: str
    name: str
    behaviours: tuple[str, ...]
    spec: NodeSpec
    line: int | None = None
    column: int | None = None
    #: The named places the step drives to, in order.
    places: tuple[str, ...] = ()


@dataclass(frozen=True)
class Mission:
    """A validated mission: its steps and the tree Exec runs (``spec``)."""

    name: str
    steps: tuple[Step, ...]
    spec: NodeSpec
    home: Pose2D | None = None
    description: str = ""
    world: str | None = None
    file: str | None = None

    #: The home pose named as a place (``home: {place: home}``), if so.
    home_place: str | None = None

    def missing_behaviours(self) -> list[str]:
        """Behaviours the steps need that this build does not register (empty: runnable)."""
        return sorted({b for s in self.steps for b in s.behaviours if b not in behaviours})

    def place_names(self) -> list[str]:
        """Every place the mission names, once each, in order."""
        return list(dict.fromkeys(name for s in self.steps for name in s.places))

    def check_places(self, places: Places, where: str = "this map") -> None:
        """`ConfigError` at the first step naming a place ``places`` (those of ``where``) lacks, with the
        closest names."""
        on = f" on {where}"
        for step in self.steps:
            for name in step.places:
                if name not in places:
                    raise ConfigError(f"mission '{self.name}' step {step.index}: no place named '{name}'{on} "
                                      f"({places.hint(name)})", file=self.file, line=step.line, column=step.column,
                                      path=f"mission.steps[{step.index}]")

    def report(self) -> dict[str, Any]:
        """A JSON-able summary for ``atemr mission validate --json``."""
        missing = set(self.missing_behaviours())
        return {
            "name": self.name, "file": self.file, "world": self.world, "description": self.description,
            "runnable": not missing, "missing_behaviours": sorted(missing), "places": self.place_names(),
            "steps": [
                {"index": s.index, "kind": s.kind, "name": s.name, "line": s.line, "behaviours": list(s.behaviours),
                 "runnable": not (set(s.behaviours) & missing)}
                for s in self.steps
            ],
        }


def _leaf(kind: str, name: str, params: Any, path: str) -> NodeSpec:
    return NodeSpec(kind, name, "leaf", params, path=path)


def _go_to(target: PoseParams | PlaceParams, name: str, path: str) -> NodeSpec:
    if isinstance(target, PlaceParams):
        return _leaf(GO_TO_PLACE, name, target, path)
    return _leaf(GO_TO_POSE, name, target, path)


#: The name of the one-step mission a single goal from the dashboard runs as (`goal_task`): not a mission the carer
#: started, so its report is said as a goal ("Goal reached.") and the state shows no mission for it.
GOAL_TASK = "goal"


def goal_task(goal: Pose2D) -> Mission:
    """A single goal from the dashboard as a one-step mission (so Exec reports it the same way)."""
    return mission_from_goals([goal], name=GOAL_TASK)


def mission_from_goals(goals: list[Pose2D], *, timeout_s: float | None = None, name: str = "goals") -> Mission:
    """Visit ``goals`` in order, one go_to step each (``atemr mission run --goal X,Y,YAW`` repeated)."""
    if not goals:
        raise ConfigError("give at least one goal", path="--goal")
    steps = []
    for i, goal in enumerate(goals):
        if not all(math.isfinite(v) for v in (goal.x_m, goal.y_m, goal.yaw_rad)):
            raise ConfigError(f"goal {i} has a non-finite coordinate: {goal}", path="--goal")
        label = f"goal {i}: ({goal.x_m:.2f}, {goal.y_m:.2f}, {goal.yaw_rad:.2f})"
        spec = _go_to(PoseParams(goal.x_m, goal.y_m, goal.yaw_rad), label, f"goals[{i}]")
        if timeout_s is not None:
            spec = NodeSpec("Timeout", f"{label} (timeout {timeout_s:g} s)", "decorator", TimeoutOptions(timeout_s),
                            (spec,), path=f"goals[{i}]")
        steps.append(Step(i, "go_to", label, (GO_TO_POSE,), spec))
    root = NodeSpec("Sequence", name, "composite", SequenceOptions(True), tuple(s.spec for s in steps), path="goals")
    return Mission(name, tuple(steps), root)


# -- parsing ---------------------------------------------------------------------------------------
_MISSION_KEYS = ("name", "description", "world", "home", "defaults", "steps")
_STEP_COMMON = ("name", "timeout_s", "retries")


Target = PoseParams | PlaceParams


def _target(item: Any, source: Source, path: str, container: Any, key: Any) -> Target:
    """A pose ``{x_m, y_m, yaw_rad}``, or a named place: ``{place: kitchen}`` (or, in a list, ``kitchen``)."""
    if isinstance(item, str):
        item = {"place": item}
    if not isinstance(item, Mapping):
        raise source.error(f"a pose is a mapping {{x_m, y_m, yaw_rad}} or a place {{place: name}}, got {item!r}",
                           path, container, key)
    if "place" in item:
        return parse_params(PlaceParams, item, source, path, container=container, key=key)
    return parse_params(PoseParams, item, source, path, container=container, key=key)


def _waypoints(raw: Any, source: Source, path: str, container: Any, key: Any) -> list[Target]:
    if not isinstance(raw, list) or not raw:
        raise source.error("'waypoints' must be a non-empty list of poses {x_m, y_m, yaw_rad} or places",
                           path, container, key)
    return [_target(item, source, f"{path}[{i}]", raw, i) for i, item in enumerate(raw)]


def _check_keys(node: Mapping[str, Any], allowed: tuple[str, ...], source: Source, path: str, what: str) -> None:
    for key in node:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), list(allowed), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise source.error(f"unknown key '{key}' in {what}{hint}; allowed: {', '.join(allowed)}",
                               f"{path}.{key}", node, key, on_key=True)


@dataclass(frozen=True)
class _StepText:
    """One step's kind value as written, with what its compiler needs to report errors."""

    raw: Any
    source: Source
    path: str
    node: Mapping[str, Any]
    name: str
    home: PoseParams | PlaceParams | None

    def error(self, message: str, container: Any = None, key: Any = None) -> ConfigError:
        return self.source.error(message, self.path, self.node if container is None else container, key)

    def mapping(self) -> Mapping[str, Any]:
        if not isinstance(self.raw, Mapping):
            raise self.error(f"expected a mapping of parameters, got {self.raw!r}", self.node,
                             self.path.rsplit(".", 1)[-1])
        return self.raw


StepCompiler = Callable[[_StepText], NodeSpec]


def _compile_go_to(at: _StepText) -> NodeSpec:
    return _go_to(_target(at.mapping(), at.source, at.path, at.node, None), at.name, at.path)


def _compile_visit(at: _StepText, *, allow_loops: bool = False) -> NodeSpec:
    raw = at.mapping()
    _check_keys(raw, ("waypoints", "loops") if allow_loops else ("waypoints",), at.source, at.path, "this step")
    points = _waypoints(raw.get("waypoints"), at.source, f"{at.path}.waypoints", raw, "waypoints")
    children = tuple(_go_to(p, f"{at.name}: " + (p.place if isinstance(p, PlaceParams) else f"waypoint {i}"),
                            f"{at.path}.waypoints[{i}]") for i, p in enumerate(points))
    return NodeSpec("Sequence", at.name, "composite", SequenceOptions(True), children, path=at.path)


def _compile_patrol(at: _StepText) -> NodeSpec:
    loop = _compile_visit(dataclasses.replace(at, name=f"{at.name}: loop"), allow_loops=True)
    loops = at.mapping().get("loops", 1)
    if not isinstance(loops, int) or isinstance(loops, bool) or not 0 <= loops <= 1_000_000:
        raise at.source.error(f"'loops' must be an integer >= 0 (0: forever), got {loops!r}", f"{at.path}.loops",
                              at.raw, "loops")
    return NodeSpec("Repeat", at.name, "decorator", RepeatOptions(loops or -1), (loop,), path=at.path)


def _simple(params_cls: type[Any], leaf: str) -> StepCompiler:
    def compile_step(at: _StepText) -> NodeSpec:
        raw = None if at.raw is None else at.mapping()
        return _leaf(leaf, at.name, parse_params(params_cls, raw, at.source, at.path, container=at.node), at.path)

    return compile_step


def _compile_home(at: _StepText) -> NodeSpec:
    if at.raw not in (None, {}):
        raise at.error("return_home takes no parameters ({})")
    if at.home is None:
        raise at.error("return_home needs the mission's 'home' pose")
    return _go_to(at.home, at.name, at.path)


#: kind → (compiler, behaviours it needs).
STEP_KINDS: dict[str, tuple[StepCompiler, tuple[str, ...]]] = {
    "go_to": (_compile_go_to, (GO_TO_POSE,)),
    "visit": (_compile_visit, (GO_TO_POSE,)),
    "patrol": (_compile_patrol, (GO_TO_POSE,)),
    "return_home": (_compile_home, (GO_TO_POSE,)),
    "wait": (_simple(WaitParams, "Wait"), ("Wait",)),
    "capture_image": (_simple(CaptureImageParams, "CaptureImage"), ("CaptureImage",)),
    "rotate": (_simple(RotateParams, "Rotate"), ("Rotate",)),
    "relocalize": (_simple(RelocalizeParams, "Relocalize"), ("Relocalize",)),
    "follow_path": (_simple(FollowPathParams, "FollowPath"), ("FollowPath",)),
    "start_mapping": (_simple(NoParams, "StartMapping"), ("StartMapping",)),
    "save_map": (_simple(SaveMapParams, "SaveMap"), ("SaveMap",)),
    "stop_mapping": (_simple(NoParams, "StopMapping"), ("StopMapping",)),
}


def load_mission(path: str | Path) -> Mission:
    """Read and validate a mission file."""
    return parse_mission(load_yaml(path), str(path))


def parse_mission(document: Any, file: str | None = None) -> Mission:
    """Validate a loaded mission document into a `Mission` (raises `ConfigError` with file:line:column)."""
    source = Source("file", file) if file else Source("argument")
    if not isinstance(document, Mapping) or set(document) != {"mission"}:
        raise source.error("a mission file has one top-level key, 'mission'", "(top)", document)
    body = document["mission"]
    if not isinstance(body, Mapping):
        raise source.error("'mission' must be a mapping", "mission", document, "mission")
    _check_keys(body, _MISSION_KEYS, source, "mission", "a mission")
    name = body.get("name")
    if not isinstance(name, str) or not name.strip():
        raise source.error("a mission needs a non-empty 'name'", "mission.name", body,
                           "name" if "name" in body else None)
    for key in ("description", "world"):
        if key in body and not isinstance(body[key], str):
            raise source.error(f"'{key}' must be a string", f"mission.{key}", body, key)
    home: PoseParams | PlaceParams | None = None
    if "home" in body:
        if not isinstance(body["home"], Mapping):
            raise source.error("'home' is a pose {x_m, y_m, yaw_rad} or a place {place: home}", "mission.home",
                               body, "home")
        home = _target(body["home"], source, "mission.home", body, "home")
    defaults = parse_params(StepDefaults, body.get("defaults"), source, "mission.defaults", container=body,
                            key="defaults") if isinstance(body.get("defaults", {}), Mapping) else None
    if defaults is None:
        raise source.error("'defaults' must be a mapping {timeout_s, retries}", "mission.defaults", body, "defaults")
    raw_steps = body.get("steps")
    if not isinstance(raw_steps, list) or not raw_steps:
        raise source.error("'steps' must be a non-empty list", "mission.steps", body,
                           "steps" if "steps" in body else None)
    steps = tuple(_parse_step(s, i, source, raw_steps, home=home, defaults=defaults) for i, s in enumerate(raw_steps))
    root = NodeSpec("Sequence", name, "composite", SequenceOptions(True), tuple(s.spec for s in steps),
                    path="mission.steps", file=file)
    return Mission(name, steps, root, home.pose() if isinstance(home, PoseParams) else None,
                   str(body.get("description", "")), body.get("world"), file,
                   home.place if isinstance(home, PlaceParams) else None)


def _parse_step(node: Any, i: int, source: Source, raw: list[Any], *, home: PoseParams | PlaceParams | None,
                defaults: StepDefaults) -> Step:
    path = f"mission.steps[{i}]"
    if not isinstance(node, Mapping):
        raise source.error(f"a step is a mapping with one kind ({', '.join(STEP_KINDS)}), got {node!r}", path, raw, i)
    kinds = [k for k in node if k not in _STEP_COMMON]
    if len(kinds) != 1 or kinds[0] not in STEP_KINDS:
        unknown = [k for k in kinds if k not in STEP_KINDS]
        if unknown:
            close = difflib.get_close_matches(str(unknown[0]), list(STEP_KINDS), n=2, cutoff=0.5)
            hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
            raise source.error(f"unknown step kind '{unknown[0]}'{hint}; kinds: {', '.join(STEP_KINDS)}",
                               f"{path}.{unknown[0]}", node, unknown[0], on_key=True)
        raise source.error(f"a step has exactly one kind ({', '.join(STEP_KINDS)}), found "
                           f"{', '.join(kinds) or 'none'}", path, raw, i)
    kind = kinds[0]
    label = node.get("name", f"step {i}: {kind}")
    if not isinstance(label, str) or not label:
        raise source.error("'name' must be a non-empty string", f"{path}.name", node, "name")
    common = parse_params(StepDefaults, marked_subset(node, ("timeout_s", "retries")), source, path, container=node)
    timeout_s = common.timeout_s if "timeout_s" in node else defaults.timeout_s
    retries = common.retries if "retries" in node else defaults.retries
    compiler, needs = STEP_KINDS[kind]
    spec = compiler(_StepText(node[kind], source, f"{path}.{kind}", node, label, home))
    places = tuple(n.options.place for n in spec.walk() if n.type == GO_TO_PLACE)
    if places:  # the same kinds drive to places with GoToPlace instead of (or beside) GoToPose
        needs = tuple(dict.fromkeys(n.type for n in spec.walk() if n.type in (GO_TO_POSE, GO_TO_PLACE)))
    if timeout_s is not None:
        spec = NodeSpec("Timeout", f"{label} (timeout {timeout_s:g} s)", "decorator", TimeoutOptions(timeout_s),
                        (spec,), path=path)
    if retries:
        spec = NodeSpec("Retry", f"{label} (retries {retries})", "decorator", RetryOptions(retries + 1), (spec,),
                        path=path)
    line, column = mark_of(raw, i)
    return Step(i, kind, label, needs, dataclasses.replace(spec, file=source.name, line=line, column=column),
                line, column, places)

