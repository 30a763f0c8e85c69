"""Integrals of an aggregated output without sampling it row by row, when its terms do not overlap.

When no sample point has two non-zero output terms, the Maximum aggregation of the implied terms is
their sum, so a weighted sum over the samples, Σ_k w_k·max_t T(c_t, μ_t(x_k)), splits into one function
per term of that term's level c alone:

* product implication (Larsen): c·Σ_k w_k μ_k;
* minimum implication (Mamdani): Σ_{μ_k < c} w_k μ_k + c·Σ_{μ_k >= c} w_k, a binary search per row in
  the term's sorted samples.

That turns the cost from rows × samples into rows × terms × log(samples). The robot's engines (adjacent
triangles) qualify; overlapping terms use the general path. Memberships below `SEPARABLE_EPS` (a
triangle's foot a rounding error off a sample) count as zero for the check, which changes results by
less than that fraction of the range.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

SEPARABLE_EPS = 1e-12


def is_separable(m: Array, implications: Sequence[str | None]) -> bool:
    """Whether sampled terms ``m`` (terms, samples) never overlap and every implication is min or product."""
    if not all(imp in ("Minimum", "AlgebraicProduct") for imp in implications):
        return False
    return bool((m > SEPARABLE_EPS).sum(axis=0).max(initial=0) <= 1)


def separable_totals(m: Array, d: Array, implications: Sequence[str | None], weights: Array) -> Array:
    """Σ_k w_k·max_t T(d_t, m_t,k) for every row and weight column: (rows, columns).

    ``m`` is (terms, samples), ``d`` (rows, terms) the levels, ``weights`` (samples, columns); the caller
    has checked `is_separable`.
    """
    totals = np.zeros((d.shape[0], weights.shape[1]))
    for t, imp in enumerate(implications):
        c = d[:, t]
        if imp == "AlgebraicProduct":
            totals += c[:, None] * (m[t] @ weights)[None, :]
            continue
        mu, below, rest = _tables(m[t].tobytes(), weights.tobytes(), weights.shape[1])
        j = np.searchsorted(mu, c, side="left")
        totals += below[j] + c[:, None] * rest[j]
    return totals


@lru_cache(maxsize=256)
def _tables(term: bytes, weights: bytes, columns: int) -> tuple[Array, Array, Array]:
    """Sorted samples of one term with the prefix sums Σ w·μ below and the suffix sums Σ w above each
    position; cached because an engine evaluates the same terms on every call."""
    m = np.frombuffer(term, dtype=np.float64)
    w_all = np.frombuffer(weights, dtype=np.float64).reshape(-1, columns)
    order = np.argsort(m, kind="stable")
    mu = m[order]
    w = w_all[order]
    zero = np.zeros((1, columns))
    below = np.concatenate([zero, np.cumsum(w * mu[:, None], axis=0)])
    rest = np.concatenate([np.cumsum(w[::-1], axis=0)[::-1], zero])
    return mu, below, rest
