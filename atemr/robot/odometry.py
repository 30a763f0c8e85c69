"""Wheel odometry as a scheduler component: integrates the motors' measured speeds into a pose."""

from __future__ import annotations

from collections.abc import Callable

from atemr.msgs import Pose2D, WheelSpeeds
from atemr.skills.diff_drive import DiffDrive, Odometry


class WheelOdometry:
    """Ticks at the control rate; ``pose`` is the dead-reckoned pose in the ``odom`` frame."""

    name = "odometry"

    def __init__(self, feedback: Callable[[], WheelSpeeds], drive: DiffDrive | None = None,
                 start: Pose2D | None = None) -> None:
        self.feedback = feedback
        self.odometry = Odometry(drive or DiffDrive())
        self.odometry.reset(start)

    def tick(self, now: float) -> None:
        self.odometry.update_speeds(now, self.feedback())

    @property
    def pose(self) -> Pose2D:
        return self.odometry.pose
