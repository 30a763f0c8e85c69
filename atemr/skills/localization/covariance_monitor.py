"""The covariance monitor (thesis recommendation 5.4 iii): notice that localization is lost, and say why.

The thesis's robot lost AMCL after driving round corners and had to be reset by hand; its author asked
for "an odometry monitor to automatically trigger local and global odometry resets when the covariance
grows past a certain limit". Two symptoms are checked on every scan:

* the pose covariance: the largest position standard deviation or the yaw standard deviation above
  its limit (the estimate no longer knows where it is);
* the scan's agreement with the map at the estimated pose below its limit (the estimate is confident
  but wrong: a kidnapped robot, a wrong convergence) — covariance alone never notices that.

One bad scan is not enough (a person walking past the lidar lowers the agreement for a moment):
the monitor reports "lost" after ``lost_after`` bad checks in a row, with the reason of the last one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atemr.errors import ConfigError
from atemr.skills.localization.amcl import PoseEstimate


@dataclass(frozen=True)
class MonitorParams:
    """Limits of the monitor."""

    max_std_xy_m: float = 0.5
    max_std_yaw_rad: float = 0.35
    min_agreement: float = 0.5
    lost_after: int = 3

    def __post_init__(self) -> None:
        for name in ("max_std_xy_m", "max_std_yaw_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"localization.{name}")
        if not 0.0 <= self.min_agreement < 1.0:
            raise ConfigError(f"must be within [0, 1), got {self.min_agreement!r}", path="localization.min_agreement")
        if self.lost_after < 1:
            raise ConfigError(f"must be >= 1, got {self.lost_after!r}", path="localization.lost_after")


@dataclass(frozen=True)
class MonitorReport:
    """One check: ``lost`` once the limits were broken ``lost_after`` times in a row; ``reason`` says which."""

    t: float
    lost: bool
    reason: str
    std_xy_m: float
    std_yaw_rad: float
    agreement: float


class CovarianceMonitor:
    """Counts consecutive bad checks; a good check resets the count."""

    def __init__(self, params: MonitorParams | None = None) -> None:
        self.params = params or MonitorParams()
        self.bad_in_a_row = 0

    def reset(self) -> None:
        self.bad_in_a_row = 0

    def problem(self, estimate: PoseEstimate, agreement: float) -> str:
        """Why this check is bad ("" when it is good)."""
        p = self.params
        cov = np.asarray(estimate.covariance, dtype=np.float64)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            return "pose covariance is not finite"
        sxy, syaw = estimate.std_xy_m, estimate.std_yaw_rad
        if sxy > p.max_std_xy_m:
            return f"position uncertainty {sxy:.2f} m above the limit {p.max_std_xy_m:.2f} m"
        if syaw > p.max_std_yaw_rad:
            limit = math.degrees(p.max_std_yaw_rad)
            return f"heading uncertainty {math.degrees(syaw):.0f}° above the limit {limit:.0f}°"
        if not (math.isfinite(agreement) and agreement >= p.min_agreement):
            return f"scan agrees with the map for {agreement:.0%} of its points, below {p.min_agreement:.0%}"
        return ""

    def check(self, estimate: PoseEstimate, agreement: float) -> MonitorReport:
        """Check one estimate and the agreement of the scan taken with it."""
        reason = self.problem(estimate, agreement)
        self.bad_in_a_row = self.bad_in_a_row + 1 if reason else 0
        finite = bool(np.all(np.isfinite(estimate.covariance)))
        return MonitorReport(
            estimate.t, self.bad_in_a_row >= self.params.lost_after, reason,
            estimate.std_xy_m if finite else math.inf, estimate.std_yaw_rad if finite else math.inf, float(agreement),
        )


__all__ = ["CovarianceMonitor", "MonitorParams", "MonitorReport"]
