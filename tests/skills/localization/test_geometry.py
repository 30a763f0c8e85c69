"""The SE(2) algebra (`atemr.skills.localization.geometry`): one pose at a time gives the same bits as a batch.

A single pose takes a path of plain floats (much faster than ufuncs on three numbers); a seeded run must not
depend on which path a pose took, so both must agree to the last bit, wrap-around included.
"""

from __future__ import annotations

import math

import numpy as np

from atemr.skills.localization.geometry import as_array, as_pose, compose, inverse, relative


def poses(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = np.column_stack([rng.normal(0, 20, n), rng.normal(0, 20, n), rng.uniform(-4 * math.pi, 4 * math.pi, n)])
    out[:4, 2] = (math.pi, -math.pi, 0.0, math.pi / 2)  # on the wrap and the axes
    return out


def test_one_pose_at_a_time_gives_the_batchs_bits() -> None:
    a, b = poses(1, 5000), poses(2, 5000)
    batch_compose, batch_inverse, batch_relative = compose(a, b), inverse(a), relative(a, b)
    for k in range(len(a)):
        one = compose(a[k], b[k])
        assert one.shape == (3,) and one.tobytes() == batch_compose[k].tobytes(), k
        assert inverse(a[k]).tobytes() == batch_inverse[k].tobytes(), k
        assert relative(a[k], b[k]).tobytes() == batch_relative[k].tobytes(), k


def test_a_pose_and_its_inverse_cancel_and_poses_round_trip() -> None:
    for p in poses(3, 200):
        identity = compose(p, inverse(p))
        assert np.allclose(identity, 0.0, atol=1e-9)
        pose = as_pose(p)
        assert isinstance(pose.yaw_rad, float) and -math.pi <= pose.yaw_rad < math.pi
        assert np.allclose(as_array(pose)[:2], p[:2]) and math.isclose(math.cos(pose.yaw_rad), math.cos(p[2]))
