"""Every leaf through the py_trees lifecycle (setup → initialise → update → terminate) on fake ports.

`test_every_registered_leaf_follows_the_lifecycle` is parametrised over the registry: a new leaf without a
sample in `SAMPLES` fails, so no behaviour is registered without being exercised.
"""

from __future__ import annotations

import math
from typing import Any

import py_trees
import pytest

from atemr.domain.places import Place, Places
from atemr.domain.status import AtReturn, BatteryStatus, ComponentHealth, PowerState, StateCode
from atemr.errors import AtemrError, ConfigError, HardwareError
from atemr.msgs import ZERO_TWIST, Pose2D, Twist
from atemr.trees.behaviours import Leaf, behaviours, parse_params
from atemr.trees.context import AgentContext
from atemr.trees.fakes import RecordingLink, RecordingPort, StraightLineNavigation
from atemr.trees.leaves.checks import ClassifyError
from atemr.trees.missions import Mission
from atemr.trees.nodes import ClockTimeout
from atemr.typed import Source

Status = py_trees.common.Status

#: Parameters each registered leaf is exercised with.
SAMPLES: dict[str, dict[str, Any]] = {
    "Wait": {"duration_s": 0.3},
    "StopMotors": {},
    "DriveJoystick": {},
    "Rotate": {"angle_rad": 0.5},
    "CheckComponent": {"component": "lidar", "timeout_s": 0.3},
    "CheckHeartbeat": {"timeout_s": 0.3},
    "ClassifyError": {},
    "AwaitRecovery": {},
    "SetMode": {"mode": "AUTO"},
    "CaptureImage": {"label": "door"},
    "SetPowerState": {"state": "running"},
    "Halt": {},
    "PublishStatus": {},
    "WatchPowerRequest": {},
    "WatchHeartbeat": {},
    "WatchHealth": {"components": ["left_motor"]},
    "WatchBattery": {},
    "GoToPose": {"x_m": 1.0, "y_m": 0.5, "yaw_rad": 0.3},
    "GoToPlace": {"place": "kitchen"},
    "FollowPath": {"points": [[1.0, 0.0], [1.0, 1.0]]},
    "Relocalize": {"timeout_s": 0.3},
    "StartMapping": {},
    "SaveMap": {"name": "flat"},
    "StopMapping": {},
}
#: Leaves that command a velocity, and on which mux input.
DRIVING = {"DriveJoystick": "joystick", "Rotate": "agent", "GoToPose": "navigation", "FollowPath": "navigation",
           "GoToPlace": "navigation"}
#: The places the benches' navigation knows (the active map's, on a robot).
PLACES = Places([Place("kitchen", Pose2D(1.0, 0.5, 1.0)), Place("home", Pose2D(0.0, 0.0, 0.0), "dock")])


class Bench:
    """One leaf with a context on fake ports, ticked by hand at 10 Hz."""

    def __init__(self, leaf: Leaf, *, port: RecordingPort | None = None, link: RecordingLink | None = None,
                 state: str = "IDLE.MANUAL") -> None:
        self.port = port or RecordingPort(dt_s=0.1)
        self.link = link if link is not None else RecordingLink()
        self.navigation = StraightLineNavigation(self.port, known_places=PLACES)
        self.ctx = AgentContext(port=self.port, link=self.link, state=state, navigation=self.navigation)
        self.link.time_source = lambda: self.ctx.now
        self.leaf = leaf
        py_trees.trees.setup(leaf, context=self.ctx)

    def tick(self, n: int = 1) -> py_trees.common.Status:
        for _ in range(n):
            for _node in self.leaf.tick():
                pass
            self.ctx.now = round(self.ctx.now + 0.1, 9)
        return self.leaf.status


def make(name: str, /, **params: Any) -> Leaf:
    cls = behaviours.get(name)
    return cls(name, parse_params(cls.Params, params or SAMPLES[name], Source("argument"), "params"))


def test_every_registered_leaf_has_a_sample() -> None:
    assert sorted(behaviours) == sorted(SAMPLES), "add a sample (and a lifecycle test) for each new leaf"


@pytest.mark.parametrize("name", sorted(SAMPLES))
def test_every_registered_leaf_follows_the_lifecycle(name: str) -> None:
    leaf = make(name)
    with pytest.raises(ConfigError, match="before setup"):
        _ = leaf.ctx
    bench = Bench(leaf)
    status = bench.tick(5)
    assert status in (Status.RUNNING, Status.SUCCESS, Status.FAILURE)
    if status == Status.RUNNING:
        leaf.stop(Status.INVALID)
        assert leaf.status == Status.INVALID
    if name in DRIVING:
        assert bench.port.commands, f"{name} drives the base"
        assert bench.port.commands[-1][0] == DRIVING[name] and bench.port.commands[-1][1] == Twist()
    assert bench.tick() in (Status.RUNNING, Status.SUCCESS, Status.FAILURE), "runs again after a stop"


def test_wait_uses_the_injected_clock() -> None:
    bench = Bench(make("Wait", duration_s=0.3))
    assert [bench.tick() for _ in range(4)] == [Status.RUNNING] * 3 + [Status.SUCCESS]
    assert bench.tick() == Status.RUNNING, "initialise restarts the wait"


def test_stop_motors() -> None:
    bench = Bench(make("StopMotors"))
    assert bench.tick() == Status.SUCCESS and bench.port.stops == 1


def test_drive_joystick_forwards_fresh_commands_only() -> None:
    bench = Bench(make("DriveJoystick", timeout_s=0.25))
    bench.port.joystick_command = (Twist(0.5, -0.2), 0.0)
    assert bench.tick() == Status.RUNNING
    assert bench.port.commands[-1] == ("joystick", Twist(0.5, -0.2), 0.0)
    bench.tick(3)
    assert bench.port.commands[-1][1] == Twist(), "older than timeout_s counts as absent"
    bench.port.joystick_command = (Twist(0.2, 0.0), bench.ctx.now)
    bench.tick()
    bench.leaf.stop(Status.INVALID)
    assert bench.port.commands[-1][1] == Twist()


def test_drive_joystick_turns_to_look_around_after_an_ambiguous_find_position() -> None:
    """While the operator's FIND POSITION asks to look around, the robot turns in place on the joystick input;
    the operator's fresh joystick wins; when the localizer stops asking (a revolution, a time limit, the operator
    taking over) the turn stops. ``look_speed_radps: 0`` (MAPPING's) never turns."""
    port = RecordingPort(look_asked=True)
    bench = Bench(make("DriveJoystick", timeout_s=0.25), port=port)
    bench.tick()
    assert port.commands[-1] == ("joystick", Twist(0.0, 0.4), 0.0)
    assert "looking around" in bench.leaf.feedback_message
    port.joystick_command = (Twist(0.3, 0.0), bench.ctx.now)  # the operator drives: the joystick wins
    bench.tick()
    assert port.commands[-1][1] == Twist(0.3, 0.0) and "looking" not in bench.leaf.feedback_message
    port.look_asked = False  # the localizer no longer asks
    bench.tick(4)
    assert port.commands[-1][1] == Twist()
    still = RecordingPort(look_asked=True)
    Bench(make("DriveJoystick", look_speed_radps=0.0), port=still).tick(5)
    assert {c[1] for c in still.commands} == {Twist()}


def test_rotate_turns_by_the_angle_through_the_wrap() -> None:
    port = RecordingPort(current_pose=Pose2D(0, 0, math.pi - 0.2), dt_s=0.1)
    bench = Bench(make("Rotate", angle_rad=math.pi), port=port)
    for _ in range(100):
        if bench.tick() != Status.RUNNING:
            break
    assert bench.leaf.status == Status.SUCCESS
    assert port.current_pose is not None
    turned = port.current_pose.yaw_rad - (math.pi - 0.2)
    assert abs(turned - math.pi) <= 0.05
    assert max(abs(c[1].angular_radps) for c in port.commands) <= 0.8
    assert port.commands[-1][1] == Twist()


def test_rotate_fails_without_a_pose() -> None:
    bench = Bench(make("Rotate", angle_rad=1.0), port=RecordingPort(current_pose=None))
    assert bench.tick() == Status.FAILURE and bench.leaf.reason == "no pose to steer by"


def test_check_component_waits_then_fails_with_a_typed_error() -> None:
    port = RecordingPort()
    port.components["lidar"] = ComponentHealth(False, "no scans")
    bench = Bench(make("CheckComponent", component="lidar", timeout_s=0.3), port=port)
    assert [bench.tick() for _ in range(3)] == [Status.RUNNING] * 3
    assert bench.tick() == Status.FAILURE
    error = bench.ctx.error
    assert isinstance(error, HardwareError) and error.critical and error.component == "lidar"
    assert "no scans after 0.3 s" in bench.leaf.reason
    port.components["lidar"] = ComponentHealth(True)
    assert bench.tick() == Status.SUCCESS


def test_check_heartbeat() -> None:
    link = RecordingLink(heartbeat=False)
    bench = Bench(make("CheckHeartbeat", timeout_s=0.1), link=link)
    assert bench.tick() == Status.RUNNING
    link.heartbeat = True
    assert bench.tick() == Status.SUCCESS


@pytest.mark.parametrize(("error", "expected"), [
    (None, Status.SUCCESS),
    (HardwareError("silent", component="left_motor"), Status.SUCCESS),
    (HardwareError("silent", component="left_motor", critical=True), Status.FAILURE),
    (AtemrError("unknown"), Status.SUCCESS),
])
def test_classify_error_by_type_and_flag(error: AtemrError | None, expected: py_trees.common.Status) -> None:
    bench = Bench(ClassifyError("classify"))
    bench.ctx.error = error
    assert bench.tick() == expected


def test_await_recovery_succeeds_at_once_for_an_error_without_a_lasting_cause() -> None:
    for error in (None, AtemrError("goal outside the map"), HardwareError("no frame", component="no_such_part")):
        bench = Bench(make("AwaitRecovery"))
        bench.ctx.error = error
        assert bench.tick() == Status.SUCCESS
        assert bench.port.fault_clears == 0


def test_await_recovery_holds_while_the_heartbeat_is_lost() -> None:
    bench = Bench(make("AwaitRecovery"), link=RecordingLink(heartbeat=False))
    bench.ctx.error = HardwareError("heartbeat 0x157 lost", component="secondary_core")
    assert bench.tick(20) == Status.RUNNING
    assert "heartbeat 0x157 still lost" in bench.leaf.feedback_message
    bench.link.heartbeat = True
    assert bench.tick() == Status.SUCCESS


def test_await_recovery_clears_latched_faults_and_waits_for_the_component() -> None:
    bench = Bench(make("AwaitRecovery"))
    bench.ctx.error = HardwareError("silent for 0.31 s", component="left_motor")
    bench.port.components["left_motor"] = ComponentHealth(False, "motors: left motor (id 1) silent")
    bench.port.faults_latched = "motors: left motor (id 1) not answering"
    assert bench.tick(5) == Status.RUNNING
    assert bench.port.fault_clears == 5, "asks the robot to clear the latched fault every tick"
    assert "left motor (id 1) not answering" in bench.leaf.feedback_message
    # the fault is cleared (nothing latched any more) but the component is not healthy yet: still waiting
    bench.port.faults_latched = None
    assert bench.tick() == Status.RUNNING
    assert "silent" in bench.leaf.feedback_message
    bench.port.components["left_motor"] = ComponentHealth(True)
    assert bench.tick() == Status.SUCCESS


def test_set_mode_and_capture_image() -> None:
    bench = Bench(make("SetMode", mode="AUTO"))
    assert bench.tick() == Status.SUCCESS and bench.port.modes == ["AUTO"] and bench.ctx.mode == "AUTO"
    camera = Bench(make("CaptureImage", label="kitchen"))
    assert camera.tick() == Status.SUCCESS and camera.port.images == ["images/kitchen-0.jpg"]
    camera.port.camera_ok = False
    assert camera.tick() == Status.FAILURE and "camera: no frame" in camera.leaf.reason  # type: ignore[attr-defined]
    with pytest.raises(ConfigError, match="label must be"):
        make("CaptureImage", label="../x")


def test_power_state_and_halt() -> None:
    bench = Bench(make("SetPowerState", state="poweroff_ack"))
    assert bench.tick() == Status.SUCCESS and bench.link.power_states == [(0.0, PowerState.POWER_OFF_ACK)]
    lonely = make("SetPowerState", state="running")
    port = RecordingPort()
    ctx = AgentContext(port=port, link=None)
    py_trees.trees.setup(lonely, context=ctx)
    for _ in lonely.tick():
        pass
    assert lonely.status == Status.FAILURE and "no secondary-core link" in lonely.reason
    halt = Bench(make("Halt"))
    assert halt.tick() == Status.SUCCESS and halt.ctx.halted


def test_publish_status_periodic_and_on_change() -> None:
    bench = Bench(make("PublishStatus", period_s=0.5), state="STARTUP")
    bench.tick(10)
    times = [t for t, _ in bench.link.statuses]
    assert times == [0.0, 0.5]
    assert bench.link.statuses[0][1].state == StateCode.STARTUP
    bench.ctx.state = "IDLE.AUTO"
    bench.tick()
    assert bench.link.statuses[-1] == (1.0, bench.link.statuses[-1][1])
    assert bench.link.statuses[-1][1].state == StateCode.IDLE
    status = bench.link.statuses[-1][1]
    assert status.hardware_ok() == dict.fromkeys(status.hardware_ok(), True)
    assert status.agent_ok()["HEARTBEAT"] and status.agent_ok()["HARDWARE"] and not status.agent_ok()["LOCALIZATION"]


def test_watch_power_request_posts_once_per_request() -> None:
    bench = Bench(make("WatchPowerRequest"))
    bench.tick(2)
    assert bench.ctx.take_events() == []
    bench.link.power_off = True
    bench.tick(3)
    events = bench.ctx.take_events()
    assert [e.trigger for e in events] == ["power_off"] and "0x150" in events[0].reason


def test_watch_heartbeat_only_in_active_states() -> None:
    bench = Bench(make("WatchHeartbeat"), state="STARTUP")
    bench.link.heartbeat = False
    bench.tick(2)
    assert bench.ctx.take_events() == []
    bench.ctx.state = "EXEC"
    bench.tick(3)
    events = bench.ctx.take_events()
    assert [e.trigger for e in events] == ["fault"]
    assert isinstance(events[0].kwargs["error"], HardwareError) and not events[0].kwargs["error"].critical


def test_watch_health_reports_each_onset() -> None:
    bench = Bench(make("WatchHealth", components=["left_motor", "right_motor"], critical=True))
    bench.tick()
    bench.port.components["left_motor"] = ComponentHealth(False, "over-temperature")
    bench.tick(3)
    events = bench.ctx.take_events()
    assert len(events) == 1 and events[0].kwargs["error"].critical
    assert "left_motor: over-temperature" in events[0].reason
    bench.port.components["left_motor"] = ComponentHealth(True)
    bench.tick()
    bench.port.components["left_motor"] = ComponentHealth(False, "again")
    bench.tick()
    assert len(bench.ctx.take_events()) == 1


def charge(percent: float, at_return: AtReturn = "cancel") -> BatteryStatus:
    """The battery at ``percent`` with the shipped limits: warn 20 %, return 10 %, critical 5 %."""
    return BatteryStatus(percent, 26.0, warn_percent=20.0, return_percent=10.0, critical_percent=5.0,
                         at_return=at_return)


@pytest.mark.parametrize(("state", "at_return", "percent", "triggers", "said"), [
    ("EXEC", "cancel", 50.0, [], None),
    ("EXEC", "cancel", 18.0, [], "Battery low: 18 %. Let it charge soon: at 10 % it ends its task and goes home"),
    ("EXEC", "cancel", 9.0, ["cancel"], "Battery 9 %: the task ends and the robot goes home to charge"),
    ("EXEC", "finish", 9.0, [], "Battery 9 %: the task finishes, then the robot goes home to charge"),
    ("IDLE.AUTO", "cancel", 9.0, ["start_mission"], "Battery 9 %: the robot goes home to charge"),
    ("IDLE.MANUAL", "cancel", 9.0, [], "Battery 9 %: drive the robot to its dock to charge"),
    ("MAPPING", "finish", 9.0, [], "Battery 9 %: drive the robot to its dock to charge"),
    ("EXEC", "finish", 4.0, ["cancel", "set_manual"], "Battery critical: 4 %, stopped where it is; charge it now"),
    ("IDLE.AUTO", "cancel", 4.0, ["set_manual"], "Battery critical: 4 %, stopped where it is; charge it now"),
    ("IDLE.MANUAL", "cancel", 4.0, [], "Battery critical: 4 %, stopped where it is; charge it now"),
    ("STARTUP", "cancel", 4.0, [], None),
    ("ERROR", "cancel", 9.0, [], None),
])
def test_watch_battery_reacts_at_each_limit(state: str, at_return: AtReturn, percent: float, triggers: list[str],
                                            said: str | None) -> None:
    bench = Bench(make("WatchBattery"), state=state)
    bench.port.battery_status = charge(percent, at_return)
    assert bench.tick(3) == Status.RUNNING
    assert [e.trigger for e in bench.ctx.take_events()] == triggers
    assert bench.port.reports == ([] if said is None else [("battery", said)])


def test_watch_battery_without_a_reading_does_nothing() -> None:
    bench = Bench(make("WatchBattery"), state="EXEC")
    assert bench.tick(3) == Status.RUNNING and bench.leaf.feedback_message == "no battery reading yet"
    assert bench.ctx.take_events() == [] and bench.port.reports == []


@pytest.mark.parametrize("at_return", ["cancel", "finish"])
def test_watch_battery_sends_the_robot_home_once_the_task_is_over(at_return: AtReturn) -> None:
    bench = Bench(make("WatchBattery"), state="EXEC")
    bench.port.battery_status = charge(9.0, at_return)
    bench.tick()
    assert [e.trigger for e in bench.ctx.take_events()] == (["cancel"] if at_return == "cancel" else [])
    bench.tick(20)  # the task runs on (finish) or is being cancelled: nothing more until the robot idles
    assert bench.ctx.take_events() == []
    bench.ctx.state = "IDLE.AUTO"
    bench.tick()
    events = bench.ctx.take_events()
    assert [e.trigger for e in events] == ["start_mission"] and "going home to charge" in events[0].reason
    mission = events[0].kwargs["mission"]
    assert isinstance(mission, Mission) and mission.place_names() == ["home"]
    bench.tick(10)
    assert bench.ctx.take_events() == [], "it goes home once"


def test_watch_battery_asks_the_operator_when_the_robot_was_taken_in_manual() -> None:
    bench = Bench(make("WatchBattery"), state="EXEC")
    bench.port.battery_status = charge(9.0, "finish")
    bench.tick()
    bench.ctx.state = "IDLE.MANUAL"  # the operator took the robot before the task ended
    bench.tick()
    bench.ctx.state = "IDLE.AUTO"
    bench.tick(3)
    assert bench.ctx.take_events() == []
    assert bench.port.reports[-1] == ("battery", "Battery 9 %: drive the robot to its dock to charge")


def test_watch_battery_says_so_when_the_map_has_no_dock() -> None:
    bench = Bench(make("WatchBattery"), state="IDLE.AUTO")
    bench.navigation.known_places = Places([Place("kitchen", Pose2D(1.0, 0.5, 1.0))])
    bench.port.battery_status = charge(9.0)
    bench.tick(2)
    assert bench.ctx.take_events() == []
    assert bench.port.reports[-1] == ("battery", "Battery 9 %: cannot go home: no dock on this map (a place of kind "
                                                 "dock, or 'home'): drive the robot to charge")


def test_watch_battery_acts_once_per_limit_until_charged_past_it() -> None:
    bench = Bench(make("WatchBattery"), state="IDLE.MANUAL")
    said: list[str] = []
    for percent in (22.0, 19.0, 19.5, 18.0, 9.0, 8.0, 12.0, 14.0, 19.0, 24.0, 26.0, 19.0):
        bench.port.battery_status = charge(percent)
        bench.tick()
        said += [text for _, text in bench.port.reports]
        bench.port.reports.clear()
    # 19 %: low; 9 %: home; charging on the dock past 10 and 20 says nothing; 15 % re-arms the return limit,
    # 25 % the warning, so the next fall below 20 % warns again
    low = "Battery low: 19 %. Let it charge soon: at 10 % it ends its task and goes home"
    assert said == [low, "Battery 9 %: drive the robot to its dock to charge", low]


def test_watch_health_reports_a_component_that_turned_bad_while_in_error_once_back() -> None:
    """In Error for a motor, the CAN bus fails: back in Idle, the bus is a fault of its own (its recovery runs
    only in Error), not an onset missed for good. One that healed meanwhile is nothing."""
    bench = Bench(make("WatchHealth", components=["can_bus", "left_motor"]))
    bench.tick()
    bench.port.components["left_motor"] = ComponentHealth(False, "silent")
    bench.tick()
    assert [e.reason for e in bench.ctx.take_events()] == ["left_motor: silent"]
    bench.ctx.state = "ERROR"
    bench.port.components["can_bus"] = ComponentHealth(False, "bus-off")
    bench.tick(3)
    assert bench.ctx.take_events() == []  # the agent handles one error at a time
    bench.port.components["left_motor"] = ComponentHealth(True)
    bench.tick()
    bench.ctx.state = "IDLE.MANUAL"
    bench.tick(3)
    assert [e.reason for e in bench.ctx.take_events()] == ["can_bus: bus-off"]
    bench.ctx.state = "ERROR"
    bench.port.components["left_motor"] = ComponentHealth(False, "silent")
    bench.tick()
    bench.port.components["left_motor"] = ComponentHealth(True)
    bench.ctx.state = "IDLE.MANUAL"
    bench.tick(2)
    assert bench.ctx.take_events() == []


def test_clock_timeout_stops_its_child_on_the_agent_clock() -> None:
    child = make("Rotate", angle_rad=12.0)
    timeout = ClockTimeout("limit", child, 0.35)
    bench = Bench(timeout)  # type: ignore[arg-type]
    assert [bench.tick() for _ in range(4)] == [Status.RUNNING] * 4
    assert bench.tick() == Status.FAILURE and child.status == Status.INVALID
    assert bench.port.commands[-1][1] == Twist()
    assert "timed out after 0.35 s" in timeout.feedback_message


def test_go_to_pose_drives_through_navigation_to_the_goal() -> None:
    bench = Bench(make("GoToPose", x_m=1.0, y_m=0.0, yaw_rad=0.5))
    statuses = [bench.tick()]
    while statuses[-1] == Status.RUNNING and len(statuses) < 50:
        statuses.append(bench.tick())
    assert statuses == [Status.RUNNING] * 21 + [Status.SUCCESS], "1 m at 0.5 m/s in 0.1 s ticks"
    assert bench.navigation.goals == [Pose2D(1.0, 0.0, 0.5)] and bench.port.current_pose == Pose2D(1.0, 0.0, 0.5)
    driving = [c for c in bench.port.commands if c[0] == "navigation"]
    assert driving[0][1] == Twist(0.5, 0.0) and driving[-1][1] == Twist()
    assert bench.navigation.cancels == [], "a finished goal is not cancelled"


def test_go_to_pose_refused_failed_and_interrupted() -> None:
    refused = Bench(make("GoToPose", x_m=9.0, y_m=9.0))
    refused.navigation.refuse = "goal (9.00, 9.00, 0.00 rad) is outside the map"
    assert refused.tick() == Status.FAILURE and refused.leaf.reason == \
        "goal refused: goal (9.00, 9.00, 0.00 rad) is outside the map"
    stuck = Bench(make("GoToPose", x_m=9.0, y_m=9.0))
    stuck.navigation.fail_after_s = 0.3
    assert [stuck.tick() for _ in range(4)][-1] == Status.FAILURE
    assert stuck.leaf.reason == "navigation failed: stuck" and stuck.port.commands[-1][1] == Twist()
    moving = Bench(make("GoToPose", x_m=9.0, y_m=9.0))
    moving.tick(3)
    moving.leaf.stop(Status.INVALID)
    assert moving.navigation.cancels == [0.3] and moving.port.commands[-1][1] == Twist()
    lonely = make("GoToPose", x_m=1.0, y_m=1.0)
    ctx = AgentContext(port=RecordingPort())
    py_trees.trees.setup(lonely, context=ctx)
    for _ in lonely.tick():
        pass
    assert lonely.status == Status.FAILURE and lonely.reason == "navigation is not available on this robot"


def test_go_to_place_looks_the_place_up_when_it_starts() -> None:
    bench = Bench(make("GoToPlace", place="KITCHEN"))
    for _ in range(60):
        if bench.tick() != Status.RUNNING:
            break
    assert bench.leaf.status == Status.SUCCESS and bench.navigation.goals == [Pose2D(1.0, 0.5, 1.0)]
    bench.navigation.known_places = PLACES.with_place(Place("kitchen", Pose2D(2.0, 0.5, 0.0)), replace=True)
    bench.tick()  # a place moved on the dashboard: the next start goes to where it is now
    assert bench.navigation.goals[-1] == Pose2D(2.0, 0.5, 0.0)
    gone = Bench(make("GoToPlace", place="kichen"))
    gone.navigation.known_places = PLACES.without("kitchen").with_place(Place("kitchenette", Pose2D(3, 3, 0)))
    assert gone.tick() == Status.FAILURE and gone.navigation.goals == []
    assert gone.leaf.reason == "goal refused: no place named 'kichen' on this map (closest: kitchenette)"


def test_relocalize_waits_for_localization() -> None:
    bench = Bench(make("Relocalize", timeout_s=0.3), port=RecordingPort(is_localized=True))
    assert bench.tick() == Status.RUNNING and bench.port.relocalizations == [0.0]
    bench.port.is_localized = True
    assert bench.tick() == Status.SUCCESS
    lost = Bench(make("Relocalize", timeout_s=0.3), port=RecordingPort(is_localized=False))
    assert [lost.tick() for _ in range(4)] == [Status.RUNNING] * 3 + [Status.FAILURE]
    assert lost.leaf.reason == "not localized after 0.3 s"
    unable = Bench(make("Relocalize"), port=RecordingPort(is_localized=None))
    assert unable.tick() == Status.FAILURE
    assert unable.leaf.reason == "cannot relocalize: localization is not available in this build"


def test_relocalize_turns_in_place_while_ambiguous_and_stops_once_localized() -> None:
    """Look-alike places: the robot turns (on the agent's input) to see more, stops turning when the search
    decides, and never turns more than one revolution; a search that is not ambiguous, or ``turn: false``,
    waits without moving."""
    port = RecordingPort(is_localized=False, unlocalized_state="ambiguous", dt_s=0.5)
    bench = Bench(make("Relocalize", timeout_s=60.0), port=port)
    assert [bench.tick() for _ in range(3)] == [Status.RUNNING] * 3
    assert [c[:2] for c in port.commands] == [("agent", Twist(0.0, 0.4))] * 3
    assert "ambiguous: turning" in bench.leaf.feedback_message
    port.is_localized = True
    assert bench.tick() == Status.SUCCESS
    assert port.commands[-1][:2] == ("agent", ZERO_TWIST)
    # at most one revolution: 0.4 rad/s x 0.5 s a tick is 0.2 rad a tick, 2 pi after 32 ticks
    port = RecordingPort(is_localized=False, unlocalized_state="ambiguous", dt_s=0.5)
    bench = Bench(make("Relocalize", timeout_s=60.0), port=port)
    for _ in range(40):
        assert bench.tick() == Status.RUNNING
    turning = [c for c in port.commands if c[1].angular_radps > 0]
    assert len(turning) == 32 and port.commands[-1][1] == ZERO_TWIST
    assert port.current_pose is not None and abs(port.current_pose.yaw_rad - 32 * 0.2) < 1e-9
    for state, turn in (("searching", True), ("ambiguous", False)):
        still = RecordingPort(is_localized=False, unlocalized_state=state, dt_s=0.5)
        waiting = Bench(make("Relocalize", timeout_s=60.0, turn=turn), port=still)
        assert [waiting.tick() for _ in range(3)] == [Status.RUNNING] * 3 and still.commands == []


def test_follow_path_drives_the_route_in_order_to_its_last_point() -> None:
    bench = Bench(make("FollowPath", points=[[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]))
    statuses = [bench.tick()]
    while statuses[-1] == Status.RUNNING and len(statuses) < 100:
        statuses.append(bench.tick())
    assert statuses[-1] == Status.SUCCESS
    # The last point is the goal, heading along the last stretch (-x); the others are the route.
    assert bench.navigation.goals == [Pose2D(0.0, 1.0, math.pi)]
    assert bench.navigation.routes == [[(1.0, 0.0), (1.0, 1.0)]]
    assert len(statuses) > 60, "3 m of route at 0.5 m/s, not the 1 m straight line"
    assert bench.port.commands[-1] == ("navigation", Twist(), pytest.approx(bench.ctx.now - 0.1))
    one = Bench(make("FollowPath", points=[[2.0, 0.0]], yaw_rad=1.0))
    one.tick()
    assert one.navigation.goals == [Pose2D(2.0, 0.0, 1.0)] and one.navigation.routes == [[]]


@pytest.mark.parametrize(("params", "message"), [
    ({"points": []}, "at least one point"),
    ({"points": [[1.0, 2.0, 3.0]]}, r"points\[0\] must be \[x_m, y_m\]"),
    ({"points": [[1.0, "north"]]}, "params.points: expected a number, got 'north'"),
    ({"points": [[1.0, 2e4]]}, "within 10 km"),
    ({}, "needs at least one point"),
])
def test_follow_path_parameters_are_checked(params: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_params(behaviours.get("FollowPath").Params, params, Source("argument"), "params")


def test_follow_path_refused_and_interrupted() -> None:
    refused = Bench(make("FollowPath"))
    refused.navigation.refuse = "route passes through or too close to an obstacle near (1.00, 0.50)"
    assert refused.tick() == Status.FAILURE
    assert refused.leaf.reason == "goal refused: route passes through or too close to an obstacle near (1.00, 0.50)"
    moving = Bench(make("FollowPath"))
    moving.tick(3)
    moving.leaf.stop(Status.INVALID)
    assert moving.navigation.cancels == [0.3] and moving.port.commands[-1][1] == Twist()


def test_mapping_leaves_start_save_and_drop_a_session() -> None:
    bench = Bench(make("StartMapping"), port=RecordingPort(dt_s=0.1, mapping_available=True))
    assert bench.tick() == Status.SUCCESS and bench.port.mapping and bench.ctx.mapping_active
    assert bench.tick() == Status.SUCCESS, "already mapping is fine"
    save = make("SaveMap", name="flat-2")
    py_trees.trees.setup(save, context=bench.ctx)
    for _ in save.tick():
        pass
    assert save.status == Status.SUCCESS and bench.port.maps == ["flat-2"] and not bench.ctx.mapping_active
    for _ in save.tick():
        pass
    assert save.status == Status.FAILURE and save.reason == "no mapping session to save"
    stop = make("StopMapping")
    py_trees.trees.setup(stop, context=bench.ctx)
    for _ in stop.tick():
        pass
    assert stop.status == Status.SUCCESS and bench.port.maps == ["flat-2"], "nothing to drop"
    bench.leaf.stop(Status.INVALID)
    bench.tick()
    for _ in stop.tick():
        pass
    assert stop.status == Status.SUCCESS and bench.port.maps == ["flat-2", None] and not bench.port.mapping


def test_mapping_leaves_report_what_went_wrong() -> None:
    unable = Bench(make("StartMapping"))  # the recording port cannot map unless told
    assert unable.tick() == Status.FAILURE
    assert unable.leaf.reason == "cannot start mapping: mapping is not available in this build"
    assert not unable.ctx.mapping_active

    class FullDisk(RecordingPort):
        def end_mapping(self, save_as: str | None) -> None:
            raise HardwareError("no space left on the data disk")

    saving = Bench(make("SaveMap"), port=FullDisk())
    saving.ctx.mapping_active = True
    assert saving.tick() == Status.FAILURE
    assert saving.leaf.reason == "saving map 'flat' failed: no space left on the data disk"
    assert saving.ctx.mapping_active, "the session goes on: the map is not lost"
    with pytest.raises(ConfigError, match="map name must be"):
        parse_params(behaviours.get("SaveMap").Params, {"name": "../etc/passwd"}, Source("argument"), "params")


def test_follow_path_goal_heading() -> None:
    params = behaviours.get("FollowPath").Params
    def pose(**raw: Any) -> Pose2D:
        return parse_params(params, raw, Source("argument"), "params").pose()
    assert pose(points=[[0.0, 0.0], [1.0, 1.0]]) == Pose2D(1.0, 1.0, math.pi / 4)
    assert pose(points=[[0.0, 0.0], [1.0, 1.0], [1.0, 1.0]]).yaw_rad == pytest.approx(math.pi / 4), \
        "a repeated last point: the heading of the last real stretch"
    assert pose(points=[[2.0, 0.0]]).yaw_rad == 0.0
    assert pose(points=[[0.0, 0.0], [1.0, 1.0]], yaw_rad=-1.0).yaw_rad == -1.0
