"""The thesis's low-level behaviours on the WHOLE simulated robot (issue 6, "Wiring";
docs/navigation.md#the-motion-pipeline).

Every test builds the assembled robot on a `SimClock` (motors emulated over a private virtual CAN channel,
the emulated secondary core, the agent), waits until the agent is IDLE and the secondary core in OPS,
then drives it as an operator would: the dashboard's joystick resends every 100 ms while held
(`MotionInputs.operate`), awareness is the operator's flag. Ground truth (pose, speed, collisions, falls)
comes from the simulator, decisions from the motion control's last result. Seeded and on simulated time:
no test sleeps on the wall clock.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.io.can.bus import unique_channel
from atemr.msgs import Pose2D, Twist
from atemr.robot import Robot, build_robot
from atemr.robot.gateway import RobotGatewayImpl
from atemr.skills.motion_pipeline import ControlResult

STUDIO = Path(__file__).resolve().parents[2] / "atemr" / "worlds" / "studio"
#: The control loop's period (50 Hz): the tests step the robot tick by tick.
TICK = 0.02
#: The dashboard's joystick resends every 100 ms while held.
RESEND = 0.1
#: The speed the dashboard's joystick asks for when pushed fully forward (its default linear limit).
DASHBOARD_SPEED = 0.5
FOOTPRINT = 0.25
STOP_DISTANCE = 0.28
SLOW_DISTANCE = 0.56
SLOW_SPEED = 0.35
#: The RMD model's first-order time constant: the wheels follow a command with this lag.
MOTOR_TAU = 0.08
#: True speed noise of the simulated base (wheel slip) around a commanded speed.
SPEED_NOISE = 0.01


@dataclass(frozen=True)
class Sample:
    """One control tick: time, true pose and forward speed, and the motion control's decision."""

    t: float
    pose: Pose2D
    v: float
    result: ControlResult


class Drive:
    """The whole robot plus an operator: step it tick by tick and keep what happened."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.sim = robot.parts.sim
        self.inputs = robot.parts.inputs
        self.motion = robot.components["motion"]
        self.agent = robot.components["agent"]
        self.log: list[Sample] = []
        self.last_sent = -math.inf

    @property
    def t(self) -> float:
        return self.robot.clock.now()

    def boot(self) -> float:
        """Run until the agent is IDLE and the secondary core in OPS (about 3 s); returns that time."""
        board = self.robot.components["secondary_core"]
        while not (self.agent.state.startswith("IDLE") and board.state == "ops"):
            assert self.t < 10.0, f"not ready: agent {self.agent.state}, secondary core {board.state}"
            self.robot.run(until=round(self.t + TICK, 6))
        return self.t

    def place(self, pose: Pose2D) -> None:
        """Carry the robot to ``pose`` and tell the localization (as the operator's initial-pose click)."""
        self.sim.kidnap(pose)
        self.robot.parts.localization.set_initial_pose(self.t, pose)

    def run(self, until: float, joy: Twist | None = None) -> None:
        """Tick to ``until``; with ``joy`` the operator holds the joystick (resent every 100 ms)."""
        while self.t < until - 1e-9:
            if joy is not None and self.t - self.last_sent >= RESEND - 1e-9:
                self.inputs.operate(joy, self.t)
                self.last_sent = self.t
            self.robot.run(until=round(self.t + TICK, 6))
            last = self.motion.last
            assert last is not None
            self.log.append(Sample(self.t, self.sim.pose, self.sim.base.v_mps, last))

    def since(self, t: float) -> list[Sample]:
        return [s for s in self.log if s.t >= t - 1e-9]

    def static_clearance(self, pose: Pose2D) -> float:
        """Gap between the footprint and the nearest wall or object (movers excluded), metres."""
        return float(self.sim.scene.clearance(pose.x_m, pose.y_m, FOOTPRINT).clearance_m)


@contextmanager
def whole_robot(tmp_path: Path, **overrides: Any) -> Iterator[Drive]:
    settings = {"data_dir": str(tmp_path / "data"), "can.channel": unique_channel("scenario"), "sim.seed": 1,
                "secondary.portal_serve": False, "ui.enabled": False}
    settings.update(overrides)
    robot = build_robot(load_config(environ={}, overrides=settings), realtime=False, clock=SimClock())
    with robot:
        drive = Drive(robot)
        drive.boot()
        assert drive.agent.state == "IDLE.MANUAL"
        yield drive


def world_file(tmp_path: Path, start: tuple[float, float, float], extra: str = "") -> str:
    """A world on the studio's map (walls and mapped furniture only) with its own start and extras."""
    path = tmp_path / "scenario_world.yaml"
    path.write_text(f"name: scenario\nmap: {STUDIO / 'studio.yaml'}\nstart: [{start[0]}, {start[1]}, {start[2]}]\n"
                    + extra)
    return str(path)


# -- 1. slow zone, stop zone, resume ---------------------------------------------------------------------------

#: A clear straight approach in the studio: from the living room south to its south wall (y = 0), 0.85 m
#: from the coffee table and 0.78 m from the laundry basket as it passes them.
TO_SOUTH_WALL = Pose2D(2.9, 2.6, -math.pi / 2)
SOUTH_WALL_Y = 0.0


def drive_at_the_south_wall(drive: Drive, seconds: float) -> float:
    """Carry the robot to the approach, let it take a scan there, then push forward; returns when it started."""
    drive.place(TO_SOUTH_WALL)
    drive.run(drive.t + 0.3)
    start = drive.t
    drive.run(start + seconds, joy=Twist(DASHBOARD_SPEED, 0.0))
    return start


def test_driven_at_a_wall_the_base_is_at_slow_speed_inside_the_slow_zone(tmp_path):
    with whole_robot(tmp_path) as drive:
        start = drive_at_the_south_wall(drive, 6.0)
        inside = [s for s in drive.since(start) if s.pose.y_m - SOUTH_WALL_Y < SLOW_DISTANCE]
        assert inside, "never reached the slow zone"
        assert max(s.v for s in drive.since(start)) > DASHBOARD_SPEED - SPEED_NOISE  # it did go faster before
        too_fast = [(round(s.pose.y_m - SOUTH_WALL_Y, 3), round(s.v, 3)) for s in inside
                    if s.v > SLOW_SPEED + SPEED_NOISE]
        assert not too_fast, f"faster than {SLOW_SPEED} m/s inside the slow zone (distance, speed): {too_fast}"


def test_driven_at_a_wall_the_base_slows_then_stops_at_the_stop_zone_clear_of_the_wall(tmp_path):
    with whole_robot(tmp_path) as drive:
        log = drive.since(drive_at_the_south_wall(drive, 6.0))
        gap = [s.pose.y_m - SOUTH_WALL_Y for s in log]
        # slowing: the ramp's slow flag is up before the stop, and the base reached the stop at slow speed
        first_slow = next(i for i, s in enumerate(log) if s.result.slow)
        first_stop = next(i for i, s in enumerate(log) if s.result.emergency)
        assert first_slow < first_stop
        assert gap[first_slow] < SLOW_DISTANCE + DASHBOARD_SPEED * 0.1  # a 10 Hz scan: at most 5 cm late
        assert gap[first_slow] > STOP_DISTANCE + 0.1
        assert log[first_stop].v <= SLOW_SPEED + SPEED_NOISE
        # the emergency (zero at once, bypassing the ramp) comes before the stop zone, not inside it
        assert gap[first_stop] >= STOP_DISTANCE, gap[first_stop]
        assert log[first_stop].result.twist.is_zero and log[first_stop].result.source == "joystick"
        # at rest at or just beyond the stop distance (the braking distance anticipated), footprint clear, no collision
        rest = log[-1]
        assert rest.result.emergency and abs(rest.v) < 1e-3
        assert STOP_DISTANCE <= gap[-1] <= STOP_DISTANCE + 0.06, gap[-1]
        assert gap[-1] > FOOTPRINT
        assert not drive.sim.collisions
        # the operator keeps pushing for 3 s more: the base stays put (no creeping towards the wall)
        held_at = drive.sim.pose
        drive.run(drive.t + 3.0, joy=Twist(DASHBOARD_SPEED, 0.0))
        assert drive.sim.pose.distance_to(held_at) < 0.003
        assert all(s.result.emergency for s in drive.since(drive.t - 3.0))
        assert not drive.sim.collisions


def test_stopped_at_an_obstacle_the_base_resumes_two_seconds_after_it_left(tmp_path):
    with whole_robot(tmp_path) as drive:
        drive.place(TO_SOUTH_WALL)
        box = drive.sim.drop_obstacle(2.9, 1.6, size_m=0.4)  # its near face at y = 1.8
        forward = Twist(DASHBOARD_SPEED, 0.0)
        drive.run(drive.t + 4.0, joy=forward)
        assert drive.log[-1].result.emergency and abs(drive.log[-1].v) < 1e-3
        stopped_at = drive.sim.pose
        assert 1.8 + STOP_DISTANCE <= stopped_at.y_m <= 1.8 + STOP_DISTANCE + 0.06
        drive.sim.remove_obstacle(box)
        left_at = drive.t
        drive.run(left_at + 3.5, joy=forward)  # the operator kept pushing all along
        after = drive.since(left_at)
        moving = [s for s in after if not s.result.twist.is_zero]
        assert moving, "never resumed"
        resumed = moving[0].t
        # not before 2 s; at most one lidar period (the scan that shows the box gone) and a tick later
        assert left_at + 2.0 - 1e-6 <= resumed <= left_at + 2.0 + 0.1 + TICK + 1e-6, resumed - left_at
        for s in after:
            if s.t < resumed:
                assert s.result.emergency and s.pose.distance_to(stopped_at) < 0.003, s
        assert drive.sim.pose.y_m < stopped_at.y_m - 0.3  # and it drove on over where the box stood
        assert not drive.sim.collisions


# -- 2. idle -------------------------------------------------------------------------------------------------


def test_the_base_is_idle_eight_seconds_after_the_last_state_changing_command(tmp_path):
    with whole_robot(tmp_path) as drive:
        drive.run(drive.t + 1.0, joy=Twist(0.2, 0.0))
        assert not drive.log[-1].result.idle
        released = drive.t
        drive.inputs.operate(Twist(), released)  # the page sends one zero when the joystick is let go
        drive.run(released + 9.0)  # then nothing: the agent keeps the joystick input at a steady zero
        after = drive.since(released)
        idle_from = next(s.t for s in after if s.result.idle)
        # the agent forwards the joystick at 10 Hz, so the release reaches the pipeline up to 0.1 s later
        assert released + 8.0 - 1e-6 <= idle_from <= released + 8.0 + 0.1 + TICK + 1e-6, idle_from - released
        assert all(s.result.idle for s in after if s.t >= idle_from)
        # a new command wakes the base
        drive.run(drive.t + 0.3, joy=Twist(0.2, 0.0))
        assert not drive.log[-1].result.idle


# -- 3. awareness, idle base, a person walks up -------------------------------------------------------------


def test_with_awareness_an_idle_base_moves_away_from_a_person_walking_at_it(tmp_path):
    # The robot in the living room facing east, the coffee table's corner 0.95 m straight behind it: backing
    # straight off leads towards it. A person first walks up and down x = 4.5 (never within 1.5 m of the robot,
    # beyond the engines' 1.2 m radius) until the base is idle, then turns and walks straight at it along y = 2.6.
    start = (3.0, 2.6, 0.0)
    person = ("moving:\n  - {name: visitor, kind: person, path: [[4.5, 1.8], [4.5, 0.5], [4.5, 2.6], [1.0, 2.6]], "
              "speed_mps: 0.3}\n")
    world = world_file(tmp_path, start, person)
    with whole_robot(tmp_path, **{"sim.world": world}) as drive:
        aware_at = drive.t
        drive.inputs.awareness = True
        drive.run(aware_at + 8.5)  # no operator command: idle 8 s after the awareness switch
        assert drive.log[-1].result.idle
        home = drive.sim.pose
        assert home.distance_to(Pose2D(*start)) < 0.01, "the base moved before anything approached"
        drive.run(aware_at + 24.0)
        visitor = drive.sim.movers.items[0]
        log = drive.since(aware_at)
        end = drive.sim.pose
        # it moved away: backed off west, along the line the person came on, and the person got closer to
        # where it stood than they could have if it had not moved
        assert end.x_m < home.x_m - 0.3, end
        assert visitor.x_m < home.x_m + FOOTPRINT + visitor.spec.radius_m, (visitor.x_m, visitor.y_m)
        assert {s.result.source for s in log if not s.result.twist.is_zero} == {"reactive"}
        # and never towards another obstacle: it stopped backing off as the table behind it came near, never within
        # the stop distance of it or anything else (no emergency needed), no collision
        assert not any(s.result.emergency for s in log)
        assert not drive.sim.collisions
        assert min(drive.static_clearance(s.pose) for s in log) > STOP_DISTANCE - FOOTPRINT
        assert abs(drive.log[-1].v) < 0.01, "still moving at the end"


# -- 4. awareness while the operator drives at a wall --------------------------------------------------------


def test_with_awareness_the_manual_engine_steers_a_base_driven_at_a_wall_round_it(tmp_path):
    # The living room's south wall (y = 0), approached from the north-west at 40° off square; only the walls
    # and mapped furniture (the studio's loose basket and plant are left out of this world)
    heading = -math.pi / 2 + math.radians(40.0)
    world = world_file(tmp_path, (1.6, 1.3, heading))
    with whole_robot(tmp_path, **{"sim.world": world}) as drive:
        drive.inputs.awareness = True
        start = drive.t
        drive.run(start + 10.0, joy=Twist(DASHBOARD_SPEED, 0.0))  # the operator only pushes forward
        log = drive.since(start)
        end = drive.sim.pose
        assert not drive.sim.collisions
        assert not any(s.result.emergency for s in log)
        assert max(abs(s.result.twist.linear_mps) for s in log) <= 0.26 + 1e-9  # the engine's own speed limit
        # steered round: turned left, at least parallel to the wall (heading east), and kept going along it
        assert -math.radians(10.0) < end.yaw_rad < math.pi / 2, math.degrees(end.yaw_rad)
        assert end.x_m > 3.0, end
        assert min(s.pose.y_m - SOUTH_WALL_Y for s in log) > STOP_DISTANCE


def test_with_awareness_the_manual_engine_steers_a_base_driven_square_at_a_wall_round_it(tmp_path):
    world = world_file(tmp_path, (TO_SOUTH_WALL.x_m, TO_SOUTH_WALL.y_m, TO_SOUTH_WALL.yaw_rad))
    with whole_robot(tmp_path, **{"sim.world": world}) as drive:
        drive.inputs.awareness = True
        start = drive.t
        drive.run(start + 10.0, joy=Twist(DASHBOARD_SPEED, 0.0))
        log = drive.since(start)
        assert not drive.sim.collisions  # safe either way
        assert not any(s.result.emergency for s in log)
        assert abs(drive.sim.pose.yaw_rad - TO_SOUTH_WALL.yaw_rad) > math.radians(45.0), drive.sim.pose


# -- 5. lost joystick --------------------------------------------------------------------------------------


def test_a_lost_joystick_stops_the_base_within_half_a_second_and_the_motor_lag(tmp_path):
    with whole_robot(tmp_path) as drive:
        drive.place(TO_SOUTH_WALL)
        drive.run(drive.t + 1.5, joy=Twist(0.3, 0.0))  # 1.5 m of open floor ahead, well clear of the wall
        last_sent = drive.last_sent
        assert drive.log[-1].v > 0.28
        drive.run(last_sent + 1.5)  # the browser tab is gone: nothing more is sent
        after = drive.since(last_sent)
        # still driving until the last command is 0.5 s old (the timeout, not an earlier stop)
        assert all(not s.result.twist.is_zero for s in after if s.t < last_sent + 0.5 - 1e-6)
        # then zero at once, bypassing the ramp: the mux's watchdog at the first control tick at 0.5 s (then the
        # agent's own joystick timeout forwards a fresh zero), and zero ever after
        timed_out = [s for s in after if s.t >= last_sent + 0.5 - 1e-6]
        assert timed_out[0].t <= last_sent + 0.5 + TICK + 1e-6
        assert timed_out[0].result.twist.is_zero and timed_out[0].result.watchdog, timed_out[0]
        assert all(s.result.twist.is_zero for s in timed_out)
        # and the wheels stop with the motors' lag: one driver period and the RMD's first-order time constant
        stop_by = last_sent + 0.5 + TICK + 2 * TICK + 4 * MOTOR_TAU
        assert all(abs(s.v) < 0.01 for s in after if s.t >= stop_by)
        at_timeout = next(s.pose for s in after if s.t >= last_sent + 0.5 - 1e-6)
        assert drive.sim.pose.distance_to(at_timeout) < 0.3 * (TICK + 2 * TICK + MOTOR_TAU) + 0.01
        assert not drive.sim.collisions


# -- 6. drop zone -----------------------------------------------------------------------------------------


def test_a_drop_zone_stops_the_base_before_it_falls(tmp_path):
    # on the balcony, facing its open south edge (the drop zone starts at y = -1.3)
    with whole_robot(tmp_path) as drive:
        drive.place(Pose2D(4.25, -0.3, -math.pi / 2))
        start = drive.t
        drive.run(start + 6.0, joy=Twist(DASHBOARD_SPEED, 0.0))
        log = drive.since(start)
        assert drive.sim.falls == []
        assert any(s.result.cliff_stop for s in log)
        assert not any(s.result.emergency for s in log)  # the lidar sees no wall there: the IR sensors stopped it
        assert log[-1].result.cliff_stop and log[-1].result.twist.is_zero and abs(log[-1].v) < 1e-3
        assert drive.sim.pose.y_m > -1.3 + 0.05, drive.sim.pose
        gateway = RobotGatewayImpl(drive.robot)
        assert gateway.state()["stop_cause"] == "cliff"  # what the carer reads: a drop under the robot's edge
        gateway.close()
        # the operator keeps pushing: it does not creep over the edge
        drive.run(drive.t + 2.0, joy=Twist(DASHBOARD_SPEED, 0.0))
        assert drive.sim.falls == [] and drive.sim.pose.y_m > -1.3 + 0.05
        assert not drive.sim.collisions
