"""How the MANUAL engine's steering joins the operator's command (thesis eq. 3.1), and its speed limit."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from atemr.errors import ConfigError

#: The MANUAL engine works best at low speed (thesis 5.2): linear speed is limited to this while it runs.
MANUAL_ENGINE_SPEED_LIMIT_MPS = 0.26
#: Radius of interest of the hex-pattern sectors the engines reason about (thesis 5.2), metres.
FUZZY_RADIUS_OF_INTEREST_M = 1.2


def blend(w_engine: ArrayLike, w_operator: ArrayLike, tau: float) -> NDArray[np.float64]:
    """W_applied = W_ME·τ + W_IO·(1 − τ): τ = 1 lets the engine steer alone, τ = 0 the operator alone.

    Works element-wise on arrays (e.g. angular rates of several rows). τ outside [0, 1] would
    extrapolate past both commands, so it raises `ConfigError`.
    """
    if not 0.0 <= tau <= 1.0:
        raise ConfigError(f"blend weight tau must be within [0, 1], got {tau:g}")
    me = np.asarray(w_engine, dtype=np.float64)
    io = np.asarray(w_operator, dtype=np.float64)
    return me * tau + io * (1.0 - tau)
