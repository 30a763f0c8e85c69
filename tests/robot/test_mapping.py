"""The map service: saving a map is all or nothing."""

import pytest

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.errors import AtemrError
from atemr.io.can.bus import unique_channel
from atemr.msgs import Twist
from atemr.robot import build_robot


@pytest.fixture
def robot(tmp_path):
    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": unique_channel("map"),
                                                "secondary.portal_serve": False, "ui.enabled": False,
                                                "sim.camera_hz": 0})
    robot = build_robot(config, realtime=False, clock=SimClock())
    with robot:
        yield robot


CURVE = Twist(0.2, 0.3)


def drive(robot, until, twist=CURVE):
    inputs = robot.extras["inputs"]
    t = robot.clock.now()
    while t < until:
        inputs.operate(twist, t)
        robot.run(until=t + 0.1)
        t = robot.clock.now()


def test_a_refused_save_keeps_the_session_and_stores_nothing(robot):
    maps = robot.extras["maps"]
    robot.run(until=6.0)
    maps.begin()
    drive(robot, 12.0)
    with pytest.raises(AtemrError, match="built-in"):
        maps.end("studio", robot.clock.now())  # the built-in name is refused
    assert maps.slam is not None and maps.active_name == "studio"
    assert robot.extras["map_store"].names() == ["studio"]
    stored = maps.end("living-room", robot.clock.now())
    assert stored == "living-room" and maps.active_name == "living-room" and maps.slam is None
    assert robot.extras["map_store"].active_name() == "living-room"
