"""`NavigationPort` over the real `atemr.skills.nav.navigator.Navigator` (`atemr.robot.navigation` runs it on
the robot).

The navigator is a pure skill (data in, data out); this adapter feeds it what it needs each tick (the
pose, the latest scan, whether localization is confident) from callables the robot wiring provides, and
hands the agent's `GoToPose` leaf a `NavProgress`. It keeps the navigator's last full status
(``last_status``: global path, local trajectory, phase, recovery) for the dashboard.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from atemr.domain.places import NO_PLACES, Places
from atemr.errors import NavigationError
from atemr.msgs import LaserScan, Pose2D, Twist
from atemr.skills.nav.goal_check import GoalCheck
from atemr.skills.nav.navigator import Navigator, NavStatus
from atemr.trees.ports import NavProgress

_NO_POSE = Pose2D(math.nan, math.nan, math.nan)
#: Why a goal is refused on a robot without a map (a real robot's first start).
NO_MAP = "no map is selected: select a map (or make one in MAPPING) and set the robot's pose first"


class NavigatorPort:
    """The agent's navigation: ``Agent(spec, port, link, navigation=NavigatorPort(navigator, ...))``.

    ``pose`` gives the map-frame pose (None before any), ``scan`` the latest lidar scan (None: none yet),
    ``localized`` whether the pose can be trusted, ``velocity`` the measured twist if known, ``places`` the
    active map's named places. Without a navigator (a robot that has no map yet) every goal is refused with
    `NO_MAP`.
    """

    def __init__(self, navigator: Navigator | None, *, pose: Callable[[], Pose2D | None],
                 scan: Callable[[], LaserScan | None] = lambda: None, localized: Callable[[], bool] = lambda: True,
                 velocity: Callable[[], Twist | None] = lambda: None,
                 places: Callable[[], Places] = lambda: NO_PLACES) -> None:
        self.navigator = navigator
        self._pose, self._scan, self._localized, self._velocity = pose, scan, localized, velocity
        self._places = places
        self.last_status: NavStatus | None = None

    def check_goal(self, goal: Pose2D) -> str | None:
        verdict = self.goal_check(goal)
        return None if verdict.ok else verdict.reason

    def goal_check(self, goal: Pose2D) -> GoalCheck:
        """The navigator's whole verdict on ``goal``: with a refusal's code, which the dashboard says in plain
        words (`atemr.robot.plain_words.plain_goal_refusal`)."""
        if self.navigator is None:
            return GoalCheck(False, None, NO_MAP)
        return self.navigator.check(goal, localized=self._localized(), mode="AUTO")

    def start(self, goal: Pose2D, now: float, route: Sequence[Sequence[float]] | None = None) -> None:
        if self.navigator is None:
            raise NavigationError(NO_MAP)
        self.navigator.start(goal, now, localized=self._localized(), mode="AUTO", route=route)

    def update(self, now: float) -> NavProgress:
        if self.navigator is None:
            return NavProgress("FAILED", reason=NO_MAP)
        pose = self._pose()
        status = self.navigator.update(now, pose if pose is not None else _NO_POSE, self._scan(),
                                       self._localized(), self._velocity())
        self.last_status = status
        reason = status.message or (status.reason or "")
        return NavProgress(status.state, status.twist, status.distance_left_m, status.eta_s, reason)

    def places(self) -> Places:
        return self._places()

    def cancel(self, now: float) -> None:
        if self.navigator is not None:
            self.last_status = self.navigator.cancel(now)
