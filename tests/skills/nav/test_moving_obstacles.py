import math

import numpy as np
import pytest

from atemr.errors import NavigationError
from atemr.skills.nav.costmap import Costmap
from atemr.skills.nav.moving_obstacles import ObstacleTracker, TrackerParams, segments


def arc(cx, cy, r=0.2, n=9):
    """The visible half of a person seen from below (-y), in beam order."""
    a = np.linspace(-math.pi * 0.9, -math.pi * 0.1, n)
    return np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a)])


def test_segments_split_at_gaps():
    pts = np.vstack([arc(1.0, 1.0), arc(3.0, 1.0)])
    centres, half = segments(pts, 0.15)
    assert len(centres) == 2
    assert centres[0, 0] == pytest.approx(1.0, abs=0.01) and centres[1, 0] == pytest.approx(3.0, abs=0.01)
    assert (half > 0.1).all() and (half < 0.25).all()
    assert segments(np.zeros((0, 2)), 0.15)[0].shape == (0, 2)


def test_a_walking_person_is_tracked_and_swept_ahead():
    tracker = ObstacleTracker()
    for k in range(6):  # 0.6 m/s along +x, scans at 10 Hz; a box that stands still beside
        t = 0.1 * k
        tracker.update(t, np.vstack([arc(1.0 + 0.6 * t, 2.0), arc(3.0, 0.5)]))
    moving = tracker.moving()
    assert len(moving) == 1
    assert moving[0].vx_mps == pytest.approx(0.6, abs=0.05) and abs(moving[0].vy_mps) < 0.05
    pred = tracker.predicted_points(0.05)
    # Ahead of her (up to 0.6 m/s * 1.5 s = 0.9 m), not behind, not at the box.
    assert pred[:, 0].max() == pytest.approx(1.3 + 0.9 + moving[0].radius_m, abs=0.1)
    assert pred[:, 0].min() > 1.3 + 0.6 * 0.25 * 0.8 - moving[0].radius_m - 0.01  # from 0.25 s ahead on
    assert not (np.hypot(pred[:, 0] - 3.0, pred[:, 1] - 0.5) < 0.5).any()


def test_new_or_still_things_predict_nothing_and_old_tracks_are_forgotten():
    tracker = ObstacleTracker()
    tracker.update(0.0, arc(1.0, 1.0))
    tracker.update(0.1, arc(1.06, 1.0))
    assert tracker.moving() == []  # seen twice only
    tracker.update(0.2, arc(1.06, 1.0))
    tracker.update(0.3, arc(1.06, 1.0))
    assert tracker.moving() == []  # stopped: the smoothed speed falls under the threshold
    tracker.update(5.0, np.zeros((0, 2)))
    assert tracker.tracks == []


def test_predicted_layer_blocks_cells_and_is_replaced(make_map, make_room):
    cm = Costmap(make_map(make_room(60, 80), 0.05))
    cm.set_predicted(np.array([[2.0, 1.5]]))
    assert cm.cost_at(2.0, 1.5) == 254
    assert cm.hard_distance_at(2.0, 1.5) > 1.0  # not a present obstacle
    cm.set_predicted(np.zeros((0, 2)))
    assert cm.cost_at(2.0, 1.5) == 0


def test_bad_params():
    with pytest.raises(NavigationError, match="smoothing"):
        TrackerParams(smoothing=0.0)
