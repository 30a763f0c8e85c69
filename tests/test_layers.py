"""The import rules between the layers of `atemr` and `secondary_core`, checked on the source.

Why: the code is organised in layers so that a newcomer can read a part without the parts above it, and
so that each part can be tested without them: the skills without a simulator, the agent without a robot,
the CAN codec without an agent. Nothing but a test keeps an import from going the wrong way (Python and
mypy accept any import, and one in a function body hides until it runs), so this one reads every module's
imports with `ast`, those inside functions and under ``if TYPE_CHECKING`` included, and fails on:

* an import from a higher layer of `LAYERS` (a module imports only its own layer and the layers below);
* a module that belongs to no layer (a new package must be placed in the table first);
* an import cycle between the parts the table names (at module level or inside functions alike).

`LAYERS` is the one table of the rules, bottom first. Among what it implies: skills import nothing from
io, ui, fsm, trees or robot; io imports none of ui, fsm, trees or robot; trees does not import fsm; no
module of `atemr` imports `secondary_core`. ``docs/architecture.md`` describes the same layers; change both
together.
"""

from __future__ import annotations

import ast
import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("atemr", "secondary_core")


@dataclass(frozen=True)
class Layer:
    """One layer: its modules (a name stands for the module and everything under it) and why it is here."""

    name: str
    modules: tuple[str, ...]
    why: str


#: The layers, bottom first. A module belongs to the layer of the longest name that covers it.
LAYERS: tuple[Layer, ...] = (
    Layer("base", ("atemr", "atemr.errors", "atemr.yamlsafe", "atemr.typed", "atemr.registry", "atemr.clock",
                   "atemr.scheduler", "atemr.msgs", "atemr.logsetup"),
          "the error tree, safe YAML, typed config layers, the plugin registry, the clock, the scheduler and the "
          "messages (Pose2D, Twist, LaserScan): every layer uses them, so they use none"),
    Layer("domain", ("atemr.domain",),
          "pure types shared across layer boundaries (the occupancy grid, the status codes, a component's "
          "health): any layer may take them, so they import only the base"),
    Layer("skills", ("atemr.skills",),
          "the algorithms, data in and data out (localization, navigation, SLAM, fuzzy engines, the motion "
          "pipeline): they run in tests and benchmarks without a simulator, a bus or a robot"),
    Layer("config", ("atemr.config", "atemr.io.devices.config", "atemr.ui.permissions"),
          "the configuration gathers each section's type: the skills' own (atemr.skills.*.config) and its own; "
          "two modules it types sections with live beside the code that uses them (the devices: section beside "
          "the drivers, the dashboard's permissions beside the pages) but belong here, and import nothing above"),
    Layer("io", ("atemr.io",),
          "the world outside the process: CAN codec and buses, motor driver, secondary link, devices, maps on "
          "disk, the simulator and the device emulators (the ESP32 board too); they report through domain "
          "values and are wired by the robot, never call up to the agent or the dashboard"),
    Layer("trees", ("atemr.trees",),
          "the agent's lower half: leaves, the ports they call (the robot implements them), missions; it may "
          "name the CAN status message it publishes, never the machine built on it"),
    Layer("fsm", ("atemr.fsm",),
          "the agent's lifecycle machine, built on the trees from the agent document, and its drawings"),
    Layer("ui", ("atemr.ui",),
          "the dashboard: it reaches the robot through its gateway protocol (atemr.ui.gateway), which the robot "
          "implements"),
    Layer("robot", ("atemr.robot",),
          "the one place where the parts are wired (build_robot), with the ports' adapters and the gateway"),
    Layer("entry points", ("atemr.cli", "atemr.__main__", "atemr.worlds"),
          "the commands and tools that start what is below them; nothing imports them"),
    Layer("secondary_core", ("secondary_core",),
          "the ESP32's own program (atemr-secondary) and the link test bench, built on atemr; atemr never "
          "imports it (the board the simulator runs is atemr.io.secondary_emulator)"),
)


@dataclass(frozen=True)
class Import:
    """One import statement's target, and where it is."""

    module: str
    file: str
    line: int
    target: str

    def where(self) -> str:
        return f"{self.file}:{self.line}"


def imports_of(path: Path, root: Path = ROOT) -> Iterator[tuple[int, str]]:
    """(line, imported module) for every import in ``path``, anywhere in it, relative ones resolved."""
    name = ".".join(path.relative_to(root).with_suffix("").parts)
    package = name.rsplit(".", 1)[0] if path.name != "__init__.py" else name.removesuffix(".__init__")
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                yield node.lineno, ".".join([*base, node.module] if node.module else base)
            elif node.module is not None:
                yield node.lineno, node.module


def project_imports(root: Path = ROOT, packages: tuple[str, ...] = PACKAGES) -> list[Import]:
    """Every import of a project module by a project module."""
    found = []
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            module = ".".join(path.relative_to(root).with_suffix("").parts).removesuffix(".__init__")
            file = path.relative_to(root).as_posix()
            found += [Import(module, file, line, target) for line, target in imports_of(path, root)
                      if target.split(".")[0] in packages]
    return found


def covering(module: str, layers: tuple[Layer, ...] = LAYERS) -> tuple[int, str] | None:
    """(rank of the layer, the table's name) that covers ``module``: the longest; None when none does."""
    best: tuple[int, str] | None = None
    for rank, layer in enumerate(layers):
        for name in layer.modules:
            if (module == name or module.startswith(name + ".")) and (best is None or len(name) > len(best[1])):
                best = (rank, name)
    return best


def layer_violations(found: list[Import], layers: tuple[Layer, ...] = LAYERS) -> list[str]:
    """One sentence per import that reaches up the table: which module imports what, and the rule it breaks."""
    problems = []
    for imp in found:
        source, target = covering(imp.module, layers), covering(imp.target, layers)
        if source is None or target is None or target[0] <= source[0]:
            continue
        low, high = layers[source[0]], layers[target[0]]
        below = ", ".join(layer.name for layer in layers[: source[0]]) or "nothing"
        problems.append(
            f"{imp.where()}: {imp.module} imports {imp.target}: layer '{low.name}' may import only itself and "
            f"the layers below it ({below}), and '{high.name}' is above it. Why '{low.name}' is there: {low.why}")
    return problems


def cycles(found: list[Import], layers: tuple[Layer, ...] = LAYERS) -> list[str]:
    """Each import cycle between the table's parts: for every pair of parts in it that import each other in
    one direction, the first such import found."""
    edges: dict[str, dict[str, Import]] = {}
    for imp in found:
        source, target = covering(imp.module, layers), covering(imp.target, layers)
        if source is not None and target is not None and source[1] != target[1]:
            edges.setdefault(source[1], {}).setdefault(target[1], imp)
    # Tarjan's strongly connected components: a component of more than one part is a cycle
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    components: list[list[str]] = []

    def visit(part: str) -> None:
        index[part] = low[part] = len(index)
        stack.append(part)
        for nxt in edges.get(part, {}):
            if nxt not in index:
                visit(nxt)
                low[part] = min(low[part], low[nxt])
            elif nxt in stack:
                low[part] = min(low[part], index[nxt])
        if low[part] == index[part]:
            component = []
            while True:
                top = stack.pop()
                component.append(top)
                if top == part:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for part in sorted(edges):
        if part not in index:
            visit(part)
    return [" ; ".join(f"{a} -> {b} ({edges[a][b].where()} imports {edges[a][b].target})"
                       for a, b in itertools.permutations(component, 2) if b in edges.get(a, {}))
            for component in components]


FOUND = project_imports()


def test_every_part_has_a_layer() -> None:
    """A new top-level package or module must be placed in `LAYERS` before it can be checked."""
    parts = {child.stem if child.suffix == ".py" else child.name
             for child in (ROOT / "atemr").iterdir()
             if (child.suffix == ".py" or (child / "__init__.py").exists())}
    named = {name for layer in LAYERS for name in layer.modules}
    missing = sorted(f"atemr.{part}" for part in parts - {"__init__"} if f"atemr.{part}" not in named)
    assert not missing, f"put these in a layer of LAYERS in {Path(__file__).name}: {', '.join(missing)}"
    unplaced = sorted({imp.module for imp in FOUND if covering(imp.module) is None})
    assert not unplaced, f"modules in no layer: {', '.join(unplaced)}"


def test_no_import_reaches_up_the_layers() -> None:
    assert len(FOUND) > 500, "the scan found too few imports to be reading the package"
    problems = layer_violations(FOUND)
    assert not problems, "imports against the layers (tests/test_layers.py):\n" + "\n".join(problems)


def test_no_import_cycle_between_parts() -> None:
    found = cycles(FOUND)
    assert not found, "import cycles between parts of the layer table:\n" + "\n".join(found)


@pytest.mark.parametrize(("source", "line", "rule"), [
    ("def f():\n    from atemr.io.sim import maps\n", 2, "layer 'skills' may import only"),
    ("from ..trees import context\n", 1, "layer 'skills' may import only"),
    ("import secondary_core.cli\n", 1, "layer 'skills' may import only"),
])
def test_the_check_sees_imports_in_functions_and_relative_ones(tmp_path: Path, source: str, line: int,
                                                                rule: str) -> None:
    """The checker itself: a forbidden import in a function body, a relative one, and a plain one all fail."""
    for package in ("atemr/skills", "atemr/io/sim", "atemr/trees", "secondary_core"):
        (tmp_path / package).mkdir(parents=True, exist_ok=True)
        (tmp_path / package / "__init__.py").write_text("")
    (tmp_path / "atemr/skills/bad.py").write_text(source)
    (problem,) = layer_violations(project_imports(tmp_path))
    assert problem.startswith(f"atemr/skills/bad.py:{line}: atemr.skills.bad imports ") and rule in problem


def test_the_check_sees_a_cycle(tmp_path: Path) -> None:
    """Two parts of one layer importing each other (inside a function, even) are a cycle."""
    for package in ("atemr/cli", "atemr/worlds"):
        (tmp_path / package).mkdir(parents=True)
        (tmp_path / package / "__init__.py").write_text("")
    (tmp_path / "atemr/cli/a.py").write_text("from atemr.worlds import b\n")
    (tmp_path / "atemr/worlds/b.py").write_text("def f():\n    import atemr.cli.a\n")
    (found,) = cycles(project_imports(tmp_path))
    assert "atemr.cli -> atemr.worlds" in found and "atemr.worlds -> atemr.cli" in found
