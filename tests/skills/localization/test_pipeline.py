"""The localization pipeline as a scheduler component beside the simulator: wheels, IMU and scans in, poses out."""

from __future__ import annotations

import math

import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.errors import NavigationError
from atemr.io.sim.simulation import build_simulation
from atemr.msgs import WheelSpeeds
from atemr.scheduler import Scheduler
from atemr.skills.localization.pipeline import LocalizationPipeline


class WheelFeedback:
    """Stands in for the motor driver: reads the simulated wheels' speeds at 50 Hz."""

    name = "test.wheels"

    def __init__(self, sim, pipeline: LocalizationPipeline) -> None:  # type: ignore[no-untyped-def]
        self.sim, self.pipeline = sim, pipeline

    def tick(self, now: float) -> None:
        self.pipeline.on_wheels(now, WheelSpeeds(self.sim.left.speed_radps, self.sim.right.speed_radps))


def test_pipeline_tracks_the_robot_in_the_simulator(studio_map, simdrive) -> None:  # type: ignore[no-untyped-def]
    sim = build_simulation("studio", 6)
    pipeline = LocalizationPipeline(studio_map, np.random.default_rng(0))
    pipeline.set_initial_pose(0.0, sim.pose)
    sched = Scheduler(SimClock())
    sim.attach(sched)
    sched.add(WheelFeedback(sim, pipeline), 50.0)
    sched.add(pipeline, 10.0, phase_s=0.001)  # just after the lidar of the same instant
    sim.lidar_source.subscribe(pipeline.on_scan)
    sim.imu_source.subscribe(pipeline.on_imu)
    follower = simdrive.Follower(sim, simdrive.LIVING_ROOM_LOOP, 0.4, 1)
    sched.add(follower, 10.0)
    errors, odom_yaw_errors = [], []
    t = 0.0
    while not follower.done and t < 60.0:
        t += 0.5
        sched.run(until=t)
        pose = pipeline.map_pose()
        assert pose is not None
        errors.append(pose.distance_to(sim.pose))
        odom_yaw_errors.append(abs(math.remainder(pipeline.odom_pose.yaw_rad - sim.pose.yaw_rad, 2 * math.pi)))
    assert follower.done and pipeline.localized
    assert pipeline.scans_used > 200 and pipeline.icp_failures < 0.1 * pipeline.scans_used
    assert float(np.sqrt(np.mean(np.square(errors)))) < 0.10
    assert max(odom_yaw_errors) < 0.1  # odom frame = start pose here (start yaw 0), drifting slowly
    kinds = [e.kind for e in pipeline.drain_events()]
    assert kinds == ["initial_pose", "localized"] and pipeline.drain_events() == []
    assert pipeline.confidence >= pipeline.min_confidence and pipeline.state == "localized"


def test_pipeline_without_a_map() -> None:
    pipeline = LocalizationPipeline(None, np.random.default_rng(0))
    with pytest.raises(NavigationError, match="no active map"):
        pipeline.start_global(0.0)
    pipeline.on_wheels(0.1, WheelSpeeds(2.0, 2.0))
    pipeline.on_wheels(0.2, WheelSpeeds(2.0, 2.0))
    pipeline.tick(0.2)
    assert pipeline.map_pose() is None and not pipeline.localized and pipeline.estimate is None
    assert pipeline.odom_pose.x_m > 0.0
    assert pipeline.odom_at(0.15) == pipeline.odom_at(0.1) != pipeline.odom_at(0.25) == pipeline.odom_pose
