"""The localization monitor (thesis recommendation 5.4 iii): one confidence number, and "lost" when it falls.

The thesis's robot lost AMCL after driving round corners and had to be reset by hand; its author asked for
"an odometry monitor to automatically trigger local and global odometry resets when the covariance grows past
a certain limit". Covariance alone never notices a robot that is sure of a wrong pose, so every scan gives one
piece of evidence about the pose the robot believes, in [0, 1]:

* 0 when the pose covariance is past its limits (the largest position standard deviation, or the heading's):
  the estimate no longer knows where it is;
* otherwise the share of the scan on the map there (`MapAgreement`), robust to what the map does not know:
  people, pets and new furniture only ever *shorten* beams, so up to ``unmapped_allowance`` of the beams
  may end in free space without counting against the pose. Beams that cross a wall always count, and so
  does every unexplained beam past the allowance: a wrong pose leaves unexplained beams all round.

The **confidence** is that evidence averaged over the last ``time_constant_s`` (an exponential average in
time, not in scans): a person stepping in front of the lidar moves it a little, a kidnapped robot's drops
below the limit within about a second. "Localized" means the confidence is at least ``min_confidence``,
nothing else; the report says why when it is not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atemr.errors import ConfigError
from atemr.skills.localization.amcl import PoseEstimate
from atemr.skills.localization.map_agreement import ScanAgreement


@dataclass(frozen=True)
class MonitorParams:
    """Limits of the monitor."""

    max_std_xy_m: float = 0.5
    max_std_yaw_rad: float = 0.35
    #: The localization limit: localized while the confidence is at least this.
    min_confidence: float = 0.7
    #: Time over which the per-scan evidence is averaged (s).
    time_constant_s: float = 1.0
    #: Share of the beams unmapped obstacles may hide without counting against the pose.
    unmapped_allowance: float = 0.25

    def __post_init__(self) -> None:
        for name in ("max_std_xy_m", "max_std_yaw_rad", "time_constant_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"localization.{name}")
        if not 0.5 < self.min_confidence < 1.0:  # two places sharing the evidence must never count as localized
            raise ConfigError(f"must be within (0.5, 1), got {self.min_confidence!r}",
                              path="localization.min_confidence")
        if not 0.0 <= self.unmapped_allowance < 1.0:
            raise ConfigError(f"must be within [0, 1), got {self.unmapped_allowance!r}",
                              path="localization.unmapped_allowance")


@dataclass(frozen=True)
class MonitorReport:
    """One check: the evidence of this scan, the confidence after it, and why it is low (``reason``)."""

    t: float
    lost: bool
    reason: str
    std_xy_m: float
    std_yaw_rad: float
    evidence: float
    confidence: float


def robust_agreement(counts: ScanAgreement, allowance: float) -> float:
    """``hits / (beams − min(unexplained, allowance · beams))`` of a single-pose count (0 for an empty scan)."""
    beams = float(counts.beams[0])
    if beams <= 0:
        return 0.0
    excused = min(float(counts.unexplained[0]), allowance * beams)
    return float(counts.hits[0]) / max(beams - excused, 1.0)


class CovarianceMonitor:
    """Turns per-scan evidence into the confidence (module docstring)."""

    def __init__(self, params: MonitorParams | None = None) -> None:
        self.params = params or MonitorParams()
        self.confidence = 0.0
        self._t: float | None = None
        self._why = ""

    def reset(self, confidence: float, t: float) -> None:
        """Start over at ``confidence`` (a pose just set or found, and how well it fits)."""
        self.confidence = float(min(max(confidence, 0.0), 1.0))
        self._t = t
        self._why = ""

    def evidence(self, estimate: PoseEstimate, counts: ScanAgreement) -> tuple[float, str]:
        """This scan's evidence in [0, 1] and, when it is below the limit, why."""
        p = self.params
        cov = np.asarray(estimate.covariance, dtype=np.float64)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            return 0.0, "pose covariance is not finite"
        sxy, syaw = estimate.std_xy_m, estimate.std_yaw_rad
        if sxy > p.max_std_xy_m:
            return 0.0, f"position uncertainty {sxy:.2f} m above the limit {p.max_std_xy_m:.2f} m"
        if syaw > p.max_std_yaw_rad:
            return 0.0, (f"heading uncertainty {math.degrees(syaw):.0f}° above the limit "
                         f"{math.degrees(p.max_std_yaw_rad):.0f}°")
        value = robust_agreement(counts, p.unmapped_allowance)
        if value >= p.min_confidence:
            return value, ""
        beams = int(counts.beams[0])
        return value, (f"scan agrees with the map for {value:.0%} (of {beams} beams: {int(counts.hits[0])} on the "
                       f"map, {int(counts.through[0])} through walls, {int(counts.unexplained[0])} in free space)")

    def check(self, estimate: PoseEstimate, counts: ScanAgreement) -> MonitorReport:
        """Fold one scan's evidence into the confidence."""
        p = self.params
        value, reason = self.evidence(estimate, counts)
        t = estimate.t
        if self._t is None:
            self.confidence = value
        else:
            dt = max(0.0, t - self._t)
            self.confidence += (1.0 - math.exp(-dt / p.time_constant_s)) * (value - self.confidence)
        self._t = t
        self._why = reason or self._why
        finite = bool(np.all(np.isfinite(estimate.covariance)))
        lost = self.confidence < p.min_confidence
        why = reason or (self._why if lost else "")
        if lost:
            why = f"confidence {self.confidence:.1%} below {p.min_confidence:.0%}: {why}"
        return MonitorReport(t, lost, why,
                             estimate.std_xy_m if finite else math.inf, estimate.std_yaw_rad if finite else math.inf,
                             value, self.confidence)


__all__ = ["CovarianceMonitor", "MonitorParams", "MonitorReport", "robust_agreement"]
