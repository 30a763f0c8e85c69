"""Typed, validated objects from loosely typed layers (YAML mappings, environment strings, CLI values).

One function, `merge_into`, turns a mapping into a (nested) frozen dataclass, coercing each value to the
field's annotated type and checking the bounds declared in field metadata (``min``, ``max``,
``choices``, ``prefixes``). Every problem raises `ConfigError` that names the key path and its source: a YAML
file with line and column, an environment variable, or a command-line argument. Unknown keys are
errors, and nothing is half-applied: a new object is returned only when the whole layer is valid.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, TypeVar, Union, get_args, get_origin, get_type_hints

from atemr.errors import ConfigError
from atemr.yamlsafe import key_mark_of, mark_of

T = TypeVar("T")


@dataclasses.dataclass(frozen=True)
class Source:
    """Where a layer of values comes from, for error messages."""

    kind: Literal["default", "file", "env", "argument"]
    name: str | None = None  # file path, or None

    def error(
        self, message: str, path: str, container: Any = None, key: Any = None, *, on_key: bool = False
    ) -> ConfigError:
        if self.kind == "file":
            line, col = key_mark_of(container, key) if on_key else mark_of(container, key)
            return ConfigError(message, file=self.name, line=line, column=col, path=path)
        if self.kind == "env":
            env = "ATEMR_" + path.upper().replace(".", "__")
            return ConfigError(message, path=f"environment {env}")
        return ConfigError(message, path=f"{self.kind} {path}")


_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off"}


def _describe(tp: Any) -> str:
    origin = get_origin(tp)
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(tp))
    if origin in (Union, types.UnionType):
        return " or ".join(_describe(a) for a in get_args(tp))
    if tp is type(None):
        return "null"
    if tp is bool:
        return "true or false"
    if tp is int:
        return "an integer"
    if tp is float:
        return "a number"
    if tp is str:
        return "a string"
    if tp is Path:
        return "a path"
    if origin in (tuple, list):
        return f"a list of {_describe(get_args(tp)[0])}"
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    return getattr(tp, "__name__", str(tp))


def coerce(value: Any, tp: Any, *, from_text: bool) -> Any:  # noqa: PLR0912, PLR0915  one branch per supported type, in the order tried
    """Convert ``value`` to type ``tp`` or raise ``ValueError`` with what was expected.

    ``from_text`` is true for environment variables and CLI strings, where ``"5"`` means 5.
    """
    origin = get_origin(tp)
    if origin in (Union, types.UnionType):
        args = get_args(tp)
        is_null = value is None or (from_text and isinstance(value, str) and value.lower() in ("", "none", "null"))
        if is_null and type(None) in args:
            return None
        for arg in args:
            if arg is type(None):
                continue
            try:
                return coerce(value, arg, from_text=from_text)
            except ValueError:
                continue
        raise ValueError(f"expected {_describe(tp)}, got {value!r}")
    if origin is Literal:
        choices = get_args(tp)
        if value in choices:
            return value
        raise ValueError(f"expected {_describe(tp)}, got {value!r}")
    if tp is bool:
        if isinstance(value, bool):
            return value
        if from_text and isinstance(value, str) and value.lower() in _TRUE | _FALSE:
            return value.lower() in _TRUE
        raise ValueError(f"expected true or false, got {value!r}")
    if tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        if from_text and isinstance(value, str):
            try:
                return int(value, 0)
            except ValueError:
                pass
        raise ValueError(f"expected an integer, got {value!r}")
    if tp is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            result = float(value)
        elif from_text and isinstance(value, str):
            try:
                result = float(value)
            except ValueError:
                raise ValueError(f"expected a number, got {value!r}") from None
        else:
            raise ValueError(f"expected a number, got {value!r}")
        if not math.isfinite(result):
            raise ValueError(f"expected a finite number, got {value!r}")
        return result
    if tp is str:
        if isinstance(value, str):
            return value
        raise ValueError(f"expected a string, got {value!r}")
    if tp is Path:
        if isinstance(value, (str, Path)) and str(value):
            return Path(value).expanduser()
        raise ValueError(f"expected a path, got {value!r}")
    if origin in (tuple, list):
        item_tp = get_args(tp)[0]
        if from_text and isinstance(value, str):
            value = [v.strip() for v in value.split(",") if v.strip()]
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"expected {_describe(tp)}, got {value!r}")
        items = [coerce(v, item_tp, from_text=from_text) for v in value]
        return tuple(items) if origin is tuple else items
    raise TypeError(f"unsupported config type {tp!r}")


def _check_bounds(value: Any, meta: Mapping[str, Any]) -> None:
    if value is None:
        return
    if "min" in meta and value < meta["min"]:
        raise ValueError(f"must be at least {meta['min']}, got {value!r}")
    if "max" in meta and value > meta["max"]:
        raise ValueError(f"must be at most {meta['max']}, got {value!r}")
    if "choices" in meta and value not in meta["choices"]:
        raise ValueError(f"must be one of {', '.join(map(repr, meta['choices']))}, got {value!r}")
    if "prefixes" in meta and not str(value).startswith(tuple(meta["prefixes"])):
        raise ValueError(f"must start with {' or '.join(meta['prefixes'])}, got {value!r}")


def merge_into(obj: T, layer: Mapping[str, Any], source: Source, *, prefix: str = "") -> T:
    """Return a copy of dataclass ``obj`` with the values of ``layer`` applied, validated.

    Nested dataclass fields take nested mappings. Raises `ConfigError` on the first bad key or value;
    ``obj`` itself is never modified.
    """
    if not isinstance(layer, Mapping):
        raise source.error(f"expected a mapping, got {type(layer).__name__}", prefix or "(top)", layer)
    cls = type(obj)
    hints = get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(obj)}  # type: ignore[arg-type]
    changes: dict[str, Any] = {}
    for key, raw in layer.items():
        path = f"{prefix}.{key}" if prefix else str(key)
        if key not in fields:
            import difflib

            close = difflib.get_close_matches(str(key), list(fields), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            known = ", ".join(fields)
            raise source.error(f"unknown key '{key}'{hint}; known keys: {known}", path, layer, key, on_key=True)
        tp = hints[key]
        current = getattr(obj, key)
        if dataclasses.is_dataclass(tp):
            if not isinstance(raw, Mapping):
                raise source.error(f"expected a mapping, got {raw!r}", path, layer, key)
            changes[key] = merge_into(current, raw, source, prefix=path)
            continue
        try:
            value = coerce(raw, tp, from_text=source.kind in ("env", "argument") and isinstance(raw, str))
            _check_bounds(value, fields[key].metadata)
        except ValueError as exc:
            raise source.error(str(exc), path, layer, key) from None
        changes[key] = value
    result = dataclasses.replace(obj, **changes)  # type: ignore[type-var]
    check = getattr(result, "validate", None)
    if check is not None:
        try:
            check()
        except ValueError as exc:
            raise source.error(str(exc), prefix or "(top)", layer) from None
    return result


def field_paths(cls: type, prefix: str = "") -> dict[str, Any]:
    """Every leaf field of a (nested) dataclass type as ``{"sim.seed": int, ...}``."""
    out: dict[str, Any] = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        path = f"{prefix}.{f.name}" if prefix else f.name
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            out.update(field_paths(tp, path))  # type: ignore[arg-type]
        else:
            out[path] = tp
    return out


def nest(flat: Mapping[str, Any]) -> dict[str, Any]:
    """``{"sim.seed": 1}`` → ``{"sim": {"seed": 1}}``."""
    out: dict[str, Any] = {}
    for dotted, value in flat.items():
        node = out
        *parents, leaf = dotted.split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = value
    return out
