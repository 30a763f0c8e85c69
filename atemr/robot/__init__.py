"""The robot assembled from its parts: `build_robot` wires them, `Robot` runs them.

Wiring lives here and nowhere else: every other package is a part (a skill, a driver, the simulator,
the agent, the dashboard) that knows nothing of the others.
"""

from atemr.robot.assembly import RATES, build_robot, make_clock
from atemr.robot.core import Robot, RobotEvent

__all__ = ["RATES", "Robot", "RobotEvent", "build_robot", "make_clock"]
