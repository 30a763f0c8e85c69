"""The fuzzy inference engine: variables, rule blocks and vectorised evaluation of N input rows at once.

`Engine.process` evaluates every rule for all rows with numpy, never looping over rows or samples: it runs
the plan the engine compiled into flat arrays when it was built (`atemr.skills.fuzzy.compiled`, a few
dozen numpy operations per call whatever the number of rules, so one row costs tens of microseconds);
`Engine.process_columns_generic` is the same evaluation written rule by rule, the reference the plan is
tested against. Both follow fuzzylite's documented semantics, so the engines of the original robot
(written for fuzzylite) and fuzzylite's own examples give fuzzylite's numbers:

* a rule fires for a row when its activation degree (weight × antecedent) is above zero by more than
  fuzzylite's tolerance 1e-6; a non-firing rule contributes nothing;
* an output none of whose rules fired takes its ``default`` value (NaN unless set), and an integral
  defuzzifier over an all-zero fuzzy set gives NaN (0/0), exactly as fuzzylite prints in its datasets;
* Mamdani/Larsen: each fired rule adds ``implication(degree, μ_term(x))`` to its output, aggregated with
  the output's S-norm, then an integral defuzzifier; Takagi-Sugeno and Tsukamoto: degrees of the same
  term are grouped with the output's aggregation (or summed when it has none) and combined by a weighted
  defuzzifier; a hybrid engine mixes both across rule blocks.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from atemr.errors import AtemrError, ConfigError
from atemr.skills.fuzzy.compiled import FIRING_EPSILON, CompiledEngine, compile_engine, integrate, weighted_kind
from atemr.skills.fuzzy.defuzzifiers import Centroid, Defuzzifier, IntegralDefuzzifier, WeightedDefuzzifier
from atemr.skills.fuzzy.discrete_centroid import DiscreteCentroid
from atemr.skills.fuzzy.norms import HEDGES, SNORMS, TNORMS, Norm, maximum
from atemr.skills.fuzzy.rules import Rule
from atemr.skills.fuzzy.separable import is_separable
from atemr.skills.fuzzy.terms import Constant, Linear, Term

Array = NDArray[np.float64]

#: Engine kinds a YAML ``type:`` may declare; the engine checks the declaration against its parts.
ENGINE_TYPES = ("Mamdani", "Larsen", "Tsukamoto", "TakagiSugeno", "Hybrid")


class FuzzyInputError(AtemrError):
    """The inputs handed to `Engine.process` are wrong: a missing or unknown variable, non-numbers,
    shapes that do not broadcast."""


@dataclass(frozen=True)
class InputVariable:
    """An input with its range and terms; ``lock_range`` clips values to the range before fuzzifying."""

    name: str
    minimum: float
    maximum: float
    terms: tuple[Term, ...]
    lock_range: bool = False

    def term(self, name: str) -> Term:
        """The term called ``name``."""
        return next(t for t in self.terms if t.name == name)


@dataclass(frozen=True)
class OutputVariable:
    """An output: range, terms, defuzzifier, aggregation S-norm (None: 'none'), default for no firing."""

    name: str
    minimum: float
    maximum: float
    terms: tuple[Term, ...]
    defuzzifier: Defuzzifier
    aggregation: str | None = "Maximum"
    default: float = math.nan
    lock_range: bool = False

    def term(self, name: str) -> Term:
        """The term called ``name``."""
        return next(t for t in self.terms if t.name == name)


@dataclass(frozen=True)
class RuleBlock:
    """Rules sharing operators; None means 'none' (a rule that needs the operator is refused)."""

    name: str
    rules: tuple[Rule, ...]
    conjunction: str | None = "Minimum"
    disjunction: str | None = "Maximum"
    implication: str | None = "Minimum"
    activation: str = "General"


@dataclass
class _Contribution:
    term: Term
    degree: Array
    fired: NDArray[np.bool_]
    implication: str | None


@dataclass(frozen=True)
class Engine:
    """A validated fuzzy inference system; build it with `load_engine` or directly from its parts."""

    name: str
    inputs: tuple[InputVariable, ...]
    outputs: tuple[OutputVariable, ...]
    rule_blocks: tuple[RuleBlock, ...]
    description: str = ""
    type: str | None = None
    _grids: dict[str, tuple[Array, dict[str, Array]]] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )
    _plan: CompiledEngine = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        validate_engine(self)
        for out in self.outputs:
            d = out.defuzzifier
            if isinstance(d, IntegralDefuzzifier):
                x = d.samples(out.minimum, out.maximum)
                self._grids[out.name] = (x, {t.name: t.membership(x) for t in out.terms})
        object.__setattr__(self, "_plan", compile_engine(self, self._grids))

    @property
    def input_names(self) -> tuple[str, ...]:
        """Input variable names in declaration order (the column order of `atemr fuzzy eval`)."""
        return self._plan.input_names

    @property
    def output_names(self) -> tuple[str, ...]:
        """Output variable names in declaration order."""
        return tuple(v.name for v in self.outputs)

    @property
    def rules(self) -> tuple[Rule, ...]:
        """Every rule of every block, in order."""
        return tuple(r for b in self.rule_blocks for r in b.rules)

    def process(self, inputs: Mapping[str, ArrayLike]) -> dict[str, Array]:
        """Evaluate the engine for every row of ``inputs`` (name → scalar or array, broadcast together).

        Returns name → array of the broadcast shape (a scalar input gives shape ()). Raises
        `FuzzyInputError` for missing or unknown names and values that are not numbers.
        """
        plan = self._plan
        if plan.input_set != set(inputs):
            raise self._names_error(inputs)
        values = [inputs[name] for name in plan.input_names]
        if all(isinstance(v, (float, int)) for v in values):  # one row of plain numbers: the control tick
            matrix = np.array(values, dtype=np.float64).reshape(-1, 1)
            shape: tuple[int, ...] = ()
        else:
            matrix, shape = self._matrix(values)
        result = plan.evaluate(matrix).reshape((len(self.outputs), *shape))
        return {name: result[p, ...] for name, p in plan.outputs}

    def _names_error(self, inputs: Mapping[str, ArrayLike]) -> FuzzyInputError:
        missing = [n for n in self.input_names if n not in inputs]
        unknown = [n for n in inputs if n not in self.input_names]
        parts = []
        if missing:
            parts.append(f"missing input(s) {', '.join(missing)}")
        if unknown:
            parts.append(f"unknown input(s) {', '.join(map(str, unknown))}")
        return FuzzyInputError(f"engine '{self.name}': {'; '.join(parts)}; inputs are {', '.join(self.input_names)}")

    def _matrix(self, values: list[ArrayLike]) -> tuple[Array, tuple[int, ...]]:
        """The (inputs, rows) matrix of the inputs broadcast together, and their broadcast shape."""
        arrays = []
        for var, value in zip(self.inputs, values, strict=True):
            try:
                arrays.append(np.asarray(value, dtype=np.float64))
            except (TypeError, ValueError):
                raise FuzzyInputError(f"engine '{self.name}': input '{var.name}' is not numeric: {value!r}") from None
        try:
            shaped = np.broadcast_arrays(*arrays)
        except ValueError:
            shapes = ", ".join(f"{v.name}{a.shape}" for v, a in zip(self.inputs, arrays, strict=True))
            raise FuzzyInputError(f"engine '{self.name}': input shapes do not broadcast: {shapes}") from None
        if not shaped:
            return np.zeros((0, 1)), ()
        return np.stack([a.reshape(-1) for a in shaped]), shaped[0].shape

    def process_columns(self, columns: Mapping[str, Array]) -> dict[str, Array]:
        """Core of `process`: every input a 1-D float array of the same length N; no checks."""
        plan = self._plan
        if plan.input_names:
            matrix = np.stack([np.asarray(columns[name], dtype=np.float64) for name in plan.input_names])
        else:
            matrix = np.zeros((0, 1))
        result = plan.evaluate(matrix)
        return {name: result[p] for name, p in plan.outputs}

    def process_columns_generic(self, columns: Mapping[str, Array]) -> dict[str, Array]:
        """`process_columns` rule by rule, term by term: the reference the compiled plan is tested against
        (same numbers) and `benchmarks/bench_fuzzy.py` times; about ten times slower for one row."""
        values: dict[str, Array] = {}
        for var in self.inputs:
            x = columns[var.name]
            values[var.name] = np.clip(x, var.minimum, var.maximum) if var.lock_range else x
        n = len(next(iter(values.values()))) if values else 1
        memo: dict[tuple[str, str], Array] = {}
        by_name = {v.name: v for v in self.inputs}

        def membership(variable: str, term: str) -> Array:
            key = (variable, term)
            if key not in memo:
                memo[key] = by_name[variable].term(term).membership(values[variable])
            return memo[key]

        contributions: dict[str, list[_Contribution]] = {o.name: [] for o in self.outputs}
        outputs = {o.name: o for o in self.outputs}
        for block in self.rule_blocks:
            conj = TNORMS.get(block.conjunction) if block.conjunction else None
            disj = SNORMS.get(block.disjunction) if block.disjunction else None
            for rule in block.rules:
                degree = np.broadcast_to(rule.degree(membership, conj, disj), (n,))
                fired = degree >= FIRING_EPSILON
                degree = np.where(fired, degree, 0.0)
                for prop in rule.consequents:
                    d = degree
                    for hedge in reversed(prop.hedges):
                        d = np.where(fired, HEDGES.get(hedge)(d), 0.0)
                    term = outputs[prop.variable].term(prop.term)
                    contributions[prop.variable].append(_Contribution(term, d, fired, block.implication))

        matrix = np.column_stack([values[v.name] for v in self.inputs]) if self.inputs else np.zeros((n, 0))
        result: dict[str, Array] = {}
        for out in self.outputs:
            parts = contributions[out.name]
            any_fired = np.zeros(n, dtype=bool)
            for c in parts:
                any_fired |= c.fired
            if isinstance(out.defuzzifier, IntegralDefuzzifier):
                crisp = self._integral(out, parts, n)
            else:
                crisp = self._weighted(out, parts, n, matrix)
            crisp = np.where(any_fired, crisp, out.default)
            if out.lock_range:
                crisp = np.clip(crisp, out.minimum, out.maximum)
            result[out.name] = crisp
        return result

    def _integral(self, out: OutputVariable, parts: list[_Contribution], n: int) -> Array:
        assert isinstance(out.defuzzifier, IntegralDefuzzifier)
        x, mu = self._grids[out.name]
        agg: Norm = SNORMS.get(out.aggregation) if out.aggregation else maximum
        if agg is maximum:
            # max over rules of T(d_r, μ) == T(max d_r, μ) for any monotone T-norm: group by term first.
            grouped: dict[tuple[str, str | None], Array] = {}
            for c in parts:
                key = (c.term.name, c.implication)
                grouped[key] = np.maximum(grouped[key], c.degree) if key in grouped else c.degree
            items = [(mu[t], d, imp) for (t, imp), d in grouped.items()]
        else:
            items = [(mu[c.term.name], c.degree, c.implication) for c in parts]
        separable = None
        if type(out.defuzzifier) is Centroid and agg is maximum and items:
            separable = is_separable(np.stack([i[0] for i in items]), [i[2] for i in items])
        return integrate(out.defuzzifier, x, items, n, agg, separable=separable)

    def _weighted(self, out: OutputVariable, parts: list[_Contribution], n: int, matrix: Array) -> Array:
        d = out.defuzzifier
        assert isinstance(d, WeightedDefuzzifier)
        group: Norm = SNORMS.get(out.aggregation) if out.aggregation else SNORMS.get("UnboundedSum")
        degrees: dict[str, Array] = {}
        fired: dict[str, NDArray[np.bool_]] = {}
        terms: dict[str, Term] = {}
        for c in parts:
            name = c.term.name
            degrees[name] = group(degrees[name], c.degree) if name in degrees else c.degree
            fired[name] = fired[name] | c.fired if name in fired else c.fired
            terms[name] = c.term
        if not terms:
            return np.full(n, np.nan)
        names = list(terms)
        w = np.column_stack([degrees[k] for k in names])
        present = np.column_stack([fired[k] for k in names])
        kind = weighted_kind(out)
        zs = []
        for k in names:
            term = terms[k]
            if kind == "Tsukamoto":
                zs.append(np.where(fired[k], term.tsukamoto(degrees[k]), 0.0))
            elif isinstance(term, Linear):
                zs.append(term.evaluate(matrix))
            else:
                zs.append(np.broadcast_to(term.membership(degrees[k]), (n,)))
        z = np.column_stack(zs)
        return d.combine(w, z, present)

    def describe(self) -> str:
        """The engine in fuzzylite's `.fll` layout (what `atemr fuzzy show` prints)."""
        lines = [f"Engine: {self.name}"]
        if self.type:
            lines.append(f"#  type: {self.type}")
        if self.description:
            lines.append(f"#  {self.description}")
        for v in self.inputs:
            lines += [f"InputVariable: {v.name}", f"  range: {v.minimum:g} {v.maximum:g}",
                      f"  lock-range: {str(v.lock_range).lower()}"]
            lines += [f"  term: {t.describe()}" for t in v.terms]
        for o in self.outputs:
            lines += [f"OutputVariable: {o.name}", f"  range: {o.minimum:g} {o.maximum:g}",
                      f"  lock-range: {str(o.lock_range).lower()}", f"  aggregation: {o.aggregation or 'none'}",
                      f"  defuzzifier: {o.defuzzifier.describe()}", f"  default: {o.default:g}"]
            lines += [f"  term: {t.describe()}" for t in o.terms]
        for b in self.rule_blocks:
            lines += [f"RuleBlock: {b.name}", f"  conjunction: {b.conjunction or 'none'}",
                      f"  disjunction: {b.disjunction or 'none'}", f"  implication: {b.implication or 'none'}",
                      f"  activation: {b.activation}"]
            lines += [f"  rule: {r.text}" for r in b.rules]
        return "\n".join(lines) + "\n"


def validate_engine(engine: Engine) -> None:
    """Cross-checks that need the whole engine; raises `ConfigError` with the offending part's path. The checks
    run in the order of the file (variables, type, rule blocks, outputs), so the first error named is the first
    a reader meets."""
    _check_variables(engine)
    if engine.type is not None and engine.type not in ENGINE_TYPES:
        raise ConfigError(f"type must be one of {', '.join(ENGINE_TYPES)}, got '{engine.type}'", path="type")
    used = _check_rule_blocks(engine)
    for out in engine.outputs:
        _check_output(out, used[out.name], len(engine.inputs))
    _check_type(engine)


def _check_variables(engine: Engine) -> None:
    """Unique variable names, at least one output, a range below its maximum, unique term names."""
    names = [v.name for v in engine.inputs] + [v.name for v in engine.outputs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ConfigError(f"variable name(s) used twice: {', '.join(dup)}", path="inputs/outputs")
    if not engine.outputs:
        raise ConfigError("an engine needs at least one output", path="outputs")
    variables: list[InputVariable | OutputVariable] = [*engine.inputs, *engine.outputs]
    for var in variables:
        kind = "inputs" if isinstance(var, InputVariable) else "outputs"
        if not var.minimum < var.maximum:
            raise ConfigError(f"range minimum {var.minimum:g} must be below maximum {var.maximum:g}",
                              path=f"{kind}.{var.name}.range")
        tnames = [t.name for t in var.terms]
        if len(set(tnames)) != len(tnames):
            raise ConfigError("term name used twice", path=f"{kind}.{var.name}.terms")


def _check_rule_blocks(engine: Engine) -> dict[str, set[str]]:
    """Known operators, General activation, an operator for each connective a rule uses and an implication
    where an integral output concludes; returns the terms the rules conclude on, by output."""
    used: dict[str, set[str]] = {o.name: set() for o in engine.outputs}
    for bi, block in enumerate(engine.rule_blocks):
        where = f"rule_blocks[{bi}]"
        for op, reg in (("conjunction", TNORMS), ("disjunction", SNORMS), ("implication", TNORMS)):
            value = getattr(block, op)
            if value is not None and value not in reg:
                raise ConfigError(reg.unknown_message(value), path=f"{where}.{op}")
        if block.activation != "General":
            raise ConfigError(f"activation '{block.activation}' is not supported (only General)",
                              path=f"{where}.activation")
        for ri, rule in enumerate(block.rules):
            if rule.uses("and") and block.conjunction is None:
                raise ConfigError(f"rule '{rule.text}' uses 'and' but conjunction is none", path=f"{where}.rules[{ri}]")
            if rule.uses("or") and block.disjunction is None:
                raise ConfigError(f"rule '{rule.text}' uses 'or' but disjunction is none", path=f"{where}.rules[{ri}]")
            for prop in rule.consequents:
                used[prop.variable].add(prop.term)
                out = next(o for o in engine.outputs if o.name == prop.variable)
                if out.defuzzifier.INTEGRAL and block.implication is None:
                    raise ConfigError(
                        f"output '{out.name}' has integral defuzzifier {out.defuzzifier.kind}, so the rule block "
                        "needs an implication operator", path=f"{where}.implication")
    return used


def _check_output(out: OutputVariable, used: set[str], n_inputs: int) -> None:
    """A known aggregation (Maximum for DiscreteCentroid), and terms the defuzzifier can use: of the terms the
    rules conclude on (``used``), monotonic ones for Tsukamoto, Constant or Linear ones (with one coefficient per
    input, and a constant) for Takagi-Sugeno; Linear terms only with a weighted defuzzifier."""
    where = f"outputs.{out.name}"
    if out.aggregation is not None and out.aggregation not in SNORMS:
        raise ConfigError(SNORMS.unknown_message(out.aggregation), path=f"{where}.aggregation")
    if isinstance(out.defuzzifier, DiscreteCentroid) and out.aggregation not in (None, "Maximum"):
        raise ConfigError("DiscreteCentroid aggregates with Maximum (like scikit-fuzzy)", path=f"{where}.aggregation")
    if not isinstance(out.defuzzifier, WeightedDefuzzifier):
        if any(isinstance(t, Linear) for t in out.terms):
            raise ConfigError("Linear terms need a weighted defuzzifier", path=f"{where}.defuzzifier")
        return
    kind = weighted_kind(out)
    for t in out.terms:
        if t.name not in used:
            continue
        if kind == "Tsukamoto" and not t.MONOTONIC:
            raise ConfigError(f"Tsukamoto output term '{t.name}' ({t.kind}) is not monotonic",
                              path=f"{where}.terms.{t.name}")
        if kind == "TakagiSugeno" and not isinstance(t, Constant | Linear):
            raise ConfigError(f"Takagi-Sugeno output term '{t.name}' must be Constant or Linear, "
                              f"not {t.kind}", path=f"{where}.terms.{t.name}")
        if isinstance(t, Linear) and len(t.params) not in (n_inputs, n_inputs + 1):
            raise ConfigError(f"Linear term '{t.name}' needs {n_inputs} or {n_inputs + 1} coefficients, "
                              f"got {len(t.params)}", path=f"{where}.terms.{t.name}")


def _check_type(engine: Engine) -> None:
    kind = engine.type
    if kind in (None, "Hybrid"):
        return
    integral = all(o.defuzzifier.INTEGRAL for o in engine.outputs)
    if kind in ("Mamdani", "Larsen") and not integral:
        raise ConfigError(f"a {kind} engine needs integral defuzzifiers (Centroid, ...) on every output",
                          path="outputs")
    if kind == "Larsen":
        for i, b in enumerate(engine.rule_blocks):
            if b.implication != "AlgebraicProduct":
                raise ConfigError(f"a Larsen engine uses AlgebraicProduct implication, not {b.implication}",
                                  path=f"rule_blocks[{i}].implication")
    if kind in ("Tsukamoto", "TakagiSugeno"):
        for o in engine.outputs:
            if not isinstance(o.defuzzifier, WeightedDefuzzifier) or weighted_kind(o) != kind:
                raise ConfigError(f"a {kind} engine needs {kind} weighted outputs; '{o.name}' is not one",
                                  path=f"outputs.{o.name}")
