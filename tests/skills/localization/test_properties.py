"""Property tests: pose algebra round trips; matchers and the field never crash on arbitrary input."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from atemr.domain.maps import OccupancyMap
from atemr.msgs import Pose2D
from atemr.skills.localization.geometry import compose, inverse, relative
from atemr.skills.localization.icp import icp
from atemr.skills.localization.likelihood_field import LikelihoodField

finite = st.floats(-50, 50, allow_nan=False, allow_infinity=False)
poses = st.tuples(finite, finite, st.floats(-3.14, 3.14)).map(np.array)
anything = st.floats(allow_nan=True, allow_infinity=True, width=64)

_grid = np.zeros((30, 30), dtype=np.int8)
_grid[10:12, 5:25] = 100
FIELD = LikelihoodField(OccupancyMap(_grid, 0.1, Pose2D(-1.5, -1.5, 0.3)))


@given(poses, poses)
def test_relative_inverts_compose(a: np.ndarray, b: np.ndarray) -> None:
    assert np.allclose(compose(a, relative(a, b))[:2], b[:2], atol=1e-6)
    assert np.allclose(compose(inverse(a), a), 0.0, atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(0, 40), st.just(2)), elements=anything),
       arrays(np.float64, st.tuples(st.integers(0, 40), st.just(2)), elements=anything))
def test_icp_never_raises_on_garbage(src: np.ndarray, tgt: np.ndarray) -> None:
    r = icp(src, tgt)
    if r.converged:
        assert np.isfinite([r.pose.x_m, r.pose.y_m, r.pose.yaw_rad]).all() and np.isfinite(r.rmse_m)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 5), st.just(3)), elements=anything),
       arrays(np.float64, st.tuples(st.integers(0, 20), st.just(2)), elements=anything))
def test_field_scores_are_finite_for_any_pose(p: np.ndarray, pts: np.ndarray) -> None:
    pts = pts[np.isfinite(pts).all(axis=1)]  # callers pass valid points (scan_points drops the rest)
    ll = FIELD.log_likelihood(p, pts)
    agree = FIELD.agreement(p, pts)
    assert ll.shape == agree.shape == (p.shape[0],)
    assert np.isfinite(ll).all() and ((agree >= 0) & (agree <= 1)).all()
