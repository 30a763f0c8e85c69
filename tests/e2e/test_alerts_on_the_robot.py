"""Every alert a carer can meet, provoked on the whole simulated robot and read in the page (issue 25).

`test_carer_views.py` checks the page's words against a stand-in robot; here the real robot (`RobotSite`: the
simulator, the emulated motors and secondary core, the agent, the real gateway and dashboard) is made to stop,
fail and lose itself the way it would in a home, and the test reads what the carer is told: the alert list
(ALERTS, ``#alert-items``) and, for a stop, the emergency indicator. The faults are injected with the hooks the
reliability suite uses on the headless robot (`tests/reliability/test_robot_faults.py`). Provocations share a
robot in sequence, since each robot costs a boot.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import can
import pytest

from atemr.msgs import Pose2D

from .conftest import RobotSite, running
from .test_dashboard import screen_point, wait_for

pytestmark = pytest.mark.e2e

#: Technical words that belong on the Agent page and in the logs, never in what a carer reads.
TECHNICAL = ("0x157", "can_bus", "left_motor", "right_motor", "secondary_core", "IDLE.", "EXEC", "OVER_TEMPERATURE")


class Alerts:
    """The page's alert list, read from a mark on: each provocation looks only at what it caused."""

    def __init__(self, page: Any) -> None:
        self.page = page
        self.mark = 0

    def count(self) -> int:
        return int(self.page.evaluate("document.querySelectorAll('#alert-items li').length"))

    def since_mark(self) -> list[str]:
        """The alerts said since `start`, oldest first (the list shows the newest first)."""
        new = self.count() - self.mark
        texts: list[str] = self.page.evaluate(
            f"[...document.querySelectorAll('#alert-items li')].slice(0, {new}).map((li) => li.textContent)")
        return texts[::-1]

    def start(self) -> None:
        self.mark = self.count()

    def said(self, text: str, timeout: float = 10_000) -> None:
        """Wait until an alert since the mark contains ``text``."""
        js = ("[...document.querySelectorAll('#alert-items li')]"
              f".slice(0, document.querySelectorAll('#alert-items li').length - {self.mark})"
              f".some((li) => li.textContent.includes({text!r}))")
        try:
            wait_for(self.page, js, timeout=timeout)
        except AssertionError:
            raise AssertionError(f"never said {text!r}; said: {self.since_mark()}") from None

    def plain(self) -> None:
        """Nothing said since the mark uses the robot's technical names."""
        said = self.since_mark()
        technical = [t for t in said if any(word in t for word in TECHNICAL)]
        assert not technical, f"technical words in the carer's alerts: {technical}"


def open_control(page: Any, site: RobotSite, helpers: Any) -> Alerts:
    """Log in, wait for the live robot with every part healthy, and return its alert list."""
    helpers.login(page, site.url, "admin", helpers.ADMIN_PW)
    # ?.: until the login's redirect lands, the page is still the login page, which has no socket indicator
    wait_for(page, "document.getElementById('sock')?.dataset.status === 'ONLINE' && ATEMR.live "
                   "&& ATEMR.map?.image != null && document.getElementById('agent-state').dataset.state === 'IDLE'")
    wait_for(page, "Object.values(ATEMR.state.level2).every((ok) => ok)", timeout=15_000)
    return Alerts(page)


#: The emergency indicator's words for each ``stop_cause`` (what to do is on hover).
STOP_WORDS = {"obstacle": "Stopped: too close", "heartbeat": "Stopped: lost contact", "motor": "Stopped: motor fault",
              "bus": "Stopped: motors silent", "cliff": "Stopped: a drop"}


def stop_shown(page: Any, cause: str) -> None:
    """The emergency indicator says why the robot is held stopped (the state's ``stop_cause``), with what to do on
    hover. A generous wait: on a busy machine the robot runs slower than real time, and the heartbeat alone takes
    2 s of its time."""
    wait_for(page, f"document.getElementById('emergency').dataset.cause === {cause!r}", timeout=15_000)
    assert page.inner_text("#emergency") == STOP_WORDS[cause]
    assert page.get_attribute("#emergency", "title").startswith("Stopped: ")  # alerts.js's sentence, what to do


def hold(page: Any, key: str) -> None:
    page.focus("#joystick")
    page.keyboard.down(key)


def on_map(page: Any, tool: str, pose: Pose2D) -> None:
    """Use a simulation-panel tool (``#sim-obstacle``, ``#sim-kidnap``) at ``pose``: press there, drag for the
    heading, and put the tool away."""
    page.click(tool)
    x, y = screen_point(page, pose.x_m, pose.y_m)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 40 * math.cos(pose.yaw_rad), y - 40 * math.sin(pose.yaw_rad), steps=3)
    page.mouse.up()
    page.click(tool)


def test_every_stop_is_said_with_its_cause_and_what_to_do(robot_site, page, helpers, monkeypatch, shots):
    """Something too close, a drop, the cores' heartbeat, a motor and the CAN bus, each on the running robot:
    the carer reads why it stopped and what to do, the indicator names the cause, and the all-clear follows."""
    site = robot_site
    alerts = open_control(page, site, helpers)

    # something too close: an obstacle dropped 1 m ahead (the simulation panel), the carer drives into it
    start = site.sim.pose
    alerts.start()
    on_map(page, "#sim-obstacle", Pose2D(start.x_m + 1.0, start.y_m, 0.0))
    hold(page, "ArrowUp")
    stop_shown(page, "obstacle")
    alerts.said("Stopped: something is too close. Drive away from it: reverse or turn.")
    assert "reverse" in page.get_attribute("#emergency", "title")
    page.screenshot(path=str(shots / "alerts-obstacle.png"))
    page.keyboard.up("ArrowUp")
    hold(page, "ArrowDown")  # what the alert says to do
    alerts.said("The robot may move again.")
    page.keyboard.up("ArrowDown")
    wait_for(page, "document.getElementById('emergency').textContent === 'No emergency'")
    alerts.plain()

    # the cores' heartbeat: the secondary core falls silent (its floor-sensor frames stop first)
    alerts.start()
    board = site.robot.components["secondary_core"]
    monkeypatch.setattr(board, "tick", lambda now: None)
    stop_shown(page, "heartbeat")
    alerts.said("Stopped: the robot's two computers lost contact. It moves again when they talk again")
    monkeypatch.undo()
    alerts.said("The robot may move again.", timeout=15_000)
    alerts.plain()

    # a motor: the left one falls silent, then answers again
    motor = site.robot.components["left_motor_emulator"].model  # type: ignore[attr-defined]
    alerts.start()
    site.sim.submit(motor.unplug)
    stop_shown(page, "motor")
    alerts.said("Stopped: a motor reports a fault. The robot moves again when both motors answer without error.")
    site.sim.submit(motor.plug)
    alerts.said("The robot may move again.", timeout=15_000)
    alerts.plain()

    # the CAN bus: its controller goes bus-off (it says so, and nothing more is received), then recovers
    supervised = site.robot.components["can_bus"].bus  # type: ignore[attr-defined]
    off = [True]
    monkeypatch.setattr(type(supervised), "state", property(
        lambda bus: can.BusState.ERROR if bus is supervised and off[0] else can.BusState.ACTIVE))

    def nothing(timeout: float | None = None) -> can.Message | None:
        raise can.CanOperationError("bus-off (simulated)")

    monkeypatch.setattr(supervised, "recv", nothing)
    alerts.start()
    stop_shown(page, "bus")
    alerts.said("Stopped: the motors' connection (CAN bus) failed. The robot moves again when it works again.")
    # the motors fall silent behind the bus and the driver latches that too: the cause to mend stays the bus
    wait_for(page, "ATEMR.state.agent_state === 'ERROR' && !ATEMR.state.level2.left_motor "
                   "&& !ATEMR.state.level2.right_motor", timeout=15_000)
    # The page can say so before the driver's silence timeout has run out on the robot's clock (a motor's health
    # also goes false while it has not answered since its last fault was cleared): wait for the latch itself.
    driver = site.robot.parts.driver
    for _ in range(300):
        if driver.fault is not None:
            break
        page.wait_for_timeout(50)
    assert driver.fault is not None, "the driver never latched the motors' silence behind the bus"
    assert page.inner_text("#emergency") == STOP_WORDS["bus"]
    assert not [t for t in alerts.since_mark() if "motor reports a fault" in t], alerts.since_mark()
    off[0] = False
    monkeypatch.undo()
    alerts.said("The robot may move again.", timeout=15_000)
    alerts.plain()

    # a drop: carried onto the balcony facing its open edge (the simulation panel), the carer drives on
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'", timeout=15_000)
    on_map(page, "#sim-kidnap", Pose2D(4.25, -0.3, -math.pi / 2))
    alerts.start()
    hold(page, "ArrowUp")
    stop_shown(page, "cliff")
    alerts.said("Stopped: a drop (stairs, a step) is under the robot's edge. Drive it back, away from the edge.")
    page.screenshot(path=str(shots / "alerts-cliff.png"))
    page.keyboard.up("ArrowUp")
    assert site.sim.falls == []
    hold(page, "ArrowDown")
    alerts.said("The robot may move again.")
    page.keyboard.up("ArrowDown")
    alerts.plain()


#: A robot whose goals give up after 12 s (the default is 10 minutes) and whose pack is nearly at its warning
#: level (20 %) with the slowest charger (a day for a full charge: it starts on its dock), so a goal fails and the
#: battery runs low within the test.
TIRED = {"nav.timeout_s": 12.0, "sim.battery_percent": 21.0, "sim.battery_charge_s": 86_400.0,
         "sim.camera_hz": 2.0}  # a camera that renders less often: the robot keeps its pace on a busy machine


@pytest.fixture
def tired_robot_site(tmp_path: Path) -> Iterator[RobotSite]:
    """`TIRED`, paced at 4× real time."""
    yield from running(RobotSite(tmp_path / "data", speed=4.0, overrides=TIRED))


def go_here(page: Any, pose: Pose2D) -> None:
    """GO HERE: tap ``pose`` on the map, CONFIRM (switches to AUTO when needed)."""
    page.click("#go-here")
    x, y = screen_point(page, pose.x_m, pose.y_m)
    page.mouse.click(x, y)
    page.click("#goal-go")


def test_goals_missions_refusals_localization_battery_and_offline_are_said(tired_robot_site, page, helpers, shots):
    """What a carer meets while the robot works: a refusal, a mission finished, a goal reached and one failed, the
    robot lost and found, the battery low, and the robot gone offline, each provoked on the running robot."""
    site = tired_robot_site
    alerts = open_control(page, site, helpers)

    # a refusal: a mission started in MANUAL
    alerts.start()
    page.select_option("#mission-select", "look-around")
    page.click("#mission-start")
    alerts.said("Start mission: switch to AUTO first")
    assert site.agent_state == "IDLE.MANUAL"

    # a mission finished: in AUTO, the same mission (four photos, turning on the spot)
    page.click("#mode-toggle")
    wait_for(page, "document.getElementById('mode-toggle').textContent === 'AUTO'")
    alerts.start()
    page.click("#mission-start")
    alerts.said("Mission 'look-around' finished.", timeout=40_000)
    # the line above the map ends with the mission too (it kept "On the way: 0.1 m left" after a mission's last goal)
    assert page.inner_text("#goal-progress") == "Mission 'look-around' finished."

    # a goal reached: GO HERE 1 m ahead
    start = site.sim.pose
    alerts.start()
    go_here(page, Pose2D(start.x_m + 1.0, start.y_m, 0.0))
    alerts.said("Goal reached.", timeout=30_000)

    # a refusal on the map: GO HERE onto the sofa
    alerts.start()
    go_here(page, Pose2D(0.6, 2.2, 0.0))
    alerts.said("Go here: That spot is inside a wall or a piece of furniture on the map. Tap a free spot.")
    page.click("#goal-cancel")
    alerts.plain()

    # a goal that fails: something stands on the spot (not on the map, so the goal is taken), the goal times out
    spot = Pose2D(2.4, 3.4, math.pi / 2)  # the living room's place, free on the map
    on_map(page, "#sim-obstacle", spot)
    alerts.start()
    go_here(page, spot)
    alerts.said("Goal failed: the robot did not get there in time; something may be in the way. Look at the camera, "
                "then send it again.", timeout=40_000)
    # the goal's acknowledgement gives way to its outcome: "accepted" beside "Goal failed" read as stale
    assert page.inner_text("#command-result").startswith("Go here: Goal failed: the robot did not get there")
    assert page.get_attribute("#command-result", "class") == "hint error"
    page.screenshot(path=str(shots / "alerts-goal-failed.png"))
    alerts.plain()

    # lost and found: carried off to the bedroom (the simulation panel), then FIND POSITION
    wait_for(page, "document.getElementById('agent-state').dataset.state === 'IDLE'", timeout=15_000)
    alerts.start()
    on_map(page, "#sim-kidnap", Pose2D(6.3, 1.5, 0.0))
    alerts.said("The robot is no longer sure where it is.", timeout=20_000)
    alerts.plain()
    alerts.start()
    page.click("#localize-global")
    alerts.said("The robot knows where it is", timeout=20_000)
    assert page.inner_text("#command-result").startswith("Find position: The robot knows where it is")
    truth = site.sim.pose
    wait_for(page, f"Math.hypot(ATEMR.state.pose.x_m - {truth.x_m}, ATEMR.state.pose.y_m - {truth.y_m}) < 0.3")

    # the battery runs low: the pack loses a few percent (as a while of driving would)
    pack = site.robot.parts.sim_battery
    assert pack is not None
    alerts.start()
    site.sim.submit(lambda: setattr(pack, "energy_wh", pack.capacity_wh * 0.17))
    alerts.said("Battery low", timeout=30_000)
    wait_for(page, "document.getElementById('battery').classList.contains('warning')")
    alerts.plain()

    # offline: the robot's process ends, the page stays
    alerts.start()
    site.pause()
    alerts.said("The robot is offline: no state is coming. Driving is off until it is back.", timeout=5_000)
    page.screenshot(path=str(shots / "alerts-offline.png"))
