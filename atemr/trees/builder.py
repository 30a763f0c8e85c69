"""YAML tree documents → validated `NodeSpec` trees → py_trees behaviours, in two separate steps.

`parse_node` walks the whole document first and raises `ConfigError` at the first problem, with
file:line:column and the YAML path (``states[1].tree.children[2].params.duration_s``): unknown keys,
wrong types, an unknown node type (with the closest known names), bad parameters. `build` only ever
sees a fully valid spec, so nothing is half built from a bad file.

A node is a mapping::

    type: Sequence          # a composite, a decorator, a registered leaf, or Task
    name: check hardware    # optional, defaults to the type
    memory: true            # composite/decorator options sit beside type
    children: [...]         # composites;  decorators take one `child:`
    params: {...}           # leaves only: the leaf's Params fields
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import py_trees

from atemr.errors import ConfigError
from atemr.trees import leaves as _builtin_leaves  # registers the built-in leaves before any lookup
from atemr.trees.behaviours import behaviours, parse_params
from atemr.trees.context import AgentContext
from atemr.trees.nodes import COMPOSITES, DECORATORS, TASK
from atemr.typed import Source
from atemr.yamlsafe import MarkedDict, mark_of

_ = _builtin_leaves
NodeKind = Literal["composite", "decorator", "leaf", "task"]
_COMMON_KEYS = ("type", "name", "description")


@dataclass(frozen=True)
class NodeSpec:
    """One validated node: what to build and where it was written (for later messages)."""

    type: str
    name: str
    kind: NodeKind
    options: Any
    children: tuple[NodeSpec, ...] = ()
    path: str = ""
    file: str | None = None
    line: int | None = None
    column: int | None = None
    description: str = ""

    def walk(self) -> list[NodeSpec]:
        """This node and every descendant, depth first."""
        out = [self]
        for child in self.children:
            out.extend(child.walk())
        return out


def node_types() -> list[str]:
    """Every name a node's ``type`` may take."""
    return sorted({*COMPOSITES, *DECORATORS, *behaviours, TASK})


def _error(source: Source, message: str, path: str, container: Any, key: Any = None, *, on_key: bool = False
           ) -> ConfigError:
    return source.error(message, path, container, key, on_key=on_key)


def marked_subset(node: Mapping[str, Any], keys: Sequence[str]) -> Mapping[str, Any]:
    """``{k: node[k] for k in keys}`` that keeps the YAML marks of a `MarkedDict`, for error positions."""
    present = [k for k in keys if k in node]
    if not isinstance(node, MarkedDict):
        return {k: node[k] for k in present}
    subset = MarkedDict((k, node[k]) for k in present)
    subset.file, subset.line, subset.column = node.file, node.line, node.column
    subset.key_marks = {k: node.key_marks[k] for k in present}
    subset.value_marks = {k: node.value_marks[k] for k in present}
    return subset


def _split_options(node: Mapping[str, Any], extra: Sequence[str], options_cls: type[Any]) -> Mapping[str, Any]:
    """The option keys of a composite/decorator node."""
    names = {f.name for f in dataclasses.fields(options_cls)}
    return marked_subset(node, [k for k in node if k in names and k not in extra])


def parse_node(node: Any, source: Source, path: str, *, parent: Any = None, key: Any = None,  # noqa: PLR0912  one branch per node family after the common keys
               allow_task: bool = True) -> NodeSpec:
    """Validate one node document (and its whole subtree) into a `NodeSpec`."""
    if not isinstance(node, Mapping):
        raise _error(source, f"expected a node mapping with a 'type', got {type(node).__name__}", path, parent, key)
    if "type" not in node:
        raise _error(source, "a node needs a 'type' (a composite, a decorator or a behaviour)", path, node)
    node_type = node["type"]
    if not isinstance(node_type, str):
        raise _error(source, f"'type' must be a string, got {node_type!r}", f"{path}.type", node, "type")
    name = node.get("name", node_type)
    if not isinstance(name, str) or not name:
        raise _error(source, f"'name' must be a non-empty string, got {name!r}", f"{path}.name", node, "name")
    description = node.get("description", "")
    if not isinstance(description, str):
        raise _error(source, "'description' must be a string", f"{path}.description", node, "description")
    line, column = mark_of(node)
    where: dict[str, Any] = {"path": path, "file": source.name, "line": line, "column": column,
                             "description": description}

    if node_type in COMPOSITES:
        options_cls, _ = COMPOSITES[node_type]
        _check_keys(node, source, path, (*_COMMON_KEYS, "children", *(f.name for f in dataclasses.fields(options_cls))))
        children = node.get("children")
        if not isinstance(children, list) or not children:
            raise _error(source, f"{node_type} needs 'children': a non-empty list of nodes", f"{path}.children",
                         node, "children" if "children" in node else None)
        options = parse_params(options_cls, _split_options(node, ("children",), options_cls), source, path,
                               container=node)
        kids = tuple(
            parse_node(child, source, f"{path}.children[{i}]", parent=children, key=i, allow_task=allow_task)
            for i, child in enumerate(children)
        )
        return NodeSpec(node_type, name, "composite", options, kids, **where)
    if node_type in DECORATORS:
        options_cls, _ = DECORATORS[node_type]
        _check_keys(node, source, path, (*_COMMON_KEYS, "child", *(f.name for f in dataclasses.fields(options_cls))))
        if "child" not in node:
            raise _error(source, f"{node_type} needs exactly one 'child' node", path, node)
        options = parse_params(options_cls, _split_options(node, ("child",), options_cls), source, path,
                               container=node)
        child = parse_node(node["child"], source, f"{path}.child", parent=node, key="child", allow_task=allow_task)
        return NodeSpec(node_type, name, "decorator", options, (child,), **where)
    if node_type == TASK:
        if not allow_task:
            raise _error(source, "'Task' may only appear in a state's tree (it stands for Exec's task)",
                         f"{path}.type", node, "type")
        _check_keys(node, source, path, _COMMON_KEYS)
        return NodeSpec(TASK, name, "task", None, **where)
    if node_type in behaviours:
        leaf_cls = behaviours.get(node_type)
        _check_keys(node, source, path, (*_COMMON_KEYS, "params"))
        raw = node.get("params")
        if raw is not None and not isinstance(raw, Mapping):
            raise _error(source, f"'params' must be a mapping, got {type(raw).__name__}", f"{path}.params",
                         node, "params")
        params = parse_params(leaf_cls.Params, raw, source, f"{path}.params", container=node, key="params")
        return NodeSpec(node_type, name, "leaf", params, **where)
    close = difflib.get_close_matches(node_type, node_types(), n=3, cutoff=0.5)
    hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
    raise _error(source, f"unknown node type '{node_type}'{hint}; known: {', '.join(node_types())}",
                 f"{path}.type", node, "type")


def _check_keys(node: Mapping[str, Any], source: Source, path: str, allowed: Sequence[str]) -> None:
    for key in node:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), list(allowed), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise _error(source, f"unknown key '{key}' for a {node['type']} node{hint}; allowed: "
                         f"{', '.join(allowed)}", f"{path}.{key}", node, key, on_key=True)


def build(spec: NodeSpec, *, task: NodeSpec | None = None,
          built_tasks: list[py_trees.behaviour.Behaviour] | None = None) -> py_trees.behaviour.Behaviour:
    """Build py_trees behaviours from a validated spec; ``Task`` nodes become ``task`` (or a failing leaf).

    Each built task root is appended to ``built_tasks`` so the caller can follow its progress.
    """
    if spec.kind == "composite":
        _, composite = COMPOSITES[spec.type]
        return composite(spec.name, spec.options,
                         [build(c, task=task, built_tasks=built_tasks) for c in spec.children])
    if spec.kind == "decorator":
        _, decorator = DECORATORS[spec.type]
        return decorator(spec.name, spec.options, build(spec.children[0], task=task, built_tasks=built_tasks))
    if spec.kind == "task":
        if task is None:
            return NoTask(spec.name)
        root = build(task)
        if built_tasks is not None:
            built_tasks.append(root)
        return root
    return behaviours.get(spec.type)(spec.name, spec.options)


class NoTask(py_trees.behaviour.Behaviour):
    """Where Exec's tree says ``Task`` but no task was given: fails at once with the reason."""

    reason = "no task (mission or goal) was given to execute"

    def update(self) -> py_trees.common.Status:
        self.feedback_message = self.reason
        return py_trees.common.Status.FAILURE


def setup_tree(root: py_trees.behaviour.Behaviour, context: AgentContext) -> None:
    """Call ``setup(context=...)`` on every node once (py_trees' own crawler, no timeout thread)."""
    py_trees.trees.setup(root, context=context)


def parse_tree_document(document: Any, source: Source) -> NodeSpec:
    """A standalone tree file: a single node mapping at the top level (``tree:`` key optional)."""
    if isinstance(document, MarkedDict) and set(document) == {"tree"}:
        return parse_node(document["tree"], source, "tree", parent=document, key="tree")
    return parse_node(document, source, "(top)")

