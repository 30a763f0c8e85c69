"""Drawing the agent: the lifecycle machine and each state's tree as ASCII, Mermaid, JSON, DOT, SVG or PNG.

Everything is drawn from the validated specs (`AgentSpec`, `NodeSpec`), not from built py_trees objects,
so a document naming behaviours this build lacks (a plugin's leaf) still draws. ASCII, Mermaid,
JSON and DOT are plain text and always work; SVG and PNG run Graphviz's ``dot`` program and fail with a
clear message when it is not installed. One registry names the formats (``atemr.exporters`` entry points
add more).
"""

from __future__ import annotations

import dataclasses
import json
import re
import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from atemr.domain.status import state_code
from atemr.errors import AtemrError
from atemr.fsm.spec import AgentSpec, TransitionSpec
from atemr.registry import Registry
from atemr.trees.builder import NodeSpec


@dataclass(frozen=True)
class Drawing:
    """What to draw: a whole agent document, or one tree (a state's, the Monitor, a mission)."""

    title: str
    agent: AgentSpec | None = None
    trees: tuple[tuple[str, NodeSpec], ...] = ()


Exporter = Callable[[Drawing], "str | bytes"]
exporters: Registry[Exporter] = Registry("exporters")


class ExportError(AtemrError):
    """A drawing cannot be produced (an optional tool is missing, a state has no tree)."""


def drawing_of(agent: AgentSpec, state: str | None = None) -> Drawing:
    """The whole document, or with ``state`` only that state's tree (``monitor`` names the Monitor)."""
    if state is None:
        trees = [(name, s.tree) for name, s in agent.states.items() if s.tree is not None]
        if agent.monitor is not None:
            trees.append(("monitor", agent.monitor))
        return Drawing(agent.file or "agent", agent, tuple(trees))
    if state == "monitor":
        if agent.monitor is None:
            raise ExportError("this document has no monitor tree")
        return Drawing("monitor", None, (("monitor", agent.monitor),))
    if state not in agent.states:
        raise ExportError(f"no state '{state}'; states: {', '.join(agent.states)}, monitor")
    spec = agent.tree_state(state)
    if spec is None or spec.tree is None:
        raise ExportError(f"state {state} has no tree")
    return Drawing(state, None, ((spec.name, spec.tree),))


# -- shared helpers --------------------------------------------------------------------------------
def options_text(node: NodeSpec) -> str:
    """``k=v`` for a node's options or parameters."""
    if node.options is None or not dataclasses.is_dataclass(node.options):
        return ""
    parts = []
    for f in dataclasses.fields(node.options):
        value = getattr(node.options, f.name)
        parts.append(f"{f.name}={','.join(map(str, value)) if isinstance(value, tuple) else value}")
    return " ".join(parts)


def guard_text(t: TransitionSpec) -> str:
    """The guards and, when it has one, the autonomy level the robot needs to take it on its own."""
    guards = [*t.conditions, *(f"not {g}" for g in t.unless)]
    if t.autonomy is not None:
        guards.append(f"autonomy {t.autonomy}")
    return f" [{', '.join(guards)}]" if guards else ""


def node_dict(node: NodeSpec) -> dict[str, Any]:
    out: dict[str, Any] = {"name": node.name, "type": node.type, "kind": node.kind}
    if node.options is not None and dataclasses.is_dataclass(node.options):
        out["options"] = {f.name: getattr(node.options, f.name) for f in dataclasses.fields(node.options)}
        out["options"] = {k: list(v) if isinstance(v, tuple) else v for k, v in out["options"].items()}
    if node.line is not None:
        out["line"] = node.line
    if node.children:
        out["children"] = [node_dict(c) for c in node.children]
    return out


_SYMBOL = {"Sequence": "[-]", "Selector": "[o]", "Parallel": "/_/", "Task": "[task]"}


def _symbol(node: NodeSpec) -> str:
    if node.kind == "decorator":
        return "-^-"
    return _SYMBOL.get(node.type, "-->")


# -- formats ---------------------------------------------------------------------------------------
@exporters.register("ascii")
def to_ascii(d: Drawing) -> str:
    """Indented text: the states, the transitions, then each tree with py_trees' symbols."""
    lines: list[str] = []
    agent = d.agent
    if agent is not None:
        lines.append(f"machine {d.title} (initial {agent.initial})")
        for name, s in agent.states.items():
            depth = name.count(".")
            extra = [f"code 0x{int(state_code(name)):02X}"] if depth == 0 else []
            if s.initial:
                extra.append(f"initial {s.initial.rsplit('.', 1)[-1]}")
            if s.tree is not None:
                extra.append(f"tree '{s.tree.name}'")
            for key in ("on_success", "on_failure"):
                if getattr(s, key):
                    extra.append(f"{key} -> {getattr(s, key)}")
            extra.extend(f"{key} {', '.join(getattr(s, key))}" for key in ("on_enter", "on_exit") if getattr(s, key))
            lines.append(f"{'  ' * (depth + 1)}{name.rsplit('.', 1)[-1]}  ({'; '.join(extra)})")
        lines.append("transitions")
        for t in agent.transitions:
            callbacks = [*(f"before {c}" for c in t.before), *(f"after {c}" for c in t.after)]
            tail = f"  ({', '.join(callbacks)})" if callbacks else ""
            lines.append(f"  {' | '.join(t.sources)} --{t.trigger}{guard_text(t)}--> {t.dest}{tail}")
    for owner, tree in d.trees:
        lines.append(f"tree {owner}")

        def walk(node: NodeSpec, depth: int) -> None:
            opts = options_text(node)
            kind = f"{node.type} {opts}".rstrip()
            label = node.name if node.name == node.type and not opts else f"{node.name} ({kind})"
            lines.append(f"{'    ' * depth}  {_symbol(node)} {label}")
            for child in node.children:
                walk(child, depth + 1)

        walk(tree, 0)
    return "\n".join(lines) + "\n"


@exporters.register("json")
def to_json(d: Drawing) -> str:
    """The machine and trees as JSON (for the dashboard and other tools)."""
    out: dict[str, Any] = {"title": d.title}
    if d.agent is not None:
        a = d.agent
        out["machine"] = {
            "initial": a.initial,
            "states": [{"name": n, "code": int(state_code(n)), "children": list(s.children), "initial": s.initial,
                        "tree": s.tree.name if s.tree else None, "on_success": s.on_success,
                        "on_failure": s.on_failure, "description": s.description} for n, s in a.states.items()],
            "transitions": [{"trigger": t.trigger, "source": list(t.sources), "dest": t.dest,
                             "conditions": list(t.conditions), "unless": list(t.unless), "before": list(t.before),
                             "after": list(t.after), "description": t.description, "autonomy": t.autonomy,
                             "on_deny": t.on_deny} for t in a.transitions],
        }
    out["trees"] = {owner: node_dict(tree) for owner, tree in d.trees}
    return json.dumps(out, indent=2) + "\n"


def _mid(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]", "_", text)


def _mermaid_label(text: str) -> str:
    return text.replace('"', "'")


def mermaid_machine(agent: AgentSpec) -> str:
    """The lifecycle as a Mermaid ``stateDiagram-v2`` (nested states as composite states)."""
    lines = ["stateDiagram-v2", f"    [*] --> {_mid(agent.leaf_of(agent.initial))}"]

    def declare(name: str, depth: int) -> None:
        s = agent.states[name]
        pad = "    " * depth
        if s.children:
            lines.append(f"{pad}state {_mid(name)} {{")
            assert s.initial is not None
            lines.append(f"{pad}    [*] --> {_mid(s.initial)}")
            for child in s.children:
                declare(child, depth + 1)
            lines.append(f"{pad}}}")
        else:
            lines.append(f'{pad}state "{name}" as {_mid(name)}')

    for root in agent.roots:
        declare(root, 1)
    for t in agent.transitions:
        sources = agent.roots if t.sources == ("*",) else t.sources
        for source in sources:
            lines.append(f"    {_mid(source)} --> {_mid(t.dest)} : {_mermaid_label(t.trigger + guard_text(t))}")
    return "\n".join(lines) + "\n"


def mermaid_tree(owner: str, tree: NodeSpec) -> str:
    """One tree as a Mermaid ``flowchart TD``."""
    lines = ["flowchart TD"]
    counter = iter(range(1_000_000))

    def walk(node: NodeSpec) -> str:
        nid = f"n{next(counter)}"
        opts = options_text(node)
        label = _mermaid_label(f"{_symbol(node)} {node.name}" + (f"<br/>{node.type} {opts}".rstrip()
                                                                 if node.name != node.type or opts else ""))
        shape = f'{nid}(["{label}"])' if node.kind == "leaf" else f'{nid}["{label}"]'
        lines.append(f"    {shape}")
        for child in node.children:
            lines.append(f"    {nid} --> {walk(child)}")
        return nid

    lines.insert(1, f"    %% tree of {owner}")
    walk(tree)
    return "\n".join(lines) + "\n"


@exporters.register("mermaid")
def to_mermaid(d: Drawing) -> str:
    """One diagram as raw Mermaid; several (machine + trees) as Markdown with fenced Mermaid blocks."""
    blocks = []
    if d.agent is not None:
        blocks.append(("lifecycle", mermaid_machine(d.agent)))
    blocks.extend((f"tree of {owner}", mermaid_tree(owner, tree)) for owner, tree in d.trees)
    if len(blocks) == 1:
        return blocks[0][1]
    return "\n".join(f"## {title}\n\n```mermaid\n{body}```\n" for title, body in blocks)


def _dot_label(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"')


def to_dot(d: Drawing) -> str:
    """Graphviz DOT: the machine (nested states as clusters) and each tree as its own cluster."""
    lines = [f'digraph "{_dot_label(d.title)}" {{', "  compound=true; rankdir=TB;",
             '  node [fontname="Helvetica", fontsize=10]; edge [fontname="Helvetica", fontsize=9];']
    if d.agent is not None:
        agent = d.agent
        lines.append('  subgraph cluster_machine { label="lifecycle";')

        def declare(name: str) -> None:
            s = agent.states[name]
            if s.children:
                lines.append(f'    subgraph cluster_{_mid(name)} {{ label="{name}";')
                for child in s.children:
                    declare(child)
                lines.append("    }")
            else:
                lines.append(f'    s_{_mid(name)} [label="{name}", shape=box, style=rounded];')

        for root in agent.roots:
            declare(root)
        lines.append('    start [shape=point];')
        lines.append(f"    start -> s_{_mid(agent.leaf_of(agent.initial))};")
        for t in agent.transitions:
            for source in agent.roots if t.sources == ("*",) else t.sources:
                src, dst = agent.leaf_of(source), agent.leaf_of(t.dest)
                attrs = [f'label="{_dot_label(t.trigger + guard_text(t))}"']
                if src != source:
                    attrs.append(f"ltail=cluster_{_mid(source)}")
                if dst != t.dest:
                    attrs.append(f"lhead=cluster_{_mid(t.dest)}")
                lines.append(f"    s_{_mid(src)} -> s_{_mid(dst)} [{', '.join(attrs)}];")
        lines.append("  }")
    for i, (owner, tree) in enumerate(d.trees):
        lines.append(f'  subgraph cluster_tree{i} {{ label="tree of {_dot_label(owner)}";')
        counter = iter(range(1_000_000))

        def walk(node: NodeSpec, prefix: str, counter: Any = counter) -> str:
            nid = f"{prefix}_{next(counter)}"
            shape = {"composite": "box", "decorator": "diamond", "task": "octagon"}.get(node.kind, "ellipse")
            opts = options_text(node)
            label = f"{_symbol(node)} {node.name}" + (f"\\n{node.type} {opts}".rstrip()
                                                      if node.name != node.type or opts else "")
            lines.append(f'    {nid} [label="{_dot_label(label).replace(chr(92) * 2 + "n", chr(92) + "n")}", '
                         f"shape={shape}];")
            for child in node.children:
                lines.append(f"    {nid} -> {walk(child, prefix, counter)};")
            return nid

        walk(tree, f"t{i}")
        lines.append("  }")
    lines.append("}")
    return "\n".join(lines) + "\n"


exporters.add("dot", to_dot)


def render_with_graphviz(dot_text: str, fmt: str) -> bytes:
    """Run Graphviz ``dot -T<fmt>``; a missing ``dot`` is an `ExportError` saying what still works."""
    program = shutil.which("dot")
    if program is None:
        raise ExportError(f"--format {fmt} needs Graphviz's 'dot' program, which is not installed "
                          "(apt install graphviz); ascii, mermaid, json and dot work without it")
    try:
        result = subprocess.run([program, f"-T{fmt}"], input=dot_text.encode(), capture_output=True, timeout=60,
                                check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise ExportError(f"graphviz 'dot' failed to run: {exc}") from None
    if result.returncode != 0:
        raise ExportError(f"graphviz 'dot' failed: {result.stderr.decode(errors='replace').strip()}")
    return result.stdout


@exporters.register("svg")
def to_svg(d: Drawing) -> bytes:
    return render_with_graphviz(to_dot(d), "svg")


@exporters.register("png")
def to_png(d: Drawing) -> bytes:
    return render_with_graphviz(to_dot(d), "png")
