import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.msgs import Pose2D
from atemr.skills.nav.costmap import Costmap
from atemr.skills.nav.goal_check import check_goal
from atemr.skills.nav.navigator import Navigator

RES = 0.05


@pytest.fixture
def costmap(make_map, make_room):
    data = make_room(60, 80)  # 4 m x 3 m
    data[30, 40] = 100  # a post at (2.025, 1.525)
    data[50:59, 60:79] = -1  # an unmapped corner
    return Costmap(make_map(data, RES))


@pytest.mark.parametrize(
    ("goal", "kwargs", "code", "words"),
    [
        (Pose2D(float("nan"), 1.0, 0.0), {}, "not finite", "finite"),
        (Pose2D(1.0, 1.0, float("inf")), {}, "not finite", "finite"),
        (Pose2D(1.0, 1.0, 0.0), {"mode": "MANUAL"}, "not AUTO mode", "MANUAL"),
        (Pose2D(1.0, 1.0, 0.0), {"localized": False}, "not localized", "not localized"),
        (Pose2D(9.0, 1.0, 0.0), {}, "outside the map", "outside the map 'test'"),
        (Pose2D(-0.1, 1.0, 0.0), {}, "outside the map", "x 0.00..4.00"),
        (Pose2D(2.02, 1.52, 0.0), {}, "in an obstacle", "inside an obstacle"),
        (Pose2D(2.2, 1.52, 0.0), {}, "too close to an obstacle", "needs 0.30 m"),
        (Pose2D(3.5, 2.7, 0.0), {}, "in unknown space", "unmapped"),
    ],
)
def test_refusals_name_the_goal_and_the_reason(costmap, goal, kwargs, code, words):
    verdict = check_goal(goal, costmap, **kwargs)
    assert not verdict.ok
    assert verdict.code == code
    assert words in verdict.reason
    with pytest.raises(NavigationError, match="goal"):
        verdict.raise_if_refused()


def test_a_goal_in_free_space_is_accepted(costmap):
    verdict = check_goal(Pose2D(1.0, 1.0, 0.5), costmap)
    assert verdict.ok and verdict.code is None
    verdict.raise_if_refused()


def test_navigator_start_refuses_with_navigation_error_and_stays_idle(make_map, make_room):
    data = make_room(60, 80)
    data[30, 40] = 100
    nav = Navigator(make_map(data, RES))
    with pytest.raises(NavigationError, match=r"goal \(2\.02, 1\.52.*inside an obstacle"):
        nav.start(Pose2D(2.02, 1.52, 0.0), 0.0)
    assert nav.state == "IDLE"
    assert nav.events[-1].kind == "refused"
    status = nav.update(0.1, Pose2D(1.0, 1.0, 0.0))
    assert status.state == "IDLE" and status.twist.is_zero
    assert np.isnan(status.distance_left_m)


def test_a_person_standing_on_the_goal_is_no_reason_to_refuse_it(costmap):
    costmap.obstacles[20, 20] = True  # the obstacle layer sees someone at (1.025, 1.025)
    costmap.version += 1
    assert costmap.cost_at(1.025, 1.025) == 254
    assert check_goal(Pose2D(1.025, 1.025, 0.0), costmap).ok
