"""The battery on the robot: `BatteryWatch` turns the motors' supply-voltage readings (status 1, 0x9A, which
the motor driver polls) into a state of charge (`atemr.skills.battery.BatteryEstimator`) and reacts at the
configured limits (``battery.*_percent``):

* below ``warn_percent`` (20 %) it warns (an event, so the dashboard's alerts and the recording have it);
* below ``return_percent`` (10 %) it ends the task the agent runs (``cancel``) and, in AUTO, sends the robot
  to its dock (the active map's ``dock`` place, ``home``) as a one-step mission; in MANUAL it asks the operator
  to drive it home;
* below ``critical_percent`` (5 %) it stops the robot where it is (the task cancelled, MANUAL) and reports
  critical.

Each limit fires once on the way down and is re-armed when the charge is back above it by 5 points (on the
dock), so a reading that wobbles round a limit does not repeat the reaction. Readings the estimator rejects
(NaN, 0, impossible jumps) are counted and never acted on.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

from atemr.domain.places import Places
from atemr.errors import ConfigError
from atemr.fsm.agent import Agent
from atemr.io.motors.driver import RmdDriver
from atemr.skills.battery import BatteryEstimator, BatteryParams
from atemr.trees.missions import parse_mission

#: How often the watch reads the motors' voltages (the driver polls status 1 every 0.2 s).
RATE_HZ = 2.0
#: Points above a limit the charge must climb back before that limit acts again.
REARM_POINTS = 5.0
Level = Literal["ok", "low", "return", "critical"]


class BatteryWatch:
    """See the module docstring; a scheduler component after the agent."""

    name = "battery"

    def __init__(self, params: BatteryParams, driver: RmdDriver, agent: Agent, *, places: Callable[[], Places],
                 event: Callable[[str, str], None]) -> None:
        self.params = params
        self.driver = driver
        self.agent = agent
        self.places = places
        self.event = event
        self.estimator = BatteryEstimator(params)
        self.level: Level = "ok"
        self._fired: set[Level] = set()
        self._going_home = False

    @property
    def percent(self) -> float | None:
        latest = self.estimator.latest
        return None if latest is None else latest.percent

    def forbids_task(self) -> str | None:
        """Why no new task should start on this charge (below the return limit), else None."""
        percent = self.percent
        if percent is not None and percent < self.params.return_percent:
            return f"battery {percent:.0f} %"
        return None

    def tick(self, now: float) -> None:
        motors = [(s.current_a, s.speed_radps) for s in self.driver.states.values()]
        for state in self.driver.states.values():
            if state.last_reply_t is None:
                continue  # no reply yet: nothing was measured, nothing to reject
            why = self.estimator.update(now, state.voltage_v, motors)
            if why is not None and self.estimator.rejected in (1, 10, 100, 1000):
                self.event("battery", f"reading rejected ({self.estimator.rejected} so far): {why}")
        percent = self.percent
        if percent is None:
            return
        self._rearm(percent)
        p = self.params
        if percent < p.critical_percent:
            self._react("critical", percent)
        elif percent < p.return_percent:
            self._react("return", percent)
        elif percent < p.warn_percent:
            self._react("low", percent)
        else:
            self.level = "ok"
        if self._going_home and self.agent.state == "IDLE.AUTO":
            self._send_home()

    def _rearm(self, percent: float) -> None:
        limits: dict[Level, float] = {"low": self.params.warn_percent, "return": self.params.return_percent,
                                      "critical": self.params.critical_percent}
        for level, limit in limits.items():
            if level in self._fired and percent >= limit + REARM_POINTS:
                self._fired.discard(level)

    def _react(self, level: Level, percent: float) -> None:
        self.level = level
        if level in self._fired:
            return
        self._fired.add(level)
        state = self.agent.state
        if level == "low":
            self.event("battery", f"battery low: {percent:.0f} %")
            return
        if state.startswith("EXEC"):
            self.agent.submit("cancel", origin="battery")
        if level == "critical":
            self._going_home = False
            self.agent.submit("set_manual", origin="battery")
            self.event("battery", f"battery critical: {percent:.0f} %, stopped where it is; charge it now")
            return
        if state.endswith("MANUAL"):
            self.event("battery", f"battery {percent:.0f} %: drive the robot to its dock to charge")
            return
        self._going_home = True
        self.event("battery", f"battery {percent:.0f} %: the task ends and the robot goes home to charge")

    def _send_home(self) -> None:
        self._going_home = False
        dock = self.places().dock()
        if dock is None:
            self.event("battery", "no dock on this map (a place of kind dock, or 'home'): drive the robot to charge")
            return
        try:
            mission = parse_mission({"mission": {"name": f"to {dock.name} to charge",
                                                 "steps": [{"go_to": {"place": dock.name}}]}})
        except ConfigError as exc:
            self.event("battery", f"cannot go home: {exc.reason}")
            return
        self.agent.submit("start_mission", origin="battery", mission=mission)


__all__ = ["RATE_HZ", "REARM_POINTS", "BatteryWatch"]
