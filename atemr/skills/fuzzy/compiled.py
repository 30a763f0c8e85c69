"""Engines compiled once into flat numpy arrays, so one evaluation is a short, fixed list of numpy operations.

`Engine` builds a `CompiledEngine` with `compile_engine` when it is created, and `Engine.process` runs it on
the matrix of inputs (inputs, rows). Every intermediate is laid out (terms/rules/..., rows), so reductions over
terms run along contiguous rows whatever N is. Nothing is looked up, validated or derived again per call. The
plan is four frozen stages, each built by its own function and run by its own method, in this order:

* fuzzification (`_Fuzzification`): the (variable, term) pairs the rules use are the columns of one
  membership matrix. Ramp, Triangle and Trapezoid columns are computed all at once from parameters stacked
  per shape, with the formulas of `atemr.skills.fuzzy.terms` (same numbers, bit for bit); other shapes call
  their own `Term.membership`. Antecedent hedges are applied to the columns that need them, one chain at a
  time.
* antecedents (`_Antecedents`): under a Minimum conjunction and a Maximum disjunction every antecedent
  equals the maximum over its clauses of the minimum over each clause's literals (its disjunctive normal
  form; exact, as min and max only select), so all rules are two padded gathers and two reductions. A rule
  whose block uses other operators (or whose normal form would be huge) is evaluated by its own tree,
  `Rule.degree`.
* consequents (`_Grouping`): the fired degrees are grouped per output term through index matrices (a ``max``
  gather for a Maximum aggregation, a padded sum for none/UnboundedSum, the S-norm folded in a loop
  otherwise).
* defuzzification (`_Defuzzification`): a separable Larsen Centroid (the IDLE engine) is the degrees times
  each term's precomputed [area, moment], summed per output; Tsukamoto Ramp/Concave and Takagi-Sugeno
  Constant values of all terms are computed together and WeightedAverage/WeightedSum are sums per output.
  Every other output (Bisector, DiscreteCentroid, overlapping terms, other aggregations or weighted
  defuzzifiers, other Tsukamoto shapes, Linear terms) goes through the same code as the rule-by-rule path
  (`integrate`, `combine`, `Term.tsukamoto`, `Linear.evaluate`).

The plan computes what `Engine.process_columns_generic` (the rule-by-rule path) computes, with the same
floating-point operations in the same order wherever it matters, so the results are the same numbers
(`tests/skills/fuzzy/test_compiled.py` checks every engine we have).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
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
    from atemr.skills.fuzzy.engine import Engine, InputVariable, OutputVariable, RuleBlock

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]
Index = NDArray[np.intp]
#: Each integral output's samples and its terms' memberships there, by output and term name.
Grids = dict[str, tuple[Array, dict[str, Array]]]
Literal = tuple[str, str, tuple[str, ...]]  # variable, term, hedges

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

@dataclass(frozen=True)
class _Fuzzification:
    """The literal rows: every (variable, term) the rules use as one column, computed shape by shape, then the
    hedged literals, one hedge chain at a time over the columns it applies to."""

    shapes: tuple[_Shape, ...]
    hedged: tuple[tuple[Index, tuple[Hedge, ...]], ...]
    #: The column of each unhedged (variable, term): what rules evaluated by their tree read.
    base_col: dict[tuple[str, str], int]
    #: The column of every literal, hedged or not.
    column: dict[Literal, int]

    def memberships(self, x: Array) -> Array:
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


def _fuzzification(inputs: Sequence[InputVariable], literals: Iterable[Literal]) -> _Fuzzification:
    """Columns for ``literals`` (in order): shapes in the order Ramp, Triangle, Trapezoid, other, each holding
    its (variable, term) pairs in the order of first use; then each hedge chain's literals."""
    var_index = {v.name: i for i, v in enumerate(inputs)}
    literals = list(literals)
    by_kind: dict[str, list[tuple[str, str]]] = {}
    for v, t in dict.fromkeys((v, t) for v, t, _ in literals):
        by_kind.setdefault(_shape_kind(inputs[var_index[v]].term(t)), []).append((v, t))
    shapes: list[_Shape] = []
    base_col: dict[tuple[str, str], int] = {}
    for kind in ("Ramp", "Triangle", "Trapezoid", "other"):
        if kind in by_kind:
            shapes.append(_shape(kind, [(var_index[v], inputs[var_index[v]].term(t)) for v, t in by_kind[kind]]))
            base_col.update((key, len(base_col)) for key in by_kind[kind])
    column: dict[Literal, int] = {(v, t, ()): c for (v, t), c in base_col.items()}
    chains: dict[tuple[str, ...], list[tuple[str, str]]] = {}
    for v, t, hedges in literals:
        if hedges:
            chains.setdefault(hedges, []).append((v, t))
    hedged: list[tuple[Index, tuple[Hedge, ...]]] = []
    for hedges, keys in chains.items():
        hedged.append((np.array([base_col[k] for k in keys], dtype=np.intp),
                       tuple(HEDGES.get(h) for h in reversed(hedges))))
        column.update(((*k, hedges), len(column)) for k in keys)
    return _Fuzzification(tuple(shapes), tuple(hedged), base_col, column)


# ---- antecedents ------------------------------------------------------------------------------------


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

Rules = Sequence[tuple["RuleBlock", Rule]]
#: A rule evaluated by its own tree: its number, the rule, its block's conjunction and disjunction.
TreeRule = tuple[int, Rule, Norm | None, Norm | None]


def _split_rules(rules: Rules) -> tuple[list[tuple[int, list[list[Literal]]]], list[TreeRule], list[Literal]]:
    """The min/max rules' normal forms (rule number, clauses), the other rules, and every literal the rules use
    in the order of first use (a tree rule's literals unhedged: its tree applies the hedges)."""
    dnf: list[tuple[int, list[list[Literal]]]] = []
    tree_rules: list[TreeRule] = []
    literals: dict[Literal, None] = {}
    for r, (block, rule) in enumerate(rules):
        if _lattice(rule, block.conjunction, block.disjunction):
            clauses = _dnf(rule.antecedent)
            dnf.append((r, clauses))
            literals.update((lit, None) for clause in clauses for lit in clause)
        else:
            tree_rules.append((r, rule, TNORMS.get(block.conjunction) if block.conjunction else None,
                               SNORMS.get(block.disjunction) if block.disjunction else None))
            literals.update(((p.variable, p.term, ()), None) for p in _propositions(rule.antecedent))
    return dnf, tree_rules, list(literals)


@dataclass(frozen=True)
class _Antecedents:
    """Activation degrees: the normal forms as two padded gathers (clauses, then rules) and two reductions,
    the rule weights, and the rules evaluated by their trees written into their rows."""

    n_rules: int
    clause_index: Index | None  # (clauses, literals per clause): columns of the literal rows
    rule_index: Index | None  # (rules, clauses per rule), None when every rule is one clause
    dnf_columns: Index  # the rule number of each normal-form row
    weights: Array | None  # None: every weight is 1
    tree_rules: tuple[TreeRule, ...]
    base_col: dict[tuple[str, str], int]

    def degrees(self, lits: Array) -> Array:
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


def _antecedents(rules: Rules, dnf: Sequence[tuple[int, list[list[Literal]]]], tree_rules: Sequence[TreeRule],
                 fuzz: _Fuzzification) -> _Antecedents:
    """The gathers of the normal forms ``dnf`` over the literal columns of ``fuzz``, and the tree rules."""
    clause_rows = [[fuzz.column[lit] for lit in clause] for _, clauses in dnf for clause in clauses]
    rule_index: Index | None = None
    if any(len(clauses) > 1 for _, clauses in dnf):
        starts = list(itertools.accumulate((len(c) for _, c in dnf), initial=0))
        rule_index = _padded([list(range(starts[k], starts[k + 1])) for k in range(len(dnf))])
    weights = np.array([rules[r][1].weight for r, _ in dnf])
    return _Antecedents(
        len(rules),
        _padded(clause_rows) if clause_rows else None,
        rule_index,
        np.array([r for r, _ in dnf], dtype=np.intp),
        _col(weights) if np.any(weights != 1.0) else None,
        tuple(tree_rules),
        fuzz.base_col,
    )


# ---- consequents ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Sources:
    """The columns items take their degrees from: the rule degrees, then the hedged consequents, grouped by
    hedge chain (each chain applied to its rules' degrees where they fired)."""

    n_rules: int
    #: The column of each hedged consequent (rule, consequent number); the others read their rule's column.
    column: dict[tuple[int, int], int]
    hedges: tuple[tuple[Index, tuple[Hedge, ...]], ...]

    @property
    def count(self) -> int:
        return self.n_rules + len(self.column)

    def of(self, r: int, k: int) -> int:
        """The source column of rule ``r``'s consequent ``k``."""
        return self.column.get((r, k), r)


def _sources(rules: Rules) -> _Sources:
    """One column per hedged consequent after the rule degrees, the consequents of one hedge chain together."""
    hedged_props: dict[tuple[str, ...], list[tuple[int, int]]] = {}
    for r, (_, rule) in enumerate(rules):
        for k, prop in enumerate(rule.consequents):
            if prop.hedges:
                hedged_props.setdefault(prop.hedges, []).append((r, k))
    column: dict[tuple[int, int], int] = {}
    hedges: list[tuple[Index, tuple[Hedge, ...]]] = []
    for chain, props in hedged_props.items():
        column.update((rk, len(rules) + len(column)) for rk in props)
        hedges.append((np.array([r for r, _ in props], dtype=np.intp), tuple(HEDGES.get(h) for h in reversed(chain))))
    return _Sources(len(rules), column, tuple(hedges))


@dataclass(frozen=True)
class _Item:
    """One (output, term[, implication]) of grouped degree: its sources grouped by ``group``."""

    output: int
    term: Term
    implication: str | None
    group: str  # "max" (also any single source), "sum", or "fold" (with ``fold``)
    fold: Norm | None
    sources: tuple[int, ...]  # columns of the source matrix
    rules: tuple[int, ...]  # the rule of each source


def _output_items(oi: int, out: OutputVariable, rules: Rules, sources: _Sources) -> tuple[_Item, ...]:
    """The items of output ``oi``, in the order of their first rule. An integral output under a Maximum
    aggregation has one per (term, implication) (fuzzylite's Maximum commutes with that grouping), under
    another one per consequent; a weighted output one per term, its degrees grouped by the aggregation."""
    integral = isinstance(out.defuzzifier, IntegralDefuzzifier)
    norm = SNORMS.get(out.aggregation) if out.aggregation else (maximum if integral else unbounded_sum)
    # an integral output's items group by max (one consequent each when the aggregation is not Maximum)
    group = "max" if integral or norm is maximum else "sum" if norm is unbounded_sum else "fold"
    found: dict[object, tuple[Term, str | None, list[int], list[int]]] = {}
    count = 0
    for r, (block, rule) in enumerate(rules):
        for k, prop in enumerate(rule.consequents):
            if prop.variable != out.name:
                continue
            term = out.term(prop.term)
            if integral:
                key: object = (term.name, block.implication) if norm is maximum else count
            else:
                key = term.name
            _, _, srcs, rs = found.setdefault(key, (term, block.implication if integral else None, [], []))
            srcs.append(sources.of(r, k))
            rs.append(r)
            count += 1
    return tuple(_Item(oi, term, imp, "max" if len(srcs) == 1 else group, norm, tuple(srcs), tuple(rs))
                 for term, imp, srcs, rs in found.values())


@dataclass(frozen=True)
class _Grouping:
    """The grouped degree of every item from the source columns: a ``max`` gather, a padded sum (the pad is a
    zero column), the S-norm folded in a loop; and whether each item is present (one of its rules fired)."""

    n_items: int
    hedges: tuple[tuple[Index, tuple[Hedge, ...]], ...]  # `_Sources.hedges`
    all_max: bool
    max_ids: Index
    max_index: Index | None
    sum_ids: Index
    sum_index: Index | None
    folds: tuple[tuple[int, _Item], ...]
    #: Unhedged fired degrees are 0 or >= FIRING_EPSILON, and so are their max and sum: then an item is present
    #: when its degree is >= FIRING_EPSILON, else when one of its rules (``present_index``) fired.
    present_from_degree: bool
    present_index: Index | None

    def grouped(self, deg: Array, fired: Mask) -> tuple[Array, Mask]:
        """Grouped degree of every item and whether it is present (one of its rules fired): (items, rows)."""
        n = deg.shape[1]
        src = deg
        if self.hedges:
            parts = [deg]
            for rs, hedges in self.hedges:
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
            w = np.empty((self.n_items, n))
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


def _grouping(items: Sequence[_Item], sources: _Sources) -> _Grouping:
    """The index matrices of ``items`` (in result order) over the source columns."""
    max_ids = [j for j, it in enumerate(items) if it.group == "max"]
    sum_ids = [j for j, it in enumerate(items) if it.group == "sum"]
    folds = tuple((j, it) for j, it in enumerate(items) if it.group == "fold")
    return _Grouping(
        len(items),
        sources.hedges,
        len(max_ids) == len(items) > 0,
        np.array(max_ids, dtype=np.intp),
        _padded([items[j].sources for j in max_ids]) if max_ids else None,
        np.array(sum_ids, dtype=np.intp),
        _padded([items[j].sources for j in sum_ids], pad=sources.count) if sum_ids else None,
        folds,
        not folds and all(s < sources.n_rules for it in items for s in it.sources),
        _padded([it.rules for it in items]) if items else None,
    )


# ---- outputs ----------------------------------------------------------------------------------------

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

@dataclass(frozen=True)
class _Layout:
    """Which path each output takes, as output numbers: separable Larsen Centroids, WeightedAverage/Sum, the
    generic code, and outputs no rule concludes on; its items and results are laid out in this order."""

    lin: tuple[int, ...]
    weighted: tuple[int, ...]
    other: tuple[int, ...]
    empty: tuple[int, ...]

    @property
    def order(self) -> tuple[int, ...]:
        return (*self.lin, *self.weighted, *self.other, *self.empty)


def _layout(outputs: Sequence[OutputVariable], out_items: Sequence[Sequence[_Item]],
            grids: Grids) -> _Layout:
    """The fastest exact path of each output: a Centroid under Maximum aggregation is separable only when every
    item's implication is AlgebraicProduct and its terms do not overlap (`is_separable`)."""
    lin: list[int] = []
    weighted: list[int] = []
    other: list[int] = []
    empty: list[int] = []
    for oi, out in enumerate(outputs):
        d, its = out.defuzzifier, out_items[oi]
        if not its:
            empty.append(oi)
        elif type(d) in (WeightedAverage, WeightedSum):
            weighted.append(oi)
        elif type(d) is Centroid and out.aggregation in (None, "Maximum") \
                and all(it.implication == "AlgebraicProduct" for it in its) \
                and is_separable(np.stack([grids[out.name][1][it.term.name] for it in its]),
                                 [it.implication for it in its]):
            lin.append(oi)
        else:
            other.append(oi)
    return _Layout(tuple(lin), tuple(weighted), tuple(other), tuple(empty))


@dataclass(frozen=True)
class _Defuzzification:
    """Crisp outputs from the items' grouped degrees and presence, outputs in `_Layout.order`: the separable
    Larsen Centroids as one product with each item's [area, moment], the WeightedAverage/Sum outputs from all
    their items' values at once, the rest by the generic code; then the default where nothing fired, and the
    locked ranges."""

    starts: Index  # the first item of each output that has items
    n_lin: int
    lin_items: int
    lin_table: Array  # (lin items, [area, moment], 1)
    lin_segments: _Segments
    weighted_items: int
    values: _Values | None  # the WeightedAverage/Sum items' values (None: no such output)
    w_segments: _Segments
    w_average: bool | Mask  # WeightedAverage (True), WeightedSum (False), or per output
    others: tuple[_Other, ...]
    n_empty: int
    defaults: Array
    out_range: tuple[Array, Array] | None

    def defuzzify(self, w: Array, present: Mask, x: Array) -> Array:
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


def _lin_table(outputs: Sequence[OutputVariable], out_items: Sequence[Sequence[_Item]], lin: Sequence[int],
               grids: Grids) -> Array:
    """[area, moment] of each item's term of the separable Larsen Centroids, as `separable_totals` sums them."""
    table = np.zeros((sum(len(out_items[oi]) for oi in lin), 2, 1))
    j = 0
    for oi in lin:
        x, mu = grids[outputs[oi].name]
        weights_x = np.stack([np.ones_like(x), x], axis=1)
        for it in out_items[oi]:
            table[j, :, 0] = mu[it.term.name] @ weights_x
            j += 1
    return table


def _others(outputs: Sequence[OutputVariable], out_items: Sequence[Sequence[_Item]], other: Sequence[int],
            first: int, grids: Grids) -> tuple[_Other, ...]:
    """The outputs the generic code evaluates, from their items' degree columns on from ``first``."""
    result: list[_Other] = []
    j = first
    for oi in other:
        out, its = outputs[oi], out_items[oi]
        if isinstance(out.defuzzifier, IntegralDefuzzifier):
            grid, mu = grids[out.name]
            m = np.stack([mu[it.term.name] for it in its])
            imps = [it.implication for it in its]
            agg = SNORMS.get(out.aggregation) if out.aggregation else maximum
            result.append(_Other(j, len(its), out, grid, tuple((mu[it.term.name], it.implication) for it in its),
                                 agg, is_separable(m, imps) if agg is maximum else None))
        else:
            is_tsu = weighted_kind(out) == "Tsukamoto"
            result.append(_Other(j, len(its), out, values=_values(its, [is_tsu] * len(its)), tsukamoto=is_tsu))
        j += len(its)
    return tuple(result)


def _defuzzification(outputs: Sequence[OutputVariable], out_items: Sequence[Sequence[_Item]], layout: _Layout,
                     grids: Grids) -> _Defuzzification:
    """Where each output's items are (starts, segments) and what each path precomputes, in ``layout`` order."""
    counts = [len(out_items[oi]) for oi in (*layout.lin, *layout.weighted, *layout.other)]
    starts = np.array(list(itertools.accumulate(counts, initial=0))[:-1], dtype=np.intp)
    lin_items = sum(len(out_items[oi]) for oi in layout.lin)
    weighted_items = sum(len(out_items[oi]) for oi in layout.weighted)
    bounds = list(itertools.pairwise([*starts.tolist(), lin_items + weighted_items]))
    n_lin, n_weighted = len(layout.lin), len(layout.weighted)
    # WeightedAverage/WeightedSum outputs: every item's value, segment starts, which outputs average
    w_items = [it for oi in layout.weighted for it in out_items[oi]]
    tsu = {oi: weighted_kind(outputs[oi]) == "Tsukamoto" for oi in layout.weighted}
    average = [type(outputs[oi].defuzzifier) is WeightedAverage for oi in layout.weighted]
    ordered = [outputs[oi] for oi in layout.order]
    out_range: tuple[Array, Array] | None = None
    if any(o.lock_range for o in ordered):
        out_range = (_col([o.minimum if o.lock_range else -math.inf for o in ordered]),
                     _col([o.maximum if o.lock_range else math.inf for o in ordered]))
    return _Defuzzification(
        starts,
        n_lin,
        lin_items,
        _lin_table(outputs, out_items, layout.lin, grids),
        _Segments(tuple(bounds[:n_lin])),
        weighted_items,
        _values(w_items, [tsu[it.output] for it in w_items]) if layout.weighted else None,
        _Segments(tuple((a - lin_items, b - lin_items) for a, b in bounds[n_lin: n_lin + n_weighted])),
        all(average) if all(average) or not any(average) else _col(average) > 0,
        _others(outputs, out_items, layout.other, lin_items + weighted_items, grids),
        len(layout.empty),
        _col([o.default for o in ordered]),
        out_range,
    )


# ---- the engine -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CompiledEngine:
    """The evaluation plan of one engine (see the module docstring), built by `compile_engine`; `evaluate`
    runs its stages in order."""

    input_names: tuple[str, ...]
    input_set: frozenset[str]
    in_range: tuple[Array, Array] | None  # clip bounds, ±inf for inputs not locked
    #: position of each output's row in the result of `evaluate`
    position: dict[str, int]
    #: (name, position) of every output in declaration order
    outputs: tuple[tuple[str, int], ...]
    fuzzification: _Fuzzification
    antecedents: _Antecedents
    grouping: _Grouping
    defuzzification: _Defuzzification
    #: The rule stage runs on chunks of this many rows (its widest intermediate stays in cache).
    chunk_rows: int

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
        return self.defuzzification.defuzzify(w, present, x)

    def _rules(self, x: Array) -> tuple[Array, Mask]:
        """Grouped degree and presence of every item (items, rows) for the (clipped) inputs."""
        deg = self.antecedents.degrees(self.fuzzification.memberships(x))
        fired = deg >= FIRING_EPSILON
        return self.grouping.grouped(np.where(fired, deg, 0.0), fired)


def compile_engine(engine: Engine, grids: Grids) -> CompiledEngine:
    """The plan of ``engine``, whose integral outputs are sampled on ``grids`` (name: samples, term name:
    membership at the samples), stage by stage."""
    inputs, outputs = engine.inputs, engine.outputs
    rules = [(b, r) for b in engine.rule_blocks for r in b.rules]
    dnf, tree_rules, literals = _split_rules(rules)
    fuzz = _fuzzification(inputs, literals)
    antecedents = _antecedents(rules, dnf, tree_rules, fuzz)
    sources = _sources(rules)
    out_items = [_output_items(oi, out, rules, sources) for oi, out in enumerate(outputs)]
    layout = _layout(outputs, out_items, grids)
    grouping = _grouping([it for oi in layout.order for it in out_items[oi]], sources)
    position = {outputs[oi].name: p for p, oi in enumerate(layout.order)}
    in_range: tuple[Array, Array] | None = None
    if any(v.lock_range for v in inputs):
        in_range = (_col([v.minimum if v.lock_range else -math.inf for v in inputs]),
                    _col([v.maximum if v.lock_range else math.inf for v in inputs]))
    widths = [len(inputs), len(fuzz.column), sources.count + 1, grouping.n_items + len(outputs), 2 * len(layout.lin)]
    widths += [index.size for index in (antecedents.clause_index, antecedents.rule_index, grouping.max_index,
                                        grouping.sum_index, grouping.present_index) if index is not None]
    names = tuple(v.name for v in inputs)
    return CompiledEngine(
        names,
        frozenset(names),
        in_range,
        position,
        tuple((o.name, position[o.name]) for o in outputs),
        fuzz,
        antecedents,
        grouping,
        _defuzzification(outputs, out_items, layout, grids),
        max(64, _CHUNK_FLOATS // max(widths)),
    )
