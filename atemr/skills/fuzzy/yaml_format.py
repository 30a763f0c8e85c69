"""The YAML engine format and its validating loader.

An engine is one mapping (see ``engines/idle.yaml`` for a full example)::

    name: IDLE
    type: Larsen                    # optional: Mamdani | Larsen | Tsukamoto | TakagiSugeno | Hybrid, checked
    description: free text
    inputs:
      FR:
        range: [0.0, 1.2]
        lock_range: true            # clip inputs to the range (default false)
        terms:
          NEAR: Ramp 0.9 0.3        # "Shape p1 p2 ... [height]", fuzzylite parameter order
          FAR: {type: Ramp, params: [0.3, 0.9]}
    outputs:
      angSteer:
        range: [-1.0, 1.0]
        aggregation: Maximum        # S-norm or none
        defuzzifier: Centroid 200   # or {type: Centroid, resolution: 200}; WeightedAverage Tsukamoto, ...
        default: 0.0                # value when no rule fires (default .nan)
        lock_range: false
        terms: {LEFT: Triangle 0.0 0.5 1.0}
    rule_blocks:
      - name: main
        conjunction: Minimum        # T-norm or none
        disjunction: Maximum        # S-norm or none
        implication: AlgebraicProduct
        activation: General
        rules:
          - if FR is NEAR and FL is FAR then angSteer is LEFT

Every mistake raises `ConfigError` with ``file:line:column`` and the path in the document; unknown keys,
shapes, norms and names are refused with the closest known names.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Any

from atemr.errors import ConfigError
from atemr.skills.fuzzy.defuzzifiers import build_defuzzifier
from atemr.skills.fuzzy.engine import Engine, InputVariable, OutputVariable, RuleBlock
from atemr.skills.fuzzy.rules import Rule, parse_rule
from atemr.skills.fuzzy.terms import Term, build_term
from atemr.yamlsafe import MarkedDict, MarkedList, key_mark_of, load_yaml, mark_of

ENGINE_KEYS = ("name", "type", "description", "inputs", "outputs", "rule_blocks")
INPUT_KEYS = ("range", "lock_range", "terms", "description")
OUTPUT_KEYS = ("range", "lock_range", "terms", "aggregation", "defuzzifier", "default", "description")
BLOCK_KEYS = ("name", "conjunction", "disjunction", "implication", "activation", "rules", "description")


class _Doc:
    """Error helper bound to one file: every error names file, line, column and document path."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.marks: dict[str, tuple[int | None, int | None]] = {}

    def error(
        self, message: str, path: str, container: Any = None, key: Any = None, on_key: bool = False
    ) -> ConfigError:
        line: int | None = None
        col: int | None = None
        if container is not None:
            line, col = key_mark_of(container, key) if on_key else mark_of(container, key)
        return ConfigError(message, file=self.file, line=line, column=col, path=path)

    def remember(self, path: str, container: Any, key: Any = None, on_key: bool = False) -> None:
        self.marks[path] = key_mark_of(container, key) if on_key else mark_of(container, key)

    def mapping(self, value: Any, path: str, parent: Any, key: Any, allowed: tuple[str, ...]) -> MarkedDict:
        if not isinstance(value, dict):
            raise self.error(f"expected a mapping, got {type(value).__name__}", path, parent, key)
        for k in value:
            if k not in allowed:
                close = difflib.get_close_matches(str(k), allowed, n=1)
                hint = f" (did you mean '{close[0]}'?)" if close else ""
                raise self.error(f"unknown key '{k}'{hint}; allowed: {', '.join(allowed)}", f"{path}.{k}",
                                 value, k, on_key=True)
        return value  # type: ignore[return-value]

    def number(self, value: Any, path: str, parent: Any, key: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float | str):
            raise self.error(f"expected a number, got {value!r}", path, parent, key)
        try:
            return float(value)
        except ValueError:
            raise self.error(f"expected a number, got {value!r}", path, parent, key) from None

    def boolean(self, value: Any, path: str, parent: Any, key: Any) -> bool:
        if not isinstance(value, bool):
            raise self.error(f"expected true or false, got {value!r}", path, parent, key)
        return value

    def name(self, value: Any, path: str, parent: Any, key: Any) -> str:
        if not isinstance(value, str) or not value or any(c.isspace() for c in value):
            raise self.error(f"expected a name without spaces, got {value!r}", path, parent, key)
        return value

    def operator(self, value: Any, path: str, parent: Any, key: Any) -> str | None:
        if value is None or (isinstance(value, str) and value.lower() == "none"):
            return None
        return self.name(value, path, parent, key)


def _range(doc: _Doc, spec: MarkedDict, path: str) -> tuple[float, float]:
    value = spec.get("range")
    if not isinstance(value, list) or len(value) != 2:
        raise doc.error("range must be a list [minimum, maximum]", f"{path}.range", spec,
                        "range" if "range" in spec else None)
    lo = doc.number(value[0], f"{path}.range[0]", value, 0)
    hi = doc.number(value[1], f"{path}.range[1]", value, 1)
    if not lo < hi or math.isnan(lo) or math.isnan(hi):
        raise doc.error(f"range minimum {lo:g} must be below maximum {hi:g}", f"{path}.range", spec, "range")
    return lo, hi


def _terms(doc: _Doc, spec: MarkedDict, path: str) -> tuple[Term, ...]:
    if "terms" not in spec:
        raise doc.error("missing 'terms'", path, spec)
    raw = spec["terms"]
    if not isinstance(raw, dict) or not raw:
        raise doc.error("terms must be a non-empty mapping of name: shape", f"{path}.terms", spec, "terms")
    terms = []
    for key, tspec in raw.items():
        tpath = f"{path}.terms.{key}"
        tname = doc.name(key, tpath, raw, key)
        if isinstance(tspec, str):
            words = tspec.split()
            if not words:
                raise doc.error("empty term", tpath, raw, tname)
            kind = words[0]
            values = [doc.number(w, tpath, raw, tname) for w in words[1:]]
        elif isinstance(tspec, dict):
            tmap = doc.mapping(tspec, tpath, raw, tname, ("type", "params", "height"))
            kind = doc.name(tmap.get("type"), f"{tpath}.type", tmap, "type")
            params = tmap.get("params", [])
            if not isinstance(params, list):
                raise doc.error("params must be a list of numbers", f"{tpath}.params", tmap, "params")
            values = [doc.number(v, f"{tpath}.params[{i}]", params, i) for i, v in enumerate(params)]
            if "height" in tmap:
                values.append(doc.number(tmap["height"], f"{tpath}.height", tmap, "height"))
        else:
            raise doc.error("a term is 'Shape p1 p2 ...' or {type:, params: [...]}", tpath, raw, tname)
        try:
            terms.append(build_term(kind, tname, values))
        except ConfigError as exc:
            raise doc.error(exc.reason, tpath, raw, tname) from None
    return tuple(terms)


def _input(doc: _Doc, name: str, spec: Any, parent: Any) -> InputVariable:
    path = f"inputs.{name}"
    spec = doc.mapping(spec, path, parent, name, INPUT_KEYS)
    lo, hi = _range(doc, spec, path)
    lock = doc.boolean(spec["lock_range"], f"{path}.lock_range", spec, "lock_range") if "lock_range" in spec else False
    doc.remember(path, parent, name, on_key=True)
    return InputVariable(name, lo, hi, _terms(doc, spec, path), lock)


def _output(doc: _Doc, name: str, spec: Any, parent: Any) -> OutputVariable:
    path = f"outputs.{name}"
    spec = doc.mapping(spec, path, parent, name, OUTPUT_KEYS)
    lo, hi = _range(doc, spec, path)
    lock = doc.boolean(spec["lock_range"], f"{path}.lock_range", spec, "lock_range") if "lock_range" in spec else False
    default = doc.number(spec["default"], f"{path}.default", spec, "default") if "default" in spec else math.nan
    aggregation = doc.operator(spec.get("aggregation"), f"{path}.aggregation", spec, "aggregation")
    if "defuzzifier" not in spec:
        raise doc.error("missing 'defuzzifier'", path, parent, name)
    raw = spec["defuzzifier"]
    dpath = f"{path}.defuzzifier"
    try:
        if isinstance(raw, str) and raw.split():
            words = raw.split()
            if len(words) > 2:
                raise ConfigError(f"expected 'Name [parameter]', got '{raw}'")
            defuzzifier = build_defuzzifier(words[0], words[1] if len(words) > 1 else None)
        elif isinstance(raw, dict):
            dmap = doc.mapping(raw, dpath, spec, "defuzzifier", ("type", "resolution"))
            dname = doc.name(dmap.get("type"), f"{dpath}.type", dmap, "type")
            defuzzifier = build_defuzzifier(dname, dmap.get("resolution"))
        else:
            raise ConfigError("expected 'Name [parameter]' or {type:, resolution:}")
    except ConfigError as exc:
        raise doc.error(exc.reason, dpath, spec, "defuzzifier") from None
    doc.remember(path, parent, name, on_key=True)
    for key in ("aggregation", "defuzzifier", "range"):
        if key in spec:
            doc.remember(f"{path}.{key}", spec, key)
    return OutputVariable(name, lo, hi, _terms(doc, spec, path), defuzzifier, aggregation, default, lock)


def _blocks(doc: _Doc, raw: Any, root: MarkedDict, inputs: dict[str, list[str]],
            outputs: dict[str, list[str]]) -> tuple[RuleBlock, ...]:
    if not isinstance(raw, list) or not raw:
        raise doc.error("rule_blocks must be a non-empty list", "rule_blocks", root, "rule_blocks")
    blocks = []
    for bi, item in enumerate(raw):
        path = f"rule_blocks[{bi}]"
        spec = doc.mapping(item, path, raw, bi, BLOCK_KEYS)
        doc.remember(path, raw, bi)
        for key in ("conjunction", "disjunction", "implication", "activation"):
            if key in spec:
                doc.remember(f"{path}.{key}", spec, key)
        name = str(spec.get("name", f"block{bi}"))
        ops = {k: doc.operator(spec.get(k, d), f"{path}.{k}", spec, k)
               for k, d in (("conjunction", None), ("disjunction", None), ("implication", None))}
        activation = doc.name(spec.get("activation", "General"), f"{path}.activation", spec, "activation")
        rules_raw = spec.get("rules")
        if not isinstance(rules_raw, MarkedList) or not rules_raw:
            raise doc.error("rules must be a non-empty list of 'if ... then ...'", f"{path}.rules", spec,
                            "rules" if "rules" in spec else None)
        rules: list[Rule] = []
        for ri, text in enumerate(rules_raw):
            rpath = f"{path}.rules[{ri}]"
            doc.remember(rpath, rules_raw, ri)
            if not isinstance(text, str):
                raise doc.error(f"a rule is a string, got {text!r}", rpath, rules_raw, ri)
            try:
                rules.append(parse_rule(text, inputs, outputs))
            except ConfigError as exc:
                raise doc.error(exc.reason, rpath, rules_raw, ri) from None
        blocks.append(RuleBlock(name, tuple(rules), ops["conjunction"], ops["disjunction"], ops["implication"],
                                activation))
    return tuple(blocks)


def engine_from_yaml(source: str | Path, text: str | None = None) -> Engine:
    """Load and validate a YAML engine from a file (or from ``text``, named ``source`` in errors)."""
    data = load_yaml(source, text=text)
    doc = _Doc(str(source))
    root = doc.mapping(data, "", None, None, ENGINE_KEYS) if data is not None else None
    if root is None:
        raise ConfigError("empty document: expected an engine mapping", file=str(source))
    for key in ("inputs", "outputs", "rule_blocks"):
        if key not in root:
            raise doc.error(f"missing '{key}'", key, root)
    for key in ("inputs", "outputs"):
        if not isinstance(root[key], dict) or (key == "outputs" and not root[key]):
            raise doc.error(f"{key} must be a mapping of variable name: definition", key, root, key)
    inputs = tuple(_input(doc, doc.name(k, f"inputs.{k}", root["inputs"], k), v, root["inputs"])
                   for k, v in root["inputs"].items())
    outputs = tuple(_output(doc, doc.name(k, f"outputs.{k}", root["outputs"], k), v, root["outputs"])
                    for k, v in root["outputs"].items())
    in_terms = {v.name: [t.name for t in v.terms] for v in inputs}
    out_terms = {v.name: [t.name for t in v.terms] for v in outputs}
    blocks = _blocks(doc, root["rule_blocks"], root, in_terms, out_terms)
    name = str(root.get("name", Path(str(source)).stem))
    kind = root.get("type")
    if "type" in root:
        doc.remember("type", root, "type")
    try:
        return Engine(name, inputs, outputs, blocks, str(root.get("description", "")).strip(),
                      None if kind is None else str(kind))
    except ConfigError as exc:
        path = exc.path or ""
        line, col = _closest_mark(doc, path)
        raise ConfigError(exc.reason, file=str(source), line=line, column=col, path=path) from None


def _closest_mark(doc: _Doc, path: str) -> tuple[int | None, int | None]:
    """The mark of ``path`` or of its nearest remembered ancestor."""
    while path:
        if path in doc.marks:
            return doc.marks[path]
        cut = max(path.rfind("."), path.rfind("["))
        path = path[:cut] if cut > 0 else ""
    return None, None
