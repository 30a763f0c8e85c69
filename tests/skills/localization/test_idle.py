"""A localized robot standing idle while the carer and the cat move: never "lost" (issue 21), no scan matching
while it stands (issue 22), and a kidnap is still noticed.

At the skill level, through the whole localization chain (`LocalizationPipeline`): the simulator's lidar sees the
studio with its carer and cat walking, the motors report wheels standing still (each reading 0 or a step of 1°/s
either way, as a real motor holding still may), and a simulated gyro reads its bias (0.003 rad/s, 10° a minute) and
its noise. The odometry EKF learns that bias while the wheels stand, so the
odometry does not turn, AMCL has no motion to update on and nothing is matched, yet the map pose stays on the
truth. Every scan is still weighed from the current pose (the monitor's one look), which is what notices the robot
carried off.

One simulated minute by default; ``ATEMR_TEST_SOAK=1`` runs the issue's full hour (``ATEMR_TEST_SOAK_S`` for another
length), as `tests/reliability/test_soak.py` does: it is 36,000 scans, several minutes of CPU.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable

import numpy as np

from atemr.io.sim.imu import Imu, ImuParams
from atemr.io.sim.lidar import Lidar, LidarParams
from atemr.io.sim.movers import Movers
from atemr.io.sim.scene import Scene
from atemr.io.sim.world import load_world
from atemr.msgs import Pose2D, WheelSpeeds
from atemr.skills.localization.localizer import Localizer
from atemr.skills.localization.pipeline import LocalizationPipeline

#: The gyro's bias (rad/s): 1.5 σ of the simulated IMU's turn-on bias. Left in the odometry, 0.18 rad a minute.
GYRO_BIAS_RADPS = 0.003
SCAN_HZ, IMU_HZ, WHEELS_HZ = 10, 50, 100


def idle_seconds() -> float:
    if os.environ.get("ATEMR_TEST_SOAK") == "1":
        return float(os.environ.get("ATEMR_TEST_SOAK_S", "3600"))
    return 60.0


class MatchCounter:
    """Counts the scan matches a localizer runs: AMCL's updates and the scan-to-map matcher's searches."""

    def __init__(self, localizer: Localizer) -> None:
        self.amcl = self.map = 0
        amcl_update, match = localizer.amcl.update, localizer.matcher.match

        def counted_update(*args, **kwargs):  # type: ignore[no-untyped-def]
            ran = amcl_update(*args, **kwargs)
            self.amcl += ran
            return ran

        def counted_match(*args, **kwargs):  # type: ignore[no-untyped-def]
            self.map += 1
            return match(*args, **kwargs)

        localizer.amcl.update = counted_update  # type: ignore[method-assign]
        localizer.matcher.match = counted_match  # type: ignore[method-assign]


def test_standing_idle_among_people_is_never_lost_matches_nothing_and_a_kidnap_is_noticed() -> None:
    world = load_world("studio")
    scene = Scene(world)
    rng = np.random.default_rng(11)
    lidar, movers = Lidar(LidarParams(), rng), Movers(world.movers, scene, rng)
    imu = Imu(ImuParams(), rng)
    imu.gyro_bias_radps = GYRO_BIAS_RADPS
    pipeline = LocalizationPipeline(world.map, np.random.default_rng(0))
    localizer = pipeline.localizer
    assert localizer is not None
    truth = world.start
    pipeline.set_initial_pose(0.0, truth)
    tick, step, jitter = 0, math.radians(1.0), np.random.default_rng(5)

    def stand(until: float, check: Callable[[float], None] = lambda t: None) -> float:
        """The robot's sensors and the pipeline at their rates until ``until`` (s): the wheels still (to a step),
        the gyro reading its bias, the lidar the room; ``check(t)`` after each scan handled."""
        nonlocal tick
        while tick * (1.0 / WHEELS_HZ) < until:
            tick += 1
            t = tick / WHEELS_HZ
            left, right = jitter.integers(-1, 2, 2) * step
            pipeline.on_wheels(t, WheelSpeeds(float(left), float(right)))
            if tick % (WHEELS_HZ // IMU_HZ) == 0:
                pipeline.on_imu(imu.sample(t, 0.0, 0.0, 0.0))
            if tick % (WHEELS_HZ // SCAN_HZ) == 0:
                movers.step(1.0 / SCAN_HZ, (truth.x_m, truth.y_m), 0.25)
                pipeline.on_scan(lidar.scan(t, truth, scene, movers.centres, movers.radii))
                pipeline.tick(t)
                check(t)
        return tick / WHEELS_HZ

    stand(2.0)  # checked the operator's pose, learnt the gyro's bias
    matches = MatchCounter(localizer)
    worst = {"confidence": 1.0, "error": 0.0, "std": 0.0}
    passes = 0

    def watch(t: float) -> None:
        nonlocal passes
        passes += bool(np.any(np.hypot(*(movers.centres - [truth.x_m, truth.y_m]).T) < 2.5))
        estimate = localizer.estimate
        assert estimate is not None, f"not localized at t={t:.1f} s: {localizer.events[-3:]}"
        worst["confidence"] = min(worst["confidence"], localizer.confidence)
        worst["error"] = max(worst["error"], estimate.pose.distance_to(truth),
                             abs(math.remainder(estimate.pose.yaw_rad - truth.yaw_rad, 2 * math.pi)))
        worst["std"] = max(worst["std"], estimate.std_xy_m)

    end = stand(2.0 + idle_seconds(), watch)
    lost = [e for e in localizer.events if e.kind == "lost"]
    assert not lost, lost
    assert passes > 0.05 * (end - 2.0) * SCAN_HZ, "the carer walked past within 2.5 m"
    assert worst["confidence"] >= 0.9 and worst["error"] < 0.05, worst
    assert worst["std"] < 0.1, worst  # the map pose's uncertainty does not creep up while it stands
    # the bias would have turned the odometry by 10°; it turned by less than half a degree, and nothing was matched
    assert abs(pipeline.odom_pose.yaw_rad) < math.radians(0.5), pipeline.odom_pose
    assert abs(pipeline.odometry.gyro_bias_radps - GYRO_BIAS_RADPS) < 0.0005, pipeline.odometry.gyro_bias_radps
    assert (matches.amcl, matches.map) == (0, 0), vars(matches)
    assert pipeline.icp_skipped >= (end - 2.0) * SCAN_HZ - 1

    # carried 2 m across the living room, facing the other way: noticed within 5 s, found again
    kidnapped_at, truth = end, Pose2D(truth.x_m + 2.0, truth.y_m + 0.2, math.pi / 2)
    stand(kidnapped_at + 5.0, lambda t: None)
    lost = [e for e in localizer.events if e.kind == "lost"]
    assert lost and lost[0].t - kidnapped_at < 5.0, localizer.events[-3:]
    estimate = localizer.estimate
    assert estimate is not None and estimate.pose.distance_to(truth) < 0.1, localizer.events[-4:]
