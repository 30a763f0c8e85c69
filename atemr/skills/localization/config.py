"""The ``localization`` configuration section: what an operator or integrator tunes, validated by `atemr.typed`.

Add it to `atemr.config.Config` as ``localization: LocalizationConfig = field(default_factory=LocalizationConfig)``
(one line; the section lives here beside the code it configures, as `MotionLimits` lives in
`atemr.skills.ramp`). `localizer_params` and `slam_params` turn it into the skills' parameter objects, which
check the cross-field rules (``min_particles <= max_particles``, ...) and raise `ConfigError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the skills import filterpy and scipy.stats (a second): only what builds them pays for it
    from atemr.skills.localization.localizer import LocalizerParams
    from atemr.skills.slam import SlamParams


@dataclass(frozen=True)
class LocalizationConfig:
    """AMCL, the confidence monitor, global localization and mapping (names as in ROS amcl where there is one)."""

    min_particles: int = field(default=300, metadata={"min": 10, "max": 100_000, "help": "AMCL's smallest cloud"})
    max_particles: int = field(default=5000, metadata={"min": 10, "max": 100_000, "help": "AMCL's largest cloud"})
    global_particles: int = field(default=20_000, metadata={"min": 100, "max": 200_000,
                                                            "help": "particles of a global localization"})
    max_beams: int = field(default=60, metadata={"min": 8, "max": 2000, "help": "beams weighed per scan"})
    sigma_hit_m: float = field(default=0.1, metadata={"min": 0.01, "max": 1.0, "help": "likelihood field std"})
    z_rand: float = field(default=0.1, metadata={"min": 0.001, "max": 1.0, "help": "weight of random returns"})
    odom_alpha1: float = field(default=0.05, metadata={"min": 0.0, "max": 5.0, "help": "rot. noise from rot."})
    odom_alpha2: float = field(default=0.05, metadata={"min": 0.0, "max": 5.0, "help": "rot. noise from trans."})
    odom_alpha3: float = field(default=0.05, metadata={"min": 0.0, "max": 5.0, "help": "trans. noise from trans."})
    odom_alpha4: float = field(default=0.02, metadata={"min": 0.0, "max": 5.0, "help": "trans. noise from rot."})
    update_min_d_m: float = field(default=0.1, metadata={"min": 0.0, "max": 5.0, "help": "AMCL update distance"})
    update_min_a_deg: float = field(default=15.0, metadata={"min": 0.0, "max": 180.0, "help": "AMCL update angle"})
    max_std_xy_m: float = field(default=0.5, metadata={"min": 0.01, "max": 10.0, "help": "lost above this std"})
    max_std_yaw_deg: float = field(default=20.0, metadata={"min": 0.5, "max": 180.0, "help": "lost above this std"})
    min_confidence: float = field(default=0.7, metadata={
        "min": 0.51, "max": 0.99, "help": "localized while the confidence (share of the scan on the map) is at least "
                                          "this; global localization needs it too"})
    confidence_time_s: float = field(default=1.0, metadata={"min": 0.05, "max": 60.0,
                                                            "help": "time the per-scan evidence is averaged over"})
    unmapped_allowance: float = field(default=0.25, metadata={
        "min": 0.0, "max": 0.9, "help": "share of a scan unmapped obstacles may hide without counting as lost"})
    relocalize_window_m: float = field(default=1.0, metadata={"min": 0.05, "max": 10.0,
                                                              "help": "local relocalization search radius"})
    seed: int = field(default=0, metadata={"min": 0, "help": "seed of AMCL's random generator"})
    map_resolution_m: float = field(default=0.05, metadata={"min": 0.01, "max": 0.5, "help": "mapping cell size"})
    map_size_m: float = field(default=30.0, metadata={"min": 2.0, "max": 200.0, "help": "mapping grid side"})

    def localizer_params(self, lidar_range_m: float = 8.0) -> LocalizerParams:
        """The `Localizer`'s parameters (raises `ConfigError` on inconsistent values); ``lidar_range_m``: the
        farthest return the robot's lidar is set to use, which the likelihood model and the global search cover."""
        from atemr.skills.localization.amcl import AmclParams
        from atemr.skills.localization.covariance_monitor import MonitorParams
        from atemr.skills.localization.global_search import GlobalSearchParams
        from atemr.skills.localization.likelihood_field import FieldParams
        from atemr.skills.localization.localizer import LocalizerParams
        from atemr.skills.localization.motion_model import OdometryNoise

        amcl = AmclParams(
            min_particles=self.min_particles, max_particles=self.max_particles,
            global_particles=self.global_particles, max_beams=self.max_beams,
            update_min_d_m=self.update_min_d_m, update_min_a_rad=math.radians(self.update_min_a_deg),
            noise=OdometryNoise(self.odom_alpha1, self.odom_alpha2, self.odom_alpha3, self.odom_alpha4),
            field=FieldParams(sigma_hit_m=self.sigma_hit_m, z_hit=1.0 - self.z_rand, z_rand=self.z_rand,
                              range_max_m=lidar_range_m),
        )
        monitor = MonitorParams(self.max_std_xy_m, math.radians(self.max_std_yaw_deg), self.min_confidence,
                                self.confidence_time_s, self.unmapped_allowance)
        search = GlobalSearchParams(min_agreement=self.min_confidence, range_max_m=amcl.field.range_max_m)
        return LocalizerParams(amcl=amcl, monitor=monitor, global_search=search,
                               relocalize_window_m=self.relocalize_window_m)

    def slam_params(self) -> SlamParams:
        from atemr.skills.slam import SlamParams

        return SlamParams(resolution_m=self.map_resolution_m, size_m=self.map_size_m)


__all__ = ["LocalizationConfig"]
