"""`load_engine`: one entry point for YAML and fuzzylite `.fll` engines, and the robot's shipped engines."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from atemr.errors import ConfigError
from atemr.skills.fuzzy.engine import Engine
from atemr.skills.fuzzy.fll import engine_from_fll
from atemr.skills.fuzzy.yaml_format import engine_from_yaml

#: Engines shipped in ``atemr/skills/fuzzy/engines/`` (package data).
BUILTIN_ENGINES = ("idle", "manual")


def load_engine(path: str | Path) -> Engine:
    """Load an engine from a ``.yaml``/``.yml`` or ``.fll`` file; other suffixes raise `ConfigError`."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in (".yaml", ".yml"):
        return engine_from_yaml(p)
    if suffix == ".fll":
        return engine_from_fll(p)
    raise ConfigError("unknown engine format: expected a .yaml, .yml or .fll file", file=str(p))


def builtin_engine_path(name: str) -> Path:
    """Path of a shipped engine's YAML (``idle`` or ``manual``)."""
    if name not in BUILTIN_ENGINES:
        raise ConfigError(f"unknown built-in engine '{name}'; known: {', '.join(BUILTIN_ENGINES)}")
    return Path(str(resources.files("atemr.skills.fuzzy").joinpath("engines", f"{name}.yaml")))


def load_builtin_engine(name: str) -> Engine:
    """The robot's IDLE (``"idle"``) or MANUAL (``"manual"``) engine."""
    return engine_from_yaml(builtin_engine_path(name))


def resolve_engine(spec: str | Path) -> Engine:
    """A built-in engine name or a path: what the CLI and configuration accept."""
    if isinstance(spec, str) and spec.lower() in BUILTIN_ENGINES and not Path(spec).exists():
        return load_builtin_engine(spec.lower())
    if isinstance(spec, str) and not Path(spec).suffix and not Path(spec).exists():
        raise ConfigError(f"no engine named {spec!r}: give a shipped engine ({', '.join(BUILTIN_ENGINES)}) or a "
                          ".yaml, .yml or .fll file")
    return load_engine(spec)
