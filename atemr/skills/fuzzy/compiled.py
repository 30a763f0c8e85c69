"""Engines compiled once into flat numpy arrays, so one evaluation is a short, fixed list of numpy operations.

`Engine` builds a `CompiledEngine` when it is created, and `Engine.process` runs it on the matrix of
inputs (inputs, rows). Every intermediate is laid out (terms/rules/..., rows), so reductions over terms run
along contiguous rows whatever N is. Nothing is looked up, validated or derived again per call:

* fuzzification: the (variable, term) pairs the rules use are the columns of one membership matrix.
  Ramp, Triangle and Trapezoid columns are computed all at once from parameters stacked per shape, with
  the formulas of `atemr.skills.fuzzy.terms` (same numbers, bit for bit); other shapes call their own
  `Term.membership`. Antecedent hedges are applied to the columns that need them, one chain at a time.
* antecedents: under a Minimum conjunction and a Maximum disjunction every antecedent equals the maximum
  over its clauses of the minimum over each clause's literals (its disjunctive normal form; exact, as
  min and max only select), so all rules are two padded gathers and two reductions. A rule whose block
  uses other operators (or whose normal form would be huge) is evaluated by its own tree, `Rule.degree`.
* consequents: the fired degrees are grouped per output term through index matrices (a ``max`` gather
  for a Maximum aggregation, a padded sum for none/UnboundedSum, the S-norm folded in a loop otherwise).
* defuzzification: a separable Larsen Centroid (the IDLE engine) is the degrees times each term's
  precomputed [area, moment], summed per output; Tsukamoto Ramp/Concave and Takagi-Sugeno Constant values
  of all terms are computed together and WeightedAverage/WeightedSum are sums per output. Every other
  output (Bisector, DiscreteCentroid, overlapping terms, other aggregations or weighted defuzzifiers,
  other Tsukamoto shapes, Linear terms) goes through the same code as the rule-by-rule path
  (`integrate`, `combine`, `Term.tsukamoto`, `Linear.evaluate`).

The plan computes what `Engine.process_columns_generic` (the rule-by-rule path) computes, with the same
floating-point operations in the same order wherever it matters, so the results are the same numbers
(`tests/skills/fuzzy/test_compiled.py` checks every engine we have).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from atemr.skills.fuzzy.defuzzifiers import (
    Centroid,
    IntegralDefuzzifier,
    WeightedAverage,
    WeightedDefuzzifier,
    WeightedSum,
)
from atemr.skills.fuzzy.discrete_centroid import DiscreteCentroid
from atemr.skills.fuzzy.norms import HEDGES, SNORMS, TNORMS, Hedge, Norm, maximum, unbounded_sum
from atemr.skills.fuzzy.rules import Expression, Operator, Proposition, Rule
from atemr.skills.fuzzy.separable import is_separable, separable_totals
from atemr.skills.fuzzy.terms import Concave, Constant, Linear, Ramp, Term, Trapezoid, Triangle

if TYPE_CHECKING:
    from atemr.skills.fuzzy.engine import Engine, OutputVariable

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]
Index = NDArray[np.intp]

#: fuzzylite's tolerance: a degree closer than this to 0 is 0 (the rule does not fire).
FIRING_EPSILON = 1e-6
#: Rows evaluated together by integral defuzzifiers (bounds memory at rows × resolution floats).
CHUNK_SAMPLES = 2_000_000
#: The rule stage runs on chunks of rows whose widest intermediate stays below this many floats (1 MB).
_CHUNK_FLOATS = 131_072
#: A rule whose disjunctive normal form has more clauses than this is evaluated by its tree instead.
_MAX_CLAUSES = 64


def integrate(
    defuzzifier: IntegralDefuzzifier,
    x: Array,
    items: Sequence[tuple[Array, Array, str | None]],
    n: int,
    agg: Norm,
    *,
    separable: bool | None = None,
) -> Array:
    """Crisp value per row of an integral output from (term sampled at ``x``, degree per row, implication)
    items aggregated with ``agg``; ``separable`` is `is_separable` of the items when the caller knows it."""
    if isinstance(defuzzifier, DiscreteCentroid):
        return defuzzifier.defuzzify_terms(x, items, n)
    if type(defuzzifier) is Centroid and agg is maximum and items:
        m = np.stack([i[0] for i in items])
        implications = [i[2] for i in items]
        if separable is None:
            separable = is_separable(m, implications)
        if separable:
            totals = separable_totals(m, np.stack([i[1] for i in items], axis=1), implications,
                                      np.stack([np.ones_like(x), x], axis=1))
            with np.errstate(divide="ignore", invalid="ignore"):
                return totals[:, 1] / totals[:, 0]
    crisp = np.full(n, np.nan)
    chunk = max(1, CHUNK_SAMPLES // max(1, len(x)))
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        y = np.zeros((stop - start, len(x)))
        for m_t, d, imp in items:
            implied = TNORMS.get(imp)(d[start:stop, None], m_t[None, :]) if imp else m_t[None, :]
            y = agg(y, implied)
        crisp[start:stop] = defuzzifier.reduce(x, y)
    return crisp


def weighted_kind(out: OutputVariable) -> str:
    """'TakagiSugeno' or 'Tsukamoto' for an output with a weighted defuzzifier (Automatic is inferred)."""
    d = out.defuzzifier
    assert isinstance(d, WeightedDefuzzifier)
    if d.type != "Automatic":
        return d.type
    if all(isinstance(t, Constant | Linear) for t in out.terms):
        return "TakagiSugeno"
    return "Tsukamoto"


def _padded(rows: Sequence[Sequence[int]], pad: int | None = None) -> Index:
    """Index matrix of ragged rows: short rows repeat their first index (for min and max, which are
    idempotent) or take ``pad`` (a neutral column, for sums)."""
    width = max(len(r) for r in rows)
    out = np.empty((len(rows), width), dtype=np.intp)
    for i, r in enumerate(rows):
        fill = r[0] if pad is None else pad
        out[i] = [*r, *([fill] * (width - len(r)))]
    return out


def _col(values: Sequence[float] | Array) -> Array:
    """A column vector: one parameter per term, broadcast along the rows."""
    return np.asarray(values, dtype=np.float64)[:, None]


# ---- fuzzification ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Shape:
    """Memberships of the terms of one shape: the input of each and the stacked parameters."""

    kind: str  # "Ramp", "Triangle", "Trapezoid" or "other" (each term's own membership)
    variables: Index
    terms: tuple[Term, ...]
    params: tuple[Array, ...] = ()
    heights: Array | None = None  # None: every height is 1

    def evaluate(self, x: Array) -> Array:
        """Memberships (terms, rows) for the inputs ``x`` (inputs, rows); call under errstate."""
        if self.kind == "other":
            return np.stack([t.membership(x[v]) for t, v in zip(self.terms, self.variables, strict=True)])
        v = x[self.variables]
        if self.kind == "Ramp":
            # Ramp's select is (x - s)/(e - s) clipped to [0, 1] for rising and falling ramps alike: the
            # falling formula (s - x)/(s - e) flips both signs, which IEEE rounding does not notice. (Exactly
            # at a falling ramp's start this gives -0.0 instead of 0.0; it fires nothing either way.)
            s, width = self.params
            mu = np.minimum(np.maximum((v - s) / width, 0.0), 1.0)
        elif self.kind == "Triangle":
            a, b, c, ba, cb, a_inf, c_inf = self.params
            rise = np.where(a_inf, 1.0, (v - a) / ba)
            fall = np.where(c_inf, 1.0, (c - v) / cb)
            mu = np.where((v < a) | (v > c), 0.0, np.where(v == b, 1.0, np.where(v < b, rise, fall)))
        else:
            a, b, c, d, ba, dc, a_inf, d_inf = self.params
            rise = np.where(a_inf, 1.0, (v - a) / ba)
            fall = np.where(d_inf, 1.0, (d - v) / dc)
            tail = np.where(d_inf, 1.0, 0.0)
            mu = np.where((v < a) | (v > d), 0.0,
                          np.where(v < b, rise, np.where(v <= c, 1.0, np.where(v < d, fall, tail))))
        if self.heights is not None:
            mu = self.heights * mu
        if self.kind != "Ramp":  # a Ramp with finite ends is NaN at NaN already
            mu = np.where(np.isnan(v), np.nan, mu)
        return mu


def _shape_kind(term: Term) -> str:
    kind = type(term)
    if kind is Ramp and all(math.isfinite(p) for p in term.params):
        return "Ramp"
    if kind is Triangle or kind is Trapezoid:
        return kind.__name__
    return "other"


def _shape(kind: str, pairs: Sequence[tuple[int, Term]]) -> _Shape:
    variables = np.array([v for v, _ in pairs], dtype=np.intp)
    terms = tuple(t for _, t in pairs)
    if kind == "other":
        return _Shape(kind, variables, terms)
    heights = np.array([t.height for t in terms])
    p = np.array([t.params for t in terms], dtype=np.float64).T
    if kind == "Ramp":
        s, e = p
        params: tuple[Array, ...] = (_col(s), _col(e - s))
    elif kind == "Triangle":
        a, b, c = p
        params = (_col(a), _col(b), _col(c), _col(b - a), _col(c - b), (a == -math.inf)[:, None],
                  (c == math.inf)[:, None])
    else:
        a, b, c, d = p
        params = (_col(a), _col(b), _col(c), _col(d), _col(b - a), _col(d - c), (a == -math.inf)[:, None],
                  (d == math.inf)[:, None])
    return _Shape(kind, variables, terms, params, None if np.all(heights == 1.0) else _col(heights))


# ---- antecedents ------------------------------------------------------------------------------------

Literal = tuple[str, str, tuple[str, ...]]  # variable, term, hedges


def _dnf(e: Expression) -> list[list[Literal]]:
    """Clauses whose max of mins equals the expression when 'and' is min and 'or' is max."""
    if isinstance(e, Proposition):
        return [[(e.variable, e.term, e.hedges)]]
    assert isinstance(e, Operator)
    left, right = _dnf(e.left), _dnf(e.right)
    if e.kind == "or":
        return left + right
    return [list(dict.fromkeys(a + b)) for a, b in itertools.product(left, right)]


def _clause_count(e: Expression) -> int:
    if isinstance(e, Proposition):
        return 1
    assert isinstance(e, Operator)
    left, right = _clause_count(e.left), _clause_count(e.right)
    return left + right if e.kind == "or" else left * right


def _propositions(e: Expression) -> list[Proposition]:
    if isinstance(e, Proposition):
        return [e]
    assert isinstance(e, Operator)
    return _propositions(e.left) + _propositions(e.right)


def _lattice(rule: Rule, conjunction: str | None, disjunction: str | None) -> bool:
    """Whether the rule's operators are min/max (or unused): then its normal form gives its degree exactly."""
    return ((not rule.uses("and") or conjunction == "Minimum")
            and (not rule.uses("or") or disjunction == "Maximum")
            and _clause_count(rule.antecedent) <= _MAX_CLAUSES)


# ---- outputs ----------------------------------------------------------------------------------------

@dataclass
class _Item:
    """One (output, term[, implication]) of grouped degree: its sources grouped by ``group``."""

    output: int
    term: Term
    implication: str | None
    group: str  # "max" (also any single source), "sum", or "fold" (with ``fold``)
    fold: Norm | None = None
    sources: list[int] = field(default_factory=list)  # columns of the source matrix
    rules: list[int] = field(default_factory=list)  # the rule of each source


@dataclass(frozen=True)
class _Values:
    """The value z of weighted items from their degrees w, for all items at once."""

    ramp: tuple[Mask, Array, Array, Array | None] | None  # mask, s, e - s, height (None: all 1)
    concave: tuple[Mask, Array, Array, Array] | None  # mask, h·(i - e), 2e, i
    constant: tuple[Mask, Array] | None  # mask, value
    tsukamoto: tuple[tuple[int, Term], ...]  # other monotonic terms: their own inverse
    linear: tuple[tuple[int, Linear], ...]

    def evaluate(self, w: Array, x: Array) -> Array:
        """z (items, rows) from w (items, rows) and the inputs x (inputs, rows); call under errstate
        (Tsukamoto values where w is 0 are inf or NaN, and the caller masks them)."""
        z: Array | None = None
        if self.ramp is not None:  # Ramp.tsukamoto: s + (e - s)·y / h
            mask, s, width, h = self.ramp
            z = s + width * w / h if h is not None else s + width * w
        if self.concave is not None:  # Concave.tsukamoto: h·(i - e) / y + 2e - i
            mask, hie, e2, i = self.concave
            values = hie / w + e2 - i
            z = values if z is None else np.where(mask, values, z)
        if self.constant is not None:
            mask, value = self.constant
            z = np.broadcast_to(value, w.shape) if z is None else np.where(mask, value, z)
        if z is None or self.tsukamoto or self.linear:
            z = np.zeros_like(w) if z is None else np.array(z)
            for j, term in self.tsukamoto:
                z[j] = term.tsukamoto(w[j])
            if self.linear:
                matrix = np.ascontiguousarray(x.T)  # (rows, inputs), as Linear.evaluate takes it
                for j, lin in self.linear:
                    z[j] = lin.evaluate(matrix)
        return z


def _values(items: Sequence[_Item], tsukamoto: Sequence[bool]) -> _Values:
    n = len(items)
    ramp, concave, constant = np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, bool)
    rs, rw, rh = np.zeros(n), np.zeros(n), np.ones(n)
    hie, e2, ci = np.zeros(n), np.zeros(n), np.zeros(n)
    value = np.zeros(n)
    others: list[tuple[int, Term]] = []
    linear: list[tuple[int, Linear]] = []
    for j, (item, tsu) in enumerate(zip(items, tsukamoto, strict=True)):
        t = item.term
        if tsu and type(t) is Ramp:
            ramp[j] = True
            rs[j], rw[j], rh[j] = t.params[0], t.params[1] - t.params[0], t.height
        elif tsu and type(t) is Concave:
            concave[j] = True
            hie[j], e2[j], ci[j] = t.height * (t.params[0] - t.params[1]), 2.0 * t.params[1], t.params[0]
        elif tsu:
            others.append((j, t))
        elif isinstance(t, Linear):
            linear.append((j, t))
        else:  # a Takagi-Sugeno Constant (validated): its membership of any degree, height·k
            constant[j] = True
            value[j] = t.height * t.params[0]
    return _Values(
        (ramp[:, None], _col(rs), _col(rw), None if np.all(rh == 1.0) else _col(rh)) if ramp.any() else None,
        (concave[:, None], _col(hie), _col(e2), _col(ci)) if concave.any() else None,
        (constant[:, None], _col(value)) if constant.any() else None,
        tuple(others),
        tuple(linear),
    )


@dataclass(frozen=True)
class _Segments:
    """Consecutive ranges of the items of each output, to sum per output along an axis."""

    bounds: tuple[tuple[int, int], ...]

    def sums(self, v: Array, axis: int) -> Array:
        """Sums per output along ``axis`` (0 or 1) of ``v``: the same additions in the same order as
        ``v[a:b].sum(axis=0)`` (or ``v[:, a:b].sum(axis=1)``) for each output, whatever the number of rows."""
        lengths = {b - a for a, b in self.bounds}
        if len(lengths) == 1:  # equal lengths: one reshape
            shape = (*v.shape[:axis], len(self.bounds), lengths.pop(), *v.shape[axis + 1:])
            return v.reshape(shape).sum(axis=axis + 1)
        if axis == 0:
            return np.stack([v[a:b].sum(axis=0) for a, b in self.bounds])
        return np.stack([v[:, a:b].sum(axis=1) for a, b in self.bounds], axis=1)


@dataclass(frozen=True)
class _Other:
    """An output evaluated by the generic code from its items' degree columns ``first:first + count``."""

    first: int
    count: int
    output: OutputVariable
    grid: Array | None = None  # integral: samples and each item's (sampled term, implication)
    spec: tuple[tuple[Array, str | None], ...] = ()
    agg: Norm = maximum
    separable: bool | None = None
    values: _Values | None = None  # weighted: the items' values
    tsukamoto: bool = False

    def evaluate(self, w_all: Array, present: Mask, x: Array) -> Array:
        """The crisp values (rows,) from the grouped degrees and presence of all items (items, rows)."""
        n = w_all.shape[1]
        w = w_all[self.first: self.first + self.count]
        d = self.output.defuzzifier
        if isinstance(d, IntegralDefuzzifier):
            assert self.grid is not None
            items = [(m, w[k], imp) for k, (m, imp) in enumerate(self.spec)]
            return integrate(d, self.grid, items, n, self.agg, separable=self.separable)
        assert isinstance(d, WeightedDefuzzifier) and self.values is not None
        p = present[self.first: self.first + self.count]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            z = self.values.evaluate(w, x)
            if self.tsukamoto:
                z = np.where(p, z, 0.0)
        return d.combine(np.ascontiguousarray(w.T), np.ascontiguousarray(z.T), np.ascontiguousarray(p.T))


class CompiledEngine:
    """The evaluation plan of one engine (see the module docstring); `evaluate` runs it."""

    def __init__(self, engine: Engine, grids: dict[str, tuple[Array, dict[str, Array]]]) -> None:
        inputs, outputs = engine.inputs, engine.outputs
        self.input_names = tuple(v.name for v in inputs)
        self.input_set = frozenset(self.input_names)
        var_index = {v.name: i for i, v in enumerate(inputs)}
        self.in_range: tuple[Array, Array] | None = None  # clip bounds, ±inf for inputs not locked
        if any(v.lock_range for v in inputs):
            self.in_range = (_col([v.minimum if v.lock_range else -math.inf for v in inputs]),
                             _col([v.maximum if v.lock_range else math.inf for v in inputs]))

        # -- antecedents: normal forms of the min/max rules, trees for the others
        rules = [(b, r) for b in engine.rule_blocks for r in b.rules]
        self.n_rules = len(rules)
        dnf: list[tuple[int, list[list[Literal]]]] = []
        self.tree_rules: list[tuple[int, Rule, Norm | None, Norm | None]] = []
        literals: dict[Literal, None] = {}
        for r, (block, rule) in enumerate(rules):
            if _lattice(rule, block.conjunction, block.disjunction):
                clauses = _dnf(rule.antecedent)
                dnf.append((r, clauses))
                literals.update((lit, None) for clause in clauses for lit in clause)
            else:
                self.tree_rules.append((r, rule, TNORMS.get(block.conjunction) if block.conjunction else None,
                                        SNORMS.get(block.disjunction) if block.disjunction else None))
                literals.update(((p.variable, p.term, ()), None) for p in _propositions(rule.antecedent))
        # membership columns: every used (variable, term), grouped by shape, then the hedged literals
        pairs = list(dict.fromkeys((v, t) for v, t, _ in literals))
        by_kind: dict[str, list[tuple[str, str]]] = {}
        for v, t in pairs:
            by_kind.setdefault(_shape_kind(inputs[var_index[v]].term(t)), []).append((v, t))
        self.shapes: list[_Shape] = []
        self.base_col: dict[tuple[str, str], int] = {}
        for kind in ("Ramp", "Triangle", "Trapezoid", "other"):
            if kind in by_kind:
                terms = [(var_index[v], inputs[var_index[v]].term(t)) for v, t in by_kind[kind]]
                self.shapes.append(_shape(kind, terms))
                self.base_col.update((key, len(self.base_col)) for key in by_kind[kind])
        column: dict[Literal, int] = {(v, t, ()): c for (v, t), c in self.base_col.items()}
        chains: dict[tuple[str, ...], list[tuple[str, str]]] = {}
        for v, t, hedges in literals:
            if hedges:
                chains.setdefault(hedges, []).append((v, t))
        self.hedged: list[tuple[Index, tuple[Hedge, ...]]] = []
        for hedges, keys in chains.items():
            self.hedged.append((np.array([self.base_col[k] for k in keys], dtype=np.intp),
                                tuple(HEDGES.get(h) for h in reversed(hedges))))
            column.update(((*k, hedges), len(column)) for k in keys)
        self.n_literals = len(column)
        clause_rows = [[column[lit] for lit in clause] for _, clauses in dnf for clause in clauses]
        self.clause_index = _padded(clause_rows) if clause_rows else None
        self.rule_index: Index | None = None
        if any(len(clauses) > 1 for _, clauses in dnf):
            starts = list(itertools.accumulate((len(c) for _, c in dnf), initial=0))
            self.rule_index = _padded([list(range(starts[k], starts[k + 1])) for k in range(len(dnf))])
        self.dnf_columns = np.array([r for r, _ in dnf], dtype=np.intp)
        weights = np.array([rules[r][1].weight for r, _ in dnf])
        self.weights = _col(weights) if np.any(weights != 1.0) else None

        # -- consequents: source columns are the rule degrees, then the hedged consequents by hedge chain
        hedged_props: dict[tuple[str, ...], list[tuple[int, int]]] = {}
        for r, (_, rule) in enumerate(rules):
            for k, prop in enumerate(rule.consequents):
                if prop.hedges:
                    hedged_props.setdefault(prop.hedges, []).append((r, k))
        source: dict[tuple[int, int], int] = {}
        self.consequent_hedges: list[tuple[Index, tuple[Hedge, ...]]] = []
        for hedges, props in hedged_props.items():
            source.update((rk, self.n_rules + len(source)) for rk in props)
            self.consequent_hedges.append((np.array([r for r, _ in props], dtype=np.intp),
                                           tuple(HEDGES.get(h) for h in reversed(hedges))))
        self.n_sources = self.n_rules + len(source)

        # -- items, by output: separable Larsen Centroids, WeightedAverage/Sum, the rest, outputs without rules
        out_items: list[list[_Item]] = []
        for oi, out in enumerate(outputs):
            items: dict[object, _Item] = {}
            integral = isinstance(out.defuzzifier, IntegralDefuzzifier)
            norm = SNORMS.get(out.aggregation) if out.aggregation else (maximum if integral else unbounded_sum)
            count = 0
            for r, (block, rule) in enumerate(rules):
                for k, prop in enumerate(rule.consequents):
                    if prop.variable != out.name:
                        continue
                    term = out.term(prop.term)
                    if integral:  # fuzzylite's Maximum aggregation commutes with grouping by (term, implication)
                        key: object = (term.name, block.implication) if norm is maximum else count
                        group = "max"
                    else:
                        key = term.name
                        group = "max" if norm is maximum else "sum" if norm is unbounded_sum else "fold"
                    item = items.setdefault(key, _Item(oi, term, block.implication if integral else None, group, norm))
                    item.sources.append(source.get((r, k), r))
                    item.rules.append(r)
                    count += 1
            for item in items.values():
                if len(item.sources) == 1:
                    item.group = "max"
            out_items.append(list(items.values()))
        lin, weighted, other, empty = [], [], [], []
        for oi, out in enumerate(outputs):
            d = out.defuzzifier
            if not out_items[oi]:
                empty.append(oi)
            elif type(d) in (WeightedAverage, WeightedSum):
                weighted.append(oi)
            elif type(d) is Centroid and out.aggregation in (None, "Maximum") \
                    and all(it.implication == "AlgebraicProduct" for it in out_items[oi]) \
                    and is_separable(np.stack([grids[out.name][1][it.term.name] for it in out_items[oi]]),
                                     [it.implication for it in out_items[oi]]):
                lin.append(oi)
            else:
                other.append(oi)
        order = [*lin, *weighted, *other, *empty]
        #: position of each output's column in the result of `evaluate`
        self.position = {outputs[oi].name: p for p, oi in enumerate(order)}
        #: (name, position) of every output in declaration order
        self.outputs = tuple((o.name, self.position[o.name]) for o in outputs)
        self.items = [it for oi in order for it in out_items[oi]]
        counts = [len(out_items[oi]) for oi in order[: len(order) - len(empty)]]
        self.starts = np.array(list(itertools.accumulate(counts, initial=0))[:-1], dtype=np.intp)
        self.n_lin, self.n_empty = len(lin), len(empty)
        self.lin_items = sum(len(out_items[oi]) for oi in lin)
        self.weighted_items = sum(len(out_items[oi]) for oi in weighted)

        # grouped degrees of the items: a max gather, a padded sum, folds
        n_items = len(self.items)
        max_ids = [j for j, it in enumerate(self.items) if it.group == "max"]
        sum_ids = [j for j, it in enumerate(self.items) if it.group == "sum"]
        self.all_max = len(max_ids) == n_items > 0
        self.max_ids = np.array(max_ids, dtype=np.intp)
        self.max_index = _padded([self.items[j].sources for j in max_ids]) if max_ids else None
        self.sum_ids = np.array(sum_ids, dtype=np.intp)
        self.sum_index = _padded([self.items[j].sources for j in sum_ids], pad=self.n_sources) if sum_ids else None
        self.folds = [(j, it) for j, it in enumerate(self.items) if it.group == "fold"]
        # an item is present when one of its rules fired. Unhedged fired degrees are 0 or >= FIRING_EPSILON,
        # and so are their max and sum: then it is present when its degree is >= FIRING_EPSILON
        self.present_from_degree = not self.folds and all(s < self.n_rules for it in self.items for s in it.sources)
        self.present_index = _padded([it.rules for it in self.items]) if self.items else None

        # separable Larsen Centroids: [area, moment] of output o = Σ over its items of degree × [area, moment]
        # of the item's term, summed in item order as `separable_totals` does
        self.lin_table = np.zeros((self.lin_items, 2, 1))
        bounds = list(itertools.pairwise([*self.starts.tolist(), self.lin_items + self.weighted_items]))
        self.lin_segments = _Segments(tuple(bounds[: len(lin)]))
        j = 0
        for oi in lin:
            x, mu = grids[outputs[oi].name]
            weights_x = np.stack([np.ones_like(x), x], axis=1)
            for it in out_items[oi]:
                self.lin_table[j, :, 0] = mu[it.term.name] @ weights_x
                j += 1
        # WeightedAverage/WeightedSum outputs: every item's value, segment starts, which outputs average
        w_items = self.items[self.lin_items: self.lin_items + self.weighted_items]
        tsu = {oi: weighted_kind(outputs[oi]) == "Tsukamoto" for oi in weighted}
        self.values = _values(w_items, [tsu[it.output] for it in w_items]) if weighted else None
        self.w_segments = _Segments(tuple((a - self.lin_items, b - self.lin_items)
                                          for a, b in bounds[len(lin): len(lin) + len(weighted)]))
        average = [type(outputs[oi].defuzzifier) is WeightedAverage for oi in weighted]
        self.w_average: bool | Mask = all(average) if all(average) or not any(average) else _col(average) > 0
        # the rest: the generic code on the items' degree columns
        self.others: list[_Other] = []
        j = self.lin_items + self.weighted_items
        for oi in other:
            out, its = outputs[oi], out_items[oi]
            if isinstance(out.defuzzifier, IntegralDefuzzifier):
                grid, mu = grids[out.name]
                m = np.stack([mu[it.term.name] for it in its])
                imps = [it.implication for it in its]
                agg = SNORMS.get(out.aggregation) if out.aggregation else maximum
                self.others.append(_Other(j, len(its), out, grid, tuple((mu[it.term.name], it.implication)
                                                                         for it in its), agg,
                                          is_separable(m, imps) if agg is maximum else None))
            else:
                is_tsu = weighted_kind(out) == "Tsukamoto"
                self.others.append(_Other(j, len(its), out, values=_values(its, [is_tsu] * len(its)),
                                          tsukamoto=is_tsu))
            j += len(its)

        ordered = [outputs[oi] for oi in order]
        self.defaults = _col([o.default for o in ordered])
        self.out_range: tuple[Array, Array] | None = None
        if any(o.lock_range for o in ordered):
            self.out_range = (_col([o.minimum if o.lock_range else -math.inf for o in ordered]),
                              _col([o.maximum if o.lock_range else math.inf for o in ordered]))
        widths = [len(inputs), self.n_literals, self.n_sources + 1, n_items + len(outputs), 2 * len(lin)]
        widths += [index.size for index in (self.clause_index, self.rule_index, self.max_index, self.sum_index,
                                            self.present_index) if index is not None]
        self.chunk_rows = max(64, _CHUNK_FLOATS // max(widths))

    # ---- evaluation ---------------------------------------------------------------------------------

    def evaluate(self, x: Array) -> Array:
        """Crisp outputs (outputs in `position` order, rows) for the inputs ``x`` (inputs, rows)."""
        n = x.shape[1]
        if self.in_range is not None:
            x = np.minimum(np.maximum(x, self.in_range[0]), self.in_range[1])
        if n <= self.chunk_rows:
            w, present = self._rules(x)
        else:  # the rule stage in chunks that stay in cache; the items are few, defuzzify them all at once
            parts = [self._rules(x[:, s: s + self.chunk_rows]) for s in range(0, n, self.chunk_rows)]
            w = np.concatenate([part[0] for part in parts], axis=1)
            present = np.concatenate([part[1] for part in parts], axis=1)
        return self._defuzzify(w, present, x)

    def _rules(self, x: Array) -> tuple[Array, Mask]:
        """Grouped degree and presence of every item (items, rows) for the (clipped) inputs."""
        deg = self._degrees(self._memberships(x))
        fired = deg >= FIRING_EPSILON
        return self._grouped(np.where(fired, deg, 0.0), fired)

    def _defuzzify(self, w: Array, present: Mask, x: Array) -> Array:
        n = x.shape[1]
        crisp: list[Array] = []
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            if self.n_lin:  # [area, moment] per output, summed over its items in order
                totals = self.lin_segments.sums(w[: self.lin_items, None, :] * self.lin_table, axis=0)
                crisp.append(totals[:, 1] / totals[:, 0])
            if self.values is not None:
                a, b = self.lin_items, self.lin_items + self.weighted_items
                ww, p = w[a:b], present[a:b]
                # as WeightedAverage/WeightedSum.combine: rows of (w·z where present) summed per output
                terms = np.ascontiguousarray(np.where(p, ww * self.values.evaluate(ww, x), 0.0).T)
                num = self.w_segments.sums(terms, axis=1).T
                if self.w_average is False:
                    crisp.append(num)
                else:
                    ratio = num / self.w_segments.sums(np.ascontiguousarray(np.where(p, ww, 0.0).T), axis=1).T
                    crisp.append(ratio if self.w_average is True else np.where(self.w_average, ratio, num))
        crisp.extend(other.evaluate(w, present, x)[None, :] for other in self.others)
        if self.n_empty:
            crisp.append(np.full((self.n_empty, n), np.nan))
        result = crisp[0] if len(crisp) == 1 else np.concatenate(crisp)
        fired_any = np.logical_or.reduceat(present, self.starts) if self.starts.size else np.zeros((0, n), bool)
        if self.n_empty:
            fired_any = np.concatenate([fired_any, np.zeros((self.n_empty, n), dtype=bool)])
        result = np.where(fired_any, result, self.defaults)
        if self.out_range is not None:
            result = np.minimum(np.maximum(result, self.out_range[0]), self.out_range[1])
        return result

    def _memberships(self, x: Array) -> Array:
        """Literal rows: the base memberships, then the hedged ones."""
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # as in Term.membership
            blocks = [s.evaluate(x) for s in self.shapes]
        if not blocks:
            return np.zeros((0, x.shape[1]))
        mu = blocks[0] if len(blocks) == 1 else np.concatenate(blocks)
        if not self.hedged:
            return mu
        parts = [mu]
        for rows, hedges in self.hedged:
            h = mu[rows]
            for hedge in hedges:
                h = hedge(h)
            parts.append(h)
        return np.concatenate(parts)

    def _degrees(self, lits: Array) -> Array:
        """Activation degree (weight × antecedent) of every rule (rules, rows)."""
        n = lits.shape[1]
        deg = np.zeros((0, n))
        if self.clause_index is not None:
            deg = lits[self.clause_index].min(axis=1)
            if self.rule_index is not None:
                deg = deg[self.rule_index].max(axis=1)
            if self.weights is not None:
                deg = self.weights * deg
        if not self.tree_rules:
            return deg
        full = np.empty((self.n_rules, n))
        full[self.dnf_columns] = deg
        membership = self._base_lookup(lits)
        for r, rule, conj, disj in self.tree_rules:
            full[r] = rule.degree(membership, conj, disj)
        return full

    def _base_lookup(self, lits: Array) -> Callable[[str, str], Array]:
        base = self.base_col

        def membership(variable: str, term: str) -> Array:
            return lits[base[(variable, term)]]

        return membership

    def _grouped(self, deg: Array, fired: Mask) -> tuple[Array, Mask]:
        """Grouped degree of every item and whether it is present (one of its rules fired): (items, rows)."""
        n = deg.shape[1]
        src = deg
        if self.consequent_hedges:
            parts = [deg]
            for rs, hedges in self.consequent_hedges:
                d, f = deg[rs], fired[rs]
                for hedge in hedges:
                    d = np.where(f, hedge(d), 0.0)
                parts.append(d)
            src = np.concatenate(parts)
        if self.sum_index is not None:
            src = np.concatenate([src, np.zeros((1, n))])
        if self.all_max:
            assert self.max_index is not None
            w = src[self.max_index].max(axis=1)
        else:
            w = np.empty((len(self.items), n))
            if self.max_index is not None:
                w[self.max_ids] = src[self.max_index].max(axis=1)
            if self.sum_index is not None:
                # as the rule-by-rule path folds them: ((d1 + d2) + d3) ..., padded with + 0
                w[self.sum_ids] = src[self.sum_index].sum(axis=1)
            for j, item in self.folds:
                assert item.fold is not None
                acc = src[item.sources[0]]
                for s in item.sources[1:]:
                    acc = item.fold(acc, src[s])
                w[j] = acc
        if self.present_from_degree:
            return w, np.greater_equal(w, FIRING_EPSILON)
        if self.present_index is None:
            return w, np.zeros((0, n), dtype=bool)
        present: Mask = np.any(fired[self.present_index], axis=1)
        return w, present
