"""1,000 seeded CAN fault schedules, each over a stretch of a simulated patrol.

What runs. A 4 m x 3 m room (a table in the middle, a cupboard by a wall, both in the map) and the robot's own
control stack around the simulator's parts: the differential-drive base (`atemr.io.sim.base`, wheel slip
included) driven by two real `RmdMotorEmulator` models, the ray-cast 360-beam lidar and the cliff sensors;
the real `Navigator` (the robot's ``nav`` parameters) on the true pose, patrolling in AUTO round the table
through four waypoints (each facing the next) at the agent's 10 Hz, its twist on the navigation input of
the real `MotionPipeline` (twist mux, speed ramp with its stop zone, cliff stop) at 50 Hz, whose wheel speeds
go to the real `RmdDriver` behind a `FaultInjectionBus`, as wired on the robot (dropped while a fault is
latched), on the simulated robot's in-process bus (``interface="atemr"``: python-can's ``virtual`` would
deep-copy every frame for each receiver, a tenth of the module's time). The motor emulators run at 50 Hz, the
driver's rate (100 Hz on the robot), to fit the budget.

Short runs from a pre-recorded patrol. 1,000 full patrols do not fit in a test (the navigator alone costs
about 2 ms a tick), so the patrol is recorded once on a clean link (`Patrol`, seeded) and schedule ``n``
starts from a copy of its state at ``1.0 + 0.1 n`` s (simulation with the true pose, wheel models and the
sensors' generators; navigator with its costmap and plan; pipeline with its ramp and mux; the leg being
driven): 1,000 different points of about 100 s of patrol, every part of the four legs, straight driving,
turns at waypoints and close passes by the table. The driver, the emulators and the links are new for each
run (the driver starts with no history). A run lasts 1.2 s of simulated time, or in an outage run until the
patrol is seen going on again after the link returned (at most 4 s after); the whole module takes about
80 s. Schedules are taken in order, so the recording is advanced, not repeated, and one copy is held.

Each schedule draws drop, duplicate, delay (up to 0.1 s), reorder and, in 30 % of runs, reply corruption
probabilities, and then either a link outage of 0.3-0.8 s (half the runs) or, in 70 % of the rest, an
obstacle put down in front of the base just beyond the distance it needs to stop (`REACTION_S`): nearer,
no controller could avoid it, so "no contact" would not be a property of the software. The agent's part is
played by the harness: on a latched motor fault it enters ERROR (navigation cancelled, its input zeroed)
and calls the robot's recovery, `RmdDriver.recover`, every tick; once that clears the fault the patrol goes
on towards the same waypoint.

Invariants checked on every run:

* stop zone: no speed command is issued forward while the pipeline sees something ahead closer than the stop
  distance, nor backward with something that close behind (the ramp's rear zone);
* freshness: every speed command a motor acts on was issued by the driver at most 0.5 s earlier, and a motor
  drives on no command issued more than 0.5 s (+ the schedule's wire delay + one emulator tick) before;
* link failure: 0.5 s into an outage the driver has latched the fault and commands zero, both motors have
  stopped by themselves (RMD communication timeout) 0.5 s after the last command they could have received,
  and 0.3 s later the base is at rest (ground truth);
* recovery: once the link is back (or a fault latches after that) the fault is cleared within 0.7 s, then the
  base moves again and gets on along the patrol within 2 s (the navigator's distance to the waypoint shrinks
  by 0.1 m, the waypoint is reached, or the base turns to its heading there), and the patrol never fails;
* no contact: the footprint never touches a wall, the furniture or the obstacle (ground truth; the simulated
  base stops where it touches and reports the contact).

Not covered here, and why:

* corrupted *command* frames: real CAN rejects bit errors with its CRC, and the RMD protocol has no checksum
  of its own, so a command corrupted past the CRC is not something software can detect. Corruption hits
  replies only (a flipped error-flag bit stops the motors, and recovery clears it);
* the stop zone judged against ground truth: the pipeline works on a scan up to 0.1 s old (by design, aged by
  its own commanded travel), so the check uses the clearance it saw. With the navigator keeping its plans out
  of the stop zone, something gets inside it only when put down in front of the base (about a third of the
  obstacle runs; the ramp's emergency fires in about one in seven);
* the whole agent (trees, state machine) and localization: the harness plays the agent's fault handling, and
  the navigator drives on the true pose. `test_robot_faults.py` runs the whole simulated robot;
* the first fault of a driver with a history: each run's driver is new.
"""

from __future__ import annotations

import copy
import math
import random
from collections.abc import Iterator
from dataclasses import dataclass, field

import can
import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.config import MotorsConfig
from atemr.domain.maps import OccupancyMap
from atemr.io.can.bus import unique_channel
from atemr.io.can.faults import FaultInjectionBus, FaultPlan
from atemr.io.motors.driver import RmdDriver
from atemr.io.motors.emulator import RmdMotorEmulator
from atemr.io.motors.rmd_codec import RmdCommand, RmdRequest, motor_can_id
from atemr.io.sim.base import MountedWheel
from atemr.io.sim.simulation import SimParams, Simulation, default_wheels
from atemr.io.sim.world import World
from atemr.msgs import Pose2D, Twist, WheelSpeeds
from atemr.robot.core import Ticker
from atemr.robot.inputs import MotionInputs
from atemr.scheduler import Component, Scheduler
from atemr.skills.motion_pipeline import ControlResult, MotionPipeline, TimedTwist
from atemr.skills.nav.config import NavConfig
from atemr.skills.nav.navigator import Navigator
from atemr.skills.ramp import MotionLimits
from atemr.skills.reactive import ReactiveEngine

RUNS = 1000
FRESH_S = 0.5
#: Built once: loading the fuzzy engines costs more than a whole run (awareness is off, so they never run).
REACTIVE = ReactiveEngine()
MOTORS = MotorsConfig()
RES_M = 0.05
#: Rates as on the robot (`atemr.robot.assembly.RATES`, ``sim.*``, ``motors.rate_hz``), except the motor
#: emulators: 50 Hz, the driver's rate, instead of 100 Hz (a frame waits up to 20 ms longer to be answered).
PHYSICS_HZ, LIDAR_HZ, CLIFF_HZ, EMULATOR_HZ, AGENT_HZ, CONTROL_HZ = 100.0, 10.0, 20.0, 50.0, 10.0, 50.0
#: The pre-recorded patrol: a snapshot every SNAPSHOT_EVERY_S from WARMUP_S on, one per schedule.
WARMUP_S = 1.0
SNAPSHOT_EVERY_S = 0.1
#: A stopped motor's speed decays with the RMD's 0.08 s time constant: after BRAKE_S it is down to 2 %.
BRAKE_S = 0.3
#: After the link returns (or a fault latches after that), the fault is cleared within RECOVER_S: both motors
#: answer within a few driver periods, the agent tries every 0.1 s, and a corrupted error flag in a status-1
#: reply waits for the next good one (0.2 s apart, one may be lost). From then on the base moves again and
#: gets on along the patrol within PROGRESS_S, and all that within GIVE_UP_S of the link's return.
RECOVER_S = 0.7
PROGRESS_S = 2.0
GIVE_UP_S = 4.0
#: "Getting on along the patrol": the navigator's distance left to the waypoint shrinks by this much (or the
#: waypoint is reached), and the base has moved at least MOVED_M...
PROGRESS_M = 0.1
MOVED_M = 0.05
#: ... or, at the waypoint, the heading error shrinks by this much.
TURNED_RAD = 0.3
#: The longest a base can take to stop for an obstacle that appears in front of it: the next scan (0.1 s),
#: a control and a driver period (0.04 s), the longest wire delay (0.1 s), a few lost frames (0.06 s) and the
#: motors' time constant (0.08 s). An obstacle put down nearer could not be avoided by any controller.
REACTION_S = 0.4
#: The simulator draws a round obstacle as the grid cells whose centres it covers: up to half a cell's
#: diagonal nearer than the circle.
RASTER_M = 0.036


def room_world() -> World:
    """A 4 m x 3 m room: a table in the middle and a cupboard by the far wall, both in the map (as SLAM
    would have drawn them)."""
    data = np.zeros((round(3.0 / RES_M), round(4.0 / RES_M)), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100

    def box(x0: float, y0: float, x1: float, y1: float) -> None:
        data[round(y0 / RES_M):round(y1 / RES_M), round(x0 / RES_M):round(x1 / RES_M)] = 100

    box(1.5, 1.1, 2.5, 1.85)  # table
    box(3.35, 2.3, 4.0, 3.0)  # cupboard
    return World("room", OccupancyMap(data, RES_M, Pose2D(), name="room"), Pose2D(0.6, 0.6, 0.0))


#: Round and round the table: each waypoint faces the next, so a leg starts without a turn on the spot.
WAYPOINTS = (
    Pose2D(3.4, 0.6, math.atan2(2.4 - 0.6, 2.9 - 3.4)),
    Pose2D(2.9, 2.4, math.pi),
    Pose2D(0.6, 2.4, -math.pi / 2),
    Pose2D(0.6, 0.6, 0.0),
)
#: The robot's navigation parameters (``nav`` defaults, with the motion pipeline's stop zone).
NAV_PARAMS = NavConfig().nav_params(MotionLimits())


@dataclass(frozen=True)
class Snapshot:
    """The patrol at time ``t``: the simulation (true pose, wheel models, sensors' generators), the navigator and
    the motion pipeline in mid-patrol, the leg being driven and the navigation input's latest twist."""

    t: float
    sim: Simulation
    nav: Navigator
    pipeline: MotionPipeline
    leg: int
    nav_input: TimedTwist | None


@dataclass(frozen=True)
class Obstacle:
    """A round obstacle (a bin, a chair's legs) of diameter ``size_m`` put down at ``t`` in front of the base,
    ``aside_m`` to the left of its heading, its near edge just beyond the distance the base needs to stop:
    ``margin_m`` more than the footprint's radius plus the speed times REACTION_S."""

    t: float
    margin_m: float
    aside_m: float
    size_m: float


@dataclass(frozen=True)
class Schedule:
    start: int
    plan: FaultPlan
    reply_corrupt: float
    outage: tuple[float, float] | None
    obstacle: Obstacle | None
    duration_s: float

    @property
    def t0(self) -> float:
        return start_time(self.start)


def start_time(index: int) -> float:
    return round(WARMUP_S + SNAPSHOT_EVERY_S * index, 6)


def schedule(seed: int) -> Schedule:
    rng = random.Random(seed)
    start = seed % RUNS
    t0 = start_time(start)
    outage = obstacle = None
    if rng.random() < 0.5:
        begin = round(t0 + rng.uniform(0.3, 0.6), 2)
        outage = (begin, round(begin + rng.uniform(0.3, 0.8), 2))
    elif rng.random() < 0.7:
        obstacle = Obstacle(round(t0 + rng.uniform(0.1, 0.4), 2), rng.uniform(0.0, 0.04), rng.uniform(-0.1, 0.1),
                            rng.uniform(0.15, 0.3))
    # an outage run keeps the other losses light, so the link that returns is usable
    plan = FaultPlan(drop=rng.uniform(0, 0.1 if outage else 0.3), duplicate=rng.uniform(0, 0.2),
                     delay=rng.uniform(0, 0.2), delay_s=rng.uniform(0.005, 0.1), reorder=rng.uniform(0, 0.2),
                     outages=(outage,) if outage else (), seed=seed)
    return Schedule(start, plan, rng.uniform(0, 0.05) if rng.random() < 0.3 else 0.0, outage, obstacle,
                    1.2 if outage is None else outage[1] - t0)


class IssuedLog(FaultInjectionBus):
    """The driver's side of the link: records when each speed frame was handed to the (faulty) wire."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.issued: dict[tuple[int, bytes], float] = {}

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.issued[(msg.arbitration_id, bytes(msg.data))] = self.clock.now()
        super().send(msg, timeout)


@dataclass
class Outcome:
    violations: list[str] = field(default_factory=list)
    #: the speed ramp's stop-zone emergency fired
    stop_zone: bool = False
    #: control ticks that saw something inside the stop distance ahead or behind (where the stop-zone check bites)
    inside: int = 0
    faults: int = 0
    #: when the latched fault was cleared (by `RmdDriver.recover`, the agent's recovery)
    cleared: list[float] = field(default_factory=list)
    #: after the link returned: when the base had moved again and got on along the patrol
    resumed_t: float | None = None
    legs_done: int = 0
    #: the footprint's least clearance to the walls, furniture and obstacle (`Scene.clearance` looks no farther
    #: than a cell beyond the footprint: 0.05 m here means "at least that")
    closest_m: float = math.inf
    #: how far the base drove in the run (ground truth)
    distance_m: float = 0.0


class PatrolRun:
    """One schedule: the robot's control stack over a faulty CAN link, from ``t0`` on.

    The simulation, navigator and pipeline given are used (and changed) as they are; the driver, the motor
    emulators, the motion inputs and the links are new.
    """

    def __init__(self, sim: Simulation, nav: Navigator, pipeline: MotionPipeline, leg: int,
                 nav_input: TimedTwist | None, t0: float, sch: Schedule, seed: int) -> None:
        self.sim, self.nav, self.pipeline, self.leg, self.sch = sim, nav, pipeline, leg, sch
        self.out = Outcome()
        self.t0 = t0
        self.clock = clock = SimClock(t0)
        channel = unique_channel("patrol-faults")
        inner: can.BusABC = can.Bus(interface="atemr", channel=channel)
        if sch.reply_corrupt:
            inner = FaultInjectionBus(inner, FaultPlan(corrupt=sch.reply_corrupt, seed=seed), clock, direction="recv")
        self.link = IssuedLog(inner, sch.plan, clock)
        self.fault_at: list[float] = []
        self.driver = RmdDriver.from_config(self.link, MOTORS, on_fault=lambda _: self.fault_at.append(clock.now()))
        self.motors = [
            RmdMotorEmulator(can.Bus(interface="atemr", channel=channel), motor_id, wheel.model, steps_model=False)
            for motor_id, wheel in ((MOTORS.left_id, sim.left), (MOTORS.right_id, sim.right))
            if isinstance(wheel, MountedWheel)
        ]
        self.inputs = MotionInputs(mode="AUTO")
        if nav_input is not None:
            self.inputs.offer("navigation", nav_input.twist, nav_input.t)
        self.issued_at = {m.motor_id: t0 for m in self.motors}
        self.in_error = False
        self.obstacle_id: int | None = None
        self.progress: list[tuple[float, int, float, float]] = []
        self._last_result: ControlResult | None = None
        self._collisions0 = len(sim.collisions)
        self._distance0 = sim.base.distance_m
        for m in self.motors:
            self._spy(m)
        self.sched = sched = Scheduler(clock, realtime=False)
        components: tuple[tuple[Component, float], ...] = (
            (sim.physics, PHYSICS_HZ), (Ticker("truth", self._watch), CONTROL_HZ), (sim.lidar_source, LIDAR_HZ),
            (sim.cliff_source, CLIFF_HZ), *((m, EMULATOR_HZ) for m in self.motors),
            (Ticker("agent", self._agent), AGENT_HZ), (Ticker("control", self._control), CONTROL_HZ),
            (self.driver, float(MOTORS.rate_hz)),
        )
        for component, rate in components:
            # from a snapshot, every component's tick at t0 has run already
            sched.add(component, rate, phase_s=1.0 / rate if t0 > 0 else 0.0)

    # -- the parts of the robot the harness plays ----------------------------------------------------------
    def _agent(self, now: float) -> None:
        """The agent at 10 Hz: patrol in AUTO (the navigator on the true pose, its twist to the pipeline's
        navigation input, the next waypoint when one is reached); on a latched motor fault ERROR (navigation
        cancelled, its input zeroed) and, every tick while there, the robot's recovery (`RmdDriver.recover`);
        once it clears, the patrol goes on towards the same waypoint."""
        sch, nav, sim = self.sch, self.nav, self.sim
        if sch.obstacle is not None and self.obstacle_id is None and now >= sch.obstacle.t - 1e-9:
            self._drop(sch.obstacle)
        if self.driver.fault is not None:
            if not self.in_error:
                self.in_error = True
                self.out.faults += 1
                nav.cancel(now)
                self.inputs.zero(now, ("navigation",))
            if self.driver.recover(now) is not None:
                return
            self.out.cleared.append(now)
        if self.in_error:
            self.in_error = False
            nav.start(WAYPOINTS[self.leg], now)
        status = nav.update(now, sim.pose, sim.lidar_source.latest, True, self._measured())
        if status.state == "SUCCEEDED":
            self.leg = (self.leg + 1) % len(WAYPOINTS)
            self.out.legs_done += 1
            nav.start(WAYPOINTS[self.leg], now)
            status = nav.update(now, sim.pose, sim.lidar_source.latest, True, self._measured())
        if status.state != "RUNNING":
            self.out.violations.append(f"t={now:.2f} the patrol stopped: {status.state} {status.message}")
        goal = WAYPOINTS[self.leg]
        yaw_err = abs(math.remainder(goal.yaw_rad - sim.pose.yaw_rad, math.tau))
        self.progress.append((now, self.out.legs_done, status.distance_left_m, yaw_err))
        self.inputs.offer("navigation", status.twist, now)

    def _measured(self) -> Twist | None:
        """The twist the pipeline commanded last (what the robot gives the navigator as measured)."""
        last = self._last_result
        return None if last is None else last.twist

    def _control(self, now: float) -> None:
        """The 50 Hz motion control, as wired on the robot: the pipeline's wheel speeds go to the driver unless a
        fault is latched. Checks the stop zone on every command issued."""
        result = self.pipeline.tick(self.inputs.control_inputs(now, self.sim.lidar_source.latest,
                                                               self.sim.cliff_source.latest))
        self._last_result = result
        self.out.stop_zone |= result.emergency
        linear = result.wheels.left_radps + result.wheels.right_radps
        stop_m = self.pipeline.limits.stop_distance_m
        if result.clearance is not None:
            self.out.inside += min(result.clearance.front_m, result.clearance.rear_m) < stop_m
            if result.clearance.front_m < stop_m and linear > 1e-9:
                self.out.violations.append(f"t={now:.2f} forward command with the front "
                                           f"{result.clearance.front_m:.3f} m away")
            if result.clearance.rear_m < stop_m and linear < -1e-9:
                self.out.violations.append(f"t={now:.2f} backward command with the rear "
                                           f"{result.clearance.rear_m:.3f} m away")
        if self.driver.fault is None:
            self.driver.set_speeds(result.wheels, now)

    def _drop(self, obstacle: Obstacle) -> None:
        sim = self.sim
        pose = sim.pose
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        near = sim.params.base.footprint_radius_m + RASTER_M + max(sim.base.v_mps, 0.0) * REACTION_S + obstacle.margin_m
        ahead = near + obstacle.size_m / 2  # to its centre
        x = pose.x_m + c * ahead - s * obstacle.aside_m
        y = pose.y_m + s * ahead + c * obstacle.aside_m
        self.obstacle_id = sim.drop_obstacle(x, y, size_m=obstacle.size_m, shape="circle", name="dropped obstacle")

    # -- checks --------------------------------------------------------------------------------------------
    def _spy(self, motor: RmdMotorEmulator) -> None:
        """Every speed command a motor acts on was issued by the driver at most 0.5 s before."""
        answer = motor.answer
        link, out, clock, issued_at = self.link, self.out, self.clock, self.issued_at

        def spy(request: RmdRequest):  # type: ignore[no-untyped-def]
            now = clock.now()
            if request.command is RmdCommand.SPEED_CONTROL:
                issued = link.issued.get((motor_can_id(motor.motor_id), bytes(request.encode().data)))
                if issued is None or now - issued > FRESH_S + 1e-9:
                    out.violations.append(f"t={now:.2f} motor {motor.motor_id} acts on a command issued at {issued}")
                else:
                    issued_at[motor.motor_id] = issued
            return answer(request)

        motor.answer = spy  # type: ignore[method-assign]

    def _watch(self, now: float) -> None:
        """Ground truth at 50 Hz: no contact (the base stops where it touches and reports it), no motor driving on a
        stale command."""
        sim, out = self.sim, self.out
        pose = sim.pose
        contact = sim.scene.clearance(pose.x_m, pose.y_m, sim.params.base.footprint_radius_m)
        out.closest_m = min(out.closest_m, contact.clearance_m)
        out.distance_m = sim.base.distance_m - self._distance0
        if contact.clearance_m < 0 or len(sim.collisions) > self._collisions0:
            out.violations.append(f"t={now:.2f} the base touches {contact.what or sim.collisions[-1].what} at "
                                  f"({pose.x_m:.2f}, {pose.y_m:.2f})")
            self._collisions0 = len(sim.collisions)
        # a frame can spend up to delay_s on the wire, and the motor can only time the silence from when it received
        # a command; one emulator tick of slack for the sampling
        stale_after = FRESH_S + self.sch.plan.delay_s + 1.0 / EMULATOR_HZ
        for m in self.motors:
            if m.model.target_radps != 0.0 and now - self.issued_at[m.motor_id] > stale_after:
                out.violations.append(f"t={now:.2f} motor {m.motor_id} drives on a command issued at "
                                      f"{self.issued_at[m.motor_id]:.2f}")

    # -- the run -------------------------------------------------------------------------------------------
    def run(self) -> Outcome:
        sch, out, sched, driver = self.sch, self.out, self.sched, self.driver
        sched.start()
        try:
            if sch.outage is None:
                sched.run(until=self.t0 + sch.duration_s)
                return out
            start, end = sch.outage
            if end - start >= FRESH_S:
                # the driver gives up on a silent link within 0.5 s: silence timeout (0.3 s) + a reply delayed
                # up to 0.1 s before the outage + one driver period
                sched.run(until=start + FRESH_S)
                if driver.fault is None or driver.commanded != WheelSpeeds():
                    out.violations.append(f"driver still commands {driver.commanded} {FRESH_S} s into the outage "
                                          f"(fault {driver.fault})")
            stopped_by = start + FRESH_S + sch.plan.delay_s + 1.0 / EMULATOR_HZ
            if end >= stopped_by:
                # cut off, each motor stops by itself 0.5 s after the last speed command it received
                sched.run(until=stopped_by)
                for m in self.motors:
                    if m.model.target_radps != 0.0:
                        out.violations.append(f"motor {m.motor_id} still driving {stopped_by - start:.2f} s into "
                                              "the outage")
            if end >= stopped_by + BRAKE_S:
                # ... and the base has come to rest (ground truth)
                sched.run(until=stopped_by + BRAKE_S)
                base = self.sim.base
                if abs(base.v_mps) > 0.02 or abs(base.w_radps) > 0.05:
                    out.violations.append(f"the base still moves ({base.v_mps:.3f} m/s, {base.w_radps:.3f} rad/s) "
                                          f"{stopped_by + BRAKE_S - start:.2f} s into the outage")
            sched.run(until=end)
            self._resume(end)
        finally:
            sched.shutdown()
        return out

    def _resume(self, back: float) -> None:
        """The link is back at ``back``: the fault (if one latched) is cleared within RECOVER_S, and then the
        base moves again and gets on along the patrol within PROGRESS_S: towards the waypoint, or turning to its
        heading once there, or on to the next one."""
        out, sim = self.out, self.sim
        ref: tuple[tuple[float, int, float, float], float] | None = None
        while True:
            now = self.clock.now()
            if now >= back + GIVE_UP_S - 1e-9:
                out.violations.append(f"t={now:.2f} no progress along the patrol {GIVE_UP_S} s after the link "
                                      f"returned ({self.out.faults} faults)")
                return
            if self.driver.fault is not None or self.in_error:
                ref = None
                since = max(back, self.fault_at[-1])
                if now >= since + RECOVER_S - 1e-9:
                    out.violations.append(f"t={now:.2f} fault still latched {now - since:.2f} s after the link "
                                          f"returned or it latched: {self.driver.fault}")
                    return
            elif ref is None:
                since = max([back, *out.cleared])
                if self.progress[-1][0] >= since:  # the agent's first tick with control back
                    ref = (self.progress[-1], sim.base.distance_m)
            else:
                (t_ref, legs0, left0, yaw0), travel0 = ref
                _, legs, left, yaw = self.progress[-1]
                moved = sim.base.distance_m - travel0
                on = legs > legs0 or left <= left0 - PROGRESS_M or (left0 < NAV_PARAMS.xy_tolerance_m
                                                                     and yaw <= yaw0 - TURNED_RAD)
                if on and (moved >= MOVED_M or yaw <= yaw0 - TURNED_RAD):
                    out.resumed_t = now
                    return
                if now >= t_ref + PROGRESS_S - 1e-9:
                    out.violations.append(f"t={now:.2f} no progress along the patrol {PROGRESS_S} s after control "
                                          f"returned at {t_ref:.2f} (moved {moved:.2f} m, distance left "
                                          f"{left0:.2f} -> {left:.2f} m, heading error {yaw0:.2f} -> {yaw:.2f})")
                    return
            self.sched.run(until=now + 1.0 / AGENT_HZ)


def _shared(sim: Simulation, *, scene: bool) -> dict[int, object]:
    """What a copy of the patrol may share with it (never changed during a run): the world, the map, the
    camera (off), the fuzzy engines, and the scene unless the run puts an obstacle down."""
    share: dict[int, object] = {id(o): o for o in (REACTIVE, sim.world, sim.world.map, sim.camera)}
    if scene:
        share[id(sim.scene)] = sim.scene
    return share


class Patrol:
    """The patrol on a clean link, recorded on demand: `at` gives a copy of its state at a time, recording on
    from where it is (or again from the start, for an earlier time), so the 1,000 schedules, taken in order,
    cost one recording and hold one copy at a time."""

    def __init__(self) -> None:
        self.world = room_world()
        self.run: PatrolRun | None = None

    def _restart(self) -> PatrolRun:
        self.close()
        sim = Simulation(self.world, *default_wheels((MOTORS.left_direction, MOTORS.right_direction)),
                         np.random.default_rng(2024), SimParams(physics_hz=PHYSICS_HZ))
        nav = Navigator(self.world.map, NAV_PARAMS)
        nav.start(WAYPOINTS[0], 0.0)
        clean = Schedule(0, FaultPlan(), 0.0, None, None, 0.0)
        run = self.run = PatrolRun(sim, nav, MotionPipeline(reactive=REACTIVE), 0, None, 0.0, clean, 0)
        run.sched.start()
        return run

    def at(self, t: float, *, scene: bool = True) -> Snapshot:
        """A copy of the patrol at time ``t`` (sharing the scene with the recording when ``scene``)."""
        run = self.run
        if run is None or t < run.clock.now():
            run = self._restart()
        run.sched.run(until=t)
        assert run.out.violations == [], run.out.violations[:5]
        copied = copy.deepcopy((run.sim, run.nav, run.pipeline), _shared(run.sim, scene=scene))
        return Snapshot(t, *copied, run.leg, run.inputs.latest("navigation"))

    def close(self) -> None:
        if self.run is not None:
            self.run.sched.shutdown()
            self.run = None


@pytest.fixture(scope="module")
def patrol() -> Iterator[Patrol]:
    recording = Patrol()
    yield recording
    recording.close()


def run_schedule(patrol: Patrol, seed: int, sch: Schedule | None = None) -> tuple[Schedule, Outcome]:
    sch = sch or schedule(seed)
    snap = patrol.at(sch.t0, scene=sch.obstacle is None)
    return sch, PatrolRun(snap.sim, snap.nav, snap.pipeline, snap.leg, snap.nav_input, snap.t, sch, seed).run()


#: The thousand schedules run in blocks of this many, one test each (each well inside the suite's timeout,
#: which all thousand together came close to on a loaded machine), in order, so the recording is only advanced.
BLOCK = 250


@pytest.fixture(scope="module")
def outcomes() -> dict[int, tuple[Schedule, Outcome]]:
    """Each schedule's outcome, run once: the blocks fill it, the coverage test reads it (and runs whatever a
    selection of tests left out)."""
    return {}


def outcome(patrol: Patrol, outcomes: dict[int, tuple[Schedule, Outcome]], seed: int) -> tuple[Schedule, Outcome]:
    if seed not in outcomes:
        outcomes[seed] = run_schedule(patrol, seed)
    return outcomes[seed]


@pytest.mark.slow
@pytest.mark.parametrize("first", range(0, RUNS, BLOCK), ids=lambda first: f"seeds-{first}-{first + BLOCK - 1}")
def test_a_thousand_fault_schedules_keep_every_invariant(patrol: Patrol, outcomes: dict[int, tuple[Schedule, Outcome]],
                                                         first: int) -> None:
    failures = {}
    for seed in range(first, first + BLOCK):
        _, out = outcome(patrol, outcomes, seed)
        if out.violations:
            failures[seed] = out.violations[:3]
    assert not failures, (f"{len(failures)} of the {BLOCK} schedules from seed {first} broke an invariant: "
                          f"{dict(list(failures.items())[:5])}")


@pytest.mark.slow
def test_the_thousand_fault_schedules_exercise_every_fault(patrol: Patrol,
                                                           outcomes: dict[int, tuple[Schedule, Outcome]]) -> None:
    """The schedules exercise the outage, the fault latch and its recovery, the stop zone and a moving patrol."""
    outages = faulted = resumed = inside = stops = moved = legs = 0
    for seed in range(RUNS):
        sch, out = outcome(patrol, outcomes, seed)
        outages += sch.outage is not None
        faulted += out.faults > 0
        resumed += out.resumed_t is not None
        inside += out.inside > 0
        stops += out.stop_zone
        moved += out.distance_m >= MOVED_M
        legs += out.legs_done
    assert outages > RUNS // 3 and faulted >= outages and resumed == outages, (outages, faulted, resumed)
    assert inside > RUNS // 20 and stops > RUNS // 50, (inside, stops)
    assert moved > RUNS // 2 and legs > RUNS // 20, (moved, legs)


def test_a_schedule_is_repeatable(patrol: Patrol) -> None:
    assert schedule(42) == schedule(42)
    first = run_schedule(patrol, 42)[1]
    again = run_schedule(patrol, 42)[1]  # an earlier time than where the recording is: recorded again from 0
    elsewhere = Patrol()
    try:
        third = run_schedule(elsewhere, 42)[1]
    finally:
        elsewhere.close()
    assert first.violations == again.violations == third.violations == []
    assert first == again == third


def test_a_motor_cut_off_from_its_driver_stops_within_half_a_second(patrol: Patrol) -> None:
    """A clean link cut for 0.8 s while the base drives along the first leg: the driver latches the fault, both
    motors stop by themselves, the base comes to rest, the fault clears and the patrol goes on."""
    t0 = start_time(30)
    sch = Schedule(30, FaultPlan(outages=((t0 + 0.3, t0 + 1.1),), seed=1), 0.0, (t0 + 0.3, t0 + 1.1), None, 0.0)
    snap = patrol.at(t0)
    assert snap.sim.base.v_mps > 0.2  # driving
    _, out = run_schedule(patrol, 1, sch)
    assert out.violations == []
    assert out.faults == 1 and len(out.cleared) == 1 and out.cleared[0] - (t0 + 1.1) <= 0.2
    assert out.resumed_t is not None


def test_an_obstacle_in_the_stop_zone_holds_the_base_on_a_lossy_link(patrol: Patrol) -> None:
    """Turning on the spot at the first waypoint, the base gets an obstacle put down just outside its footprint,
    inside the stop distance: while it is there the pipeline never commands towards it, and the base never
    touches it (the patrol goes on round it)."""
    start = 95
    snap = patrol.at(start_time(start))
    assert abs(snap.sim.base.v_mps) < 0.05 and abs(snap.sim.base.w_radps) > 0.5  # turning on the spot
    sch = Schedule(start, FaultPlan(drop=0.2, delay=0.2, delay_s=0.05, reorder=0.1, seed=3), 0.0, None,
                   Obstacle(start_time(start) + 0.1, 0.0, 0.0, 0.2), 2.0)
    _, out = run_schedule(patrol, 3, sch)
    assert out.violations == []
    assert out.inside > CONTROL_HZ  # more than a second of ticks with something inside the stop distance
    assert 0.0 <= out.closest_m < 0.05
