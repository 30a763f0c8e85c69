"""DiscreteCentroid: scikit-fuzzy's ControlSystem centroid, vectorised over rows.

scikit-fuzzy samples each output term on a discrete universe of ``points`` values and treats it as
piecewise linear between them. For one evaluation it clips every term at its activation level, adds to
the universe the points where a term's line crosses that level (``_interp_universe_fast``), takes the
maximum of the clipped terms there and integrates the piecewise-linear result exactly (trapezoids and
their moments). This module computes the same number for N rows at once: the grid-only integral for
every cell, then, only in the cells where some term crosses its level, the cell integral again with the
crossing points inserted. It lets the benchmark compare our engine with scikit-fuzzy on the same
engine, inputs and discretised universe, and gives engines a centroid that is exact for
piecewise-linear terms instead of the midpoint-rule approximation of `Centroid`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from atemr.skills.fuzzy.defuzzifiers import DEFUZZIFIERS, IntegralDefuzzifier
from atemr.skills.fuzzy.norms import TNORMS, Norm
from atemr.skills.fuzzy.separable import SEPARABLE_EPS, is_separable, separable_totals

Array = NDArray[np.float64]
#: Rows handled together, bounding memory at about rows × points × terms floats.
_CHUNK_ROWS = 16384


def _segments(xa: Array, xb: Array, ya: Array, yb: Array) -> tuple[Array, Array]:
    """Area and first moment of the straight line from (xa, ya) to (xb, yb) over [xa, xb]."""
    h = xb - xa
    area = h * (ya + yb) / 2.0
    moment = h / 6.0 * (xa * (2.0 * ya + yb) + xb * (ya + 2.0 * yb))
    return area, moment


@lru_cache(maxsize=256)
def _monotone_runs(samples: bytes) -> list[tuple[int, int, bool]]:
    """Maximal strictly rising or falling stretches of a sampled term: (first node, last node, rising).
    Flat cells never cross a level, so they end runs and belong to none. Cached: terms do not change."""
    step = np.sign(np.diff(np.frombuffer(samples, dtype=np.float64)))
    runs = []
    j = 0
    while j < len(step):
        if step[j] == 0:
            j += 1
            continue
        k = j
        while k < len(step) and step[k] == step[j]:
            k += 1
        runs.append((j, k, bool(step[j] > 0)))
        j = k
    return runs


@dataclass(frozen=True)
class DiscreteCentroid(IntegralDefuzzifier):
    """Exact centroid of the clipped terms sampled at ``resolution`` points from min to max inclusive."""

    resolution: int = 201

    def samples(self, minimum: float, maximum: float) -> Array:
        """The discrete universe: ``resolution`` evenly spaced points, both ends included."""
        return np.linspace(minimum, maximum, self.resolution)

    def reduce(self, x: Array, y: Array) -> Array:
        """Centroid of the piecewise-linear function through the samples (no crossing points)."""
        area, moment = _segments(x[:-1], x[1:], y[:, :-1], y[:, 1:])
        with np.errstate(divide="ignore", invalid="ignore"):
            return moment.sum(axis=1) / area.sum(axis=1)

    def defuzzify_terms(self, u: Array, terms: Sequence[tuple[Array, Array, str | None]], n: int) -> Array:
        """Crisp value per row from (term sampled on ``u``, degree per row, implication) triples whose
        implied sets are aggregated with Maximum. Minimum implication adds the crossing points."""
        if not terms:
            return np.full(n, np.nan)
        m = np.stack([t[0] for t in terms])  # (T, K)
        d = np.stack([t[1] for t in terms], axis=1)  # (N, T)
        clip = [imp == "Minimum" for _, _, imp in terms]
        norms: list[Norm | None] = [TNORMS.get(imp) if imp else None for _, _, imp in terms]
        runs = [_monotone_runs(m[t].tobytes()) if clip[t] else [] for t in range(len(terms))]
        out = np.empty(n)
        for start in range(0, n, _CHUNK_ROWS):
            stop = min(n, start + _CHUNK_ROWS)
            out[start:stop] = self._chunk(u, m, d[start:stop], runs=runs, norms=norms, names=[t[2] for t in terms])
        return out

    @staticmethod
    def _chunk(
        u: Array, m: Array, d: Array, *, runs: list[list[tuple[int, int, bool]]], norms: list[Norm | None],
        names: list[str | None],
    ) -> Array:
        """Centroid per row of ``d``'s rows: the grid-only integral, corrected where a term crosses its level."""
        x0, x1 = u[:-1], u[1:]
        area, moment, lonely = _grid_totals(m, d, norms=norms, names=names, x0=x0, x1=x1)
        crossings = _crossings(m, d, runs=runs, x0=x0, x1=x1, area=area, moment=moment, lonely=lonely)
        if crossings[0] and sum(len(r) for r in crossings[0]):
            _redo_cells(m, d, crossings, norms=norms, x0=x0, x1=x1, area=area, moment=moment)
        with np.errstate(divide="ignore", invalid="ignore"):
            return moment / area


def _implied(norm: Norm | None, degree: Array, mu: Array) -> Array:
    """A term ``mu`` implied at ``degree`` (no implication: the term itself, unclipped)."""
    if norm is None:
        return np.broadcast_to(mu, np.broadcast_shapes(degree.shape, mu.shape))
    return norm(degree, mu)


def _grid_totals(m: Array, d: Array, *, norms: list[Norm | None], names: list[str | None], x0: Array,
                 x1: Array) -> tuple[Array, Array, bool]:
    """Area and moment per row of the aggregated set through the grid values only, and whether a crossing cell
    holds only its own term (then `_crossings` corrects it on its own)."""
    t_count, k = m.shape
    h = x1 - x0
    # Area and moment of the piecewise-linear set through the grid values y_k are linear in y:
    # Σ w_k y_k, each grid value's weight being its share of the two cells around it.
    w_area = np.zeros(k)
    w_area[:-1] += h / 2.0
    w_area[1:] += h / 2.0
    w_moment = np.zeros(k)
    w_moment[:-1] += h / 6.0 * (2.0 * x0 + x1)
    w_moment[1:] += h / 6.0 * (x0 + 2.0 * x1)
    weights = np.stack([w_area, w_moment], axis=1)  # (K, 2)
    # (memberships below 1e-12, e.g. a triangle's foot landing a rounding error off a grid point,
    # count as zero here; ignoring them changes a result by less than 1e-12 of the range)
    active = m > SEPARABLE_EPS
    fast = is_separable(m, names)
    # ... and no cell has non-zero terms at both ends: then a crossing cell holds only its own term
    lonely = bool(fast and (active[:, :-1] | active[:, 1:]).sum(axis=0).max() <= 1)
    if fast:
        totals = separable_totals(m, d, names, weights)
    else:
        y = np.zeros((d.shape[0], k))
        for t in range(t_count):
            np.maximum(y, _implied(norms[t], d[:, t, None], m[t][None, :]), out=y)
        totals = y @ weights
    return totals[:, 0].copy(), totals[:, 1].copy(), lonely


Crossings = tuple[list[NDArray[np.intp]], list[NDArray[np.intp]], list[NDArray[np.intp]], list[Array]]


def _crossings(m: Array, d: Array, *, runs: list[list[tuple[int, int, bool]]], x0: Array, x1: Array, area: Array,
               moment: Array, lonely: bool) -> Crossings:
    """The cells where a clipped term crosses its level (scikit-fuzzy's _interp_universe_fast adds the crossing
    points there): with ``lonely`` cells, their integrals are corrected in ``area`` and ``moment`` at once;
    otherwise returned as (rows, cells, terms, crossing x) for `_redo_cells`."""
    found_rows: list[NDArray[np.intp]] = []
    found_cells: list[NDArray[np.intp]] = []
    found_terms: list[NDArray[np.intp]] = []
    found_x: list[Array] = []
    for t in range(m.shape[0]):
        for first, last, rising in runs[t]:
            # In a strictly monotone run of nodes a_0..a_L, the level c crosses the cell i with
            # a_i < c <= a_i+1 (rising) or a_i+1 < c <= a_i (falling): one binary search per row.
            nodes = m[t][first:last + 1]
            length = last - first
            c = d[:, t]
            if rising:
                i = np.searchsorted(nodes, c, side="left") - 1
            else:
                i = length - np.searchsorted(nodes[::-1], c, side="left")
                i = np.where(i == length, -1, i)
            r = np.nonzero((i >= 0) & (i < length))[0]
            cell = first + i[r]
            mk, mk1 = m[t][cell], m[t][cell + 1]
            if lonely:
                # only term t lives in this cell: the clipped line is two straight pieces meeting
                # at the crossing p at height c; each row crosses a run at most once
                ct = d[r, t]
                left, right = x0[cell], x1[cell]
                p = left + (ct - mk) * (right - left) / (mk1 - mk)
                y0, y1 = np.minimum(ct, mk), np.minimum(ct, mk1)
                a1, m1 = _segments(left, p, y0, ct)
                a2, m2 = _segments(p, right, ct, y1)
                a0, m0 = _segments(left, right, y0, y1)
                area[r] += a1 + a2 - a0
                moment[r] += m1 + m2 - m0
                continue
            found_rows.append(r)
            found_cells.append(cell)
            found_terms.append(np.full(len(r), t))
            found_x.append(x0[cell] + (d[r, t] - mk) * (x1[cell] - x0[cell]) / (mk1 - mk))
    return found_rows, found_cells, found_terms, found_x


def _redo_cells(m: Array, d: Array, crossings: Crossings, *, norms: list[Norm | None], x0: Array, x1: Array,
                area: Array, moment: Array) -> None:
    """Each (row, cell) with crossings integrated again with its crossing points inserted: the new integral
    replaces the grid-only one in ``area`` and ``moment``."""
    found_rows, found_cells, found_terms, found_x = crossings
    t_count, k = m.shape
    h = x1 - x0
    r_all = np.concatenate(found_rows)
    cell_all = np.concatenate(found_cells)
    keys, where = np.unique(r_all * (k - 1) + cell_all, return_inverse=True)
    rows, cells = np.divmod(keys, k - 1)
    left = x0[cells][:, None]
    right = x1[cells][:, None]
    pts = np.repeat(right, t_count, axis=1)
    pts[where, np.concatenate(found_terms)] = np.concatenate(found_x)
    xs = np.concatenate([left, np.sort(pts, axis=1), right], axis=1)  # (cells, T + 2)
    slope = (m[:, 1:] - m[:, :-1]) / h  # (T, K - 1), as np.interp computes it
    ys = np.zeros_like(xs)
    ends = np.zeros((len(rows), 2))
    for t in range(t_count):
        mu = slope[t, cells][:, None] * (xs - left) + m[t, cells][:, None]
        np.maximum(ys, _implied(norms[t], d[rows, t, None], mu), out=ys)
        grid = np.stack([m[t, cells], m[t, cells + 1]], axis=1)
        np.maximum(ends, _implied(norms[t], d[rows, t, None], grid), out=ends)
    a_new, m_new = _segments(xs[:, :-1], xs[:, 1:], ys[:, :-1], ys[:, 1:])
    a_old, m_old = _segments(x0[cells], x1[cells], ends[:, 0], ends[:, 1])
    np.add.at(area, rows, a_new.sum(axis=1) - a_old)
    np.add.at(moment, rows, m_new.sum(axis=1) - m_old)


DEFUZZIFIERS.add("DiscreteCentroid", DiscreteCentroid)
