"""Import of fuzzylite's FuzzyLite Language (`.fll`) into the same `Engine` the YAML loader builds.

The original robot's engines were fuzzylite engines, and fuzzylite's examples come as `.fll`; this reads
the subset that maps onto our engine: ``Engine``, ``InputVariable``, ``OutputVariable`` and ``RuleBlock``
sections with ``range``, ``lock-range``, ``enabled``, ``term``, ``aggregation``, ``defuzzifier``,
``default``, ``lock-previous``, ``conjunction``, ``disjunction``, ``implication``, ``activation`` and
``rule``. What the engine cannot honour (a disabled variable, ``lock-previous: true``, an unknown term
shape such as ``Function``) is refused with `ConfigError` naming the file and line, never ignored.
"""

from __future__ import annotations

import math
from pathlib import Path

from atemr.errors import ConfigError
from atemr.skills.fuzzy.defuzzifiers import Defuzzifier, build_defuzzifier
from atemr.skills.fuzzy.engine import Engine, InputVariable, OutputVariable, RuleBlock
from atemr.skills.fuzzy.rules import parse_rule
from atemr.skills.fuzzy.terms import Term, build_term

MAX_BYTES = 1_000_000
SECTIONS = ("Engine", "InputVariable", "OutputVariable", "RuleBlock")


class _Section:
    def __init__(self, kind: str, name: str, line: int) -> None:
        self.kind = kind
        self.name = name
        self.line = line
        self.props: dict[str, tuple[str, int]] = {}
        self.terms: list[tuple[str, int]] = []
        self.rules: list[tuple[str, int]] = []


def _number(text: str, file: str, line: int, what: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ConfigError(f"{what}: expected a number, got '{text}'", file=file, line=line) from None


def _bool(section: _Section, key: str, default: bool, file: str) -> bool:
    if key not in section.props:
        return default
    text, line = section.props[key]
    if text not in ("true", "false"):
        raise ConfigError(f"{key}: expected true or false, got '{text}'", file=file, line=line)
    return text == "true"


def _operator(section: _Section, key: str) -> str | None:
    text = section.props.get(key, ("", 0))[0]
    return None if text in ("", "none") else text


def _split_sections(text: str, file: str) -> list[_Section]:
    sections: list[_Section] = []
    for number, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].rstrip()
        if not line.strip():
            continue
        key, sep, value = line.strip().partition(":")
        if not sep:
            raise ConfigError(f"expected 'key: value', got '{line.strip()}'", file=file, line=number)
        value = value.strip()
        if not line[0].isspace() and key in SECTIONS:
            sections.append(_Section(key, value, number))
            continue
        if not sections:
            raise ConfigError(f"'{key}' before any section (Engine, InputVariable, ...)", file=file, line=number)
        current = sections[-1]
        if key == "term":
            current.terms.append((value, number))
        elif key == "rule":
            current.rules.append((value, number))
        elif key in current.props:
            raise ConfigError(f"'{key}' given twice in {current.kind} '{current.name}'", file=file, line=number)
        else:
            current.props[key] = (value, number)
    return sections


def _terms(section: _Section, file: str) -> tuple[Term, ...]:
    terms = []
    for value, line in section.terms:
        words = value.split()
        if len(words) < 2:
            raise ConfigError(f"term: expected 'name Shape parameters...', got '{value}'", file=file, line=line)
        numbers = [_number(w, file, line, f"term '{words[0]}'") for w in words[2:]]
        try:
            terms.append(build_term(words[1], words[0], numbers))
        except ConfigError as exc:
            raise ConfigError(exc.reason, file=file, line=line) from None
    return tuple(terms)


def _range(section: _Section, file: str) -> tuple[float, float]:
    text, line = section.props.get("range", ("", section.line))
    words = text.split()
    if len(words) != 2:
        raise ConfigError(f"{section.kind} '{section.name}': expected 'range: minimum maximum'", file=file, line=line)
    return _number(words[0], file, line, "range"), _number(words[1], file, line, "range")


def _check_supported(section: _Section, file: str) -> None:
    if not _bool(section, "enabled", True, file) and section.kind != "RuleBlock":
        raise ConfigError(f"{section.kind} '{section.name}' is disabled: remove it instead (not supported)",
                          file=file, line=section.props["enabled"][1])
    if _bool(section, "lock-previous", False, file):
        raise ConfigError("lock-previous: true is not supported: rows are evaluated independently",
                          file=file, line=section.props["lock-previous"][1])
    known = {
        "Engine": ("description",),
        "InputVariable": ("enabled", "range", "lock-range", "description"),
        "OutputVariable": ("enabled", "range", "lock-range", "aggregation", "defuzzifier", "default",
                           "lock-previous", "description"),
        "RuleBlock": ("enabled", "conjunction", "disjunction", "implication", "activation", "description"),
    }[section.kind]
    for key, (_, line) in section.props.items():
        if key not in known:
            raise ConfigError(f"unknown property '{key}' in {section.kind}; known: {', '.join(known)}",
                              file=file, line=line)
    if section.kind in ("Engine",) and section.terms:
        raise ConfigError("terms belong to variables, not to the Engine", file=file, line=section.terms[0][1])


def engine_from_fll(source: str | Path, text: str | None = None) -> Engine:
    """Read a `.fll` file (or ``text``, named ``source`` in errors) into a validated `Engine`."""
    file = str(source)
    sections = _split_sections(_read(source) if text is None else text, file)
    if not sections or sections[0].kind != "Engine":
        raise ConfigError("a .fll file starts with 'Engine: name'", file=file, line=sections[0].line if sections else 1)
    inputs: list[InputVariable] = []
    outputs: list[OutputVariable] = []
    for s in sections:
        _check_supported(s, file)
        if s.kind == "InputVariable":
            lo, hi = _range(s, file)
            inputs.append(InputVariable(s.name, lo, hi, _terms(s, file), _bool(s, "lock-range", False, file)))
        elif s.kind == "OutputVariable":
            outputs.append(_output_variable(s, file))
    # the line of each section and rule, to point engine validation errors (by path) at the file
    lines: dict[str, int] = {}
    blocks = _rule_blocks(sections, inputs, outputs, file, lines)
    try:
        return Engine(sections[0].name, tuple(inputs), tuple(outputs), tuple(blocks),
                      sections[0].props.get("description", ("", 0))[0])
    except ConfigError as exc:
        where = _line_for(exc.path or "", lines)
        raise ConfigError(exc.reason, file=file, line=where, path=exc.path) from None


def _read(source: str | Path) -> str:
    file = str(source)
    try:
        path = Path(source)
        if path.stat().st_size > MAX_BYTES:
            raise ConfigError(f"file is larger than {MAX_BYTES} bytes", file=file)
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("file not found", file=file) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read: {exc}", file=file) from None


def _output_variable(s: _Section, file: str) -> OutputVariable:
    lo, hi = _range(s, file)
    dtext, dline = s.props.get("defuzzifier", ("", s.line))
    words = dtext.split()
    try:
        if not words or words[0] == "none":
            raise ConfigError(f"output '{s.name}' needs a defuzzifier")
        defuzzifier: Defuzzifier = build_defuzzifier(words[0], words[1] if len(words) > 1 else None)
    except ConfigError as exc:
        raise ConfigError(exc.reason, file=file, line=dline) from None
    dtext, dline = s.props.get("default", ("nan", s.line))
    default = _number(dtext, file, dline, "default") if dtext else math.nan
    return OutputVariable(s.name, lo, hi, _terms(s, file), defuzzifier, _operator(s, "aggregation"), default,
                          _bool(s, "lock-range", False, file))


def _rule_blocks(sections: list[_Section], inputs: list[InputVariable], outputs: list[OutputVariable], file: str,
                 lines: dict[str, int]) -> list[RuleBlock]:
    """The enabled rule blocks, their rules parsed against the variables' terms; records in ``lines`` the line of
    every section, block and rule (keys as `_line_for` looks them up)."""
    in_terms = {v.name: [t.name for t in v.terms] for v in inputs}
    out_terms = {v.name: [t.name for t in v.terms] for v in outputs}
    blocks: list[RuleBlock] = []
    block_lines: list[int] = []
    for s in sections:
        if s.kind != "RuleBlock" or not _bool(s, "enabled", True, file):
            continue
        rules = []
        for ri, (rtext, line) in enumerate(s.rules):
            lines[f"rule_blocks:{len(blocks)}.rules:{ri}"] = line
            try:
                rules.append(parse_rule(rtext, in_terms, out_terms))
            except ConfigError as exc:
                raise ConfigError(exc.reason, file=file, line=line) from None
        block_lines.append(s.line)
        blocks.append(RuleBlock(s.name or f"block{len(blocks)}", tuple(rules), _operator(s, "conjunction"),
                                _operator(s, "disjunction"), _operator(s, "implication"),
                                s.props.get("activation", ("General", 0))[0] or "General"))
    lines.update({s.kind + ":" + s.name: s.line for s in sections})
    lines.update({f"rule_blocks:{i}": line for i, line in enumerate(block_lines)})
    return blocks


def _line_for(path: str, lines: dict[str, int]) -> int | None:
    """Best line for an engine validation error path (``outputs.x.aggregation`` → the OutputVariable)."""
    parts = path.replace("[", ".").split(".")
    if parts[0] == "outputs" and len(parts) > 1:
        return lines.get(f"OutputVariable:{parts[1]}")
    if parts[0] == "inputs" and len(parts) > 1:
        return lines.get(f"InputVariable:{parts[1]}")
    if parts[0] == "rule_blocks" and len(parts) > 3 and parts[2] == "rules":
        return lines.get(f"rule_blocks:{parts[1].rstrip(']')}.rules:{parts[3].rstrip(']')}")
    if parts[0] == "rule_blocks" and len(parts) > 1:
        return lines.get(f"rule_blocks:{parts[1].rstrip(']')}")
    return None
