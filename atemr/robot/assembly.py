"""`build_robot`: the one place where the robot is wired from its configuration.

Order matters only for parts due at the same instant (the scheduler runs ties in the order parts were
added): the simulated world moves first, then the emulated hardware answers, then the primary side
reads its inputs, decides (motion control) and sends (motor driver), then the agent looks at the result.

In simulation every participant on the CAN bus (the primary, each motor emulator, the secondary core)
has its own python-can Bus on the robot's virtual channel, exactly as the separate devices share one wire
on the robot. On the real robot (``simulation: false``) only the primary's parts are built, on socketcan.
The primary has one Bus, received by a `BusSupervisor` (polled in simulation, a Notifier thread on the
robot) that hands the frames to the motor driver and the secondary-core link through their inboxes and
reports bus-off, a dead receive side and a failing listener as the ``can_bus`` fault.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from atemr.clock import Clock, RealTimeSimClock, SimClock, WallClock
from atemr.config import Config
from atemr.domain.status import ComponentHealth
from atemr.errors import AtemrError, ConfigError, HardwareError
from atemr.fsm.agent import DEFAULT_AGENT_FILE, Agent
from atemr.io.can.supervisor import BusSupervisor
from atemr.io.devices.base import Device, fresh
from atemr.io.devices.drivers import (
    DeviceContext,
    Devices,
    Frame,
    build_devices,
    depth_mount,
    driver_name,
    needs_world,
)
from atemr.io.map_store import BUILTIN_MAPS, MapStore
from atemr.io.motors.driver import RmdDriver
from atemr.io.recording.mcap_writer import SUFFIX, RecordingWriter
from atemr.io.secondary_link import SecondaryLink, build_secondary_link
from atemr.io.sim.simulation import FrameSource, Simulation
from atemr.io.system_monitor import SystemMonitor
from atemr.msgs import Pose2D, Twist, WheelSpeeds
from atemr.robot.battery import RATE_HZ as BATTERY_HZ
from atemr.robot.battery import BatteryGauge
from atemr.robot.core import Robot
from atemr.robot.health import FRESH_S, HealthBoard
from atemr.robot.inputs import CAN_BUS_STOP, HEARTBEAT_STOP, MotionInputs
from atemr.robot.mapping import MapService
from atemr.robot.navigation import RobotNavigation
from atemr.robot.parts import RobotParts
from atemr.robot.port import RobotPortImpl, SecondaryLinkPort, jpeg
from atemr.robot.recorder import RATE_HZ as RECORDER_HZ
from atemr.robot.recorder import MessageSink, RecorderSources, RunRecorder
from atemr.robot.reload import RATE_HZ as RELOAD_RATE_HZ
from atemr.robot.reload import ReloadWatcher
from atemr.robot.settings_store import SettingsStore
from atemr.robot.wheels import WheelOdometryFeed
from atemr.scheduler import Component, Scheduler
from atemr.skills.localization.pipeline import LocalizationPipeline
from atemr.skills.motion_pipeline import ControlInputs, MotionControl, MotionPipeline
from atemr.skills.nav.voxel_layer import VoxelLayerParams
from atemr.skills.ramp import checked_limits

if TYPE_CHECKING:
    from atemr.io.secondary_emulator.board import SecondaryCore
    from atemr.io.sim.battery import SimBattery

log = logging.getLogger(__name__)

#: Tick rates of the primary's periodic work, in Hz (the simulator's own rates are in ``sim.*``).
RATES = {
    "can_bus": 50.0,
    "localization": 10.0,
    "motor_emulator": 100.0,
    "secondary_link": 50.0,
    "motion": 50.0,
    "odometry": 50.0,
    "agent": 10.0,
    "system_monitor": 1.0,
    "reload_watcher": RELOAD_RATE_HZ,
}


def make_clock(config: Config, *, realtime: bool) -> Clock:
    """The clock for this run: wall clock on the robot; simulated, paced or not, in simulation."""
    if not config.simulation:
        return WallClock()
    return RealTimeSimClock(speed=config.sim.speed) if realtime else SimClock()


def build_robot(config: Config, *, realtime: bool = True, clock: Clock | None = None) -> Robot:
    """Assemble the robot described by ``config``.

    ``realtime`` paces a simulation against the wall clock (``./run``); without it the simulation runs
    as fast as the CPU allows (``atemr sim --headless``, tests). ``clock`` overrides both.
    """
    clock = clock or make_clock(config, realtime=realtime)
    scheduler = Scheduler(clock, realtime=realtime or not config.simulation)
    robot = Robot(config, clock, scheduler)
    scheduler.on_error = lambda component, exc: _on_component_error(robot, component, exc)
    try:
        _wire(robot)
    except BaseException:
        robot.close_buses()  # a robot that could not be built leaves no bus open behind it
        raise
    return robot


def _wire(robot: Robot) -> None:
    """Every part of ``robot``, in the order the module docstring explains."""
    config, clock = robot.config, robot.clock
    settings = SettingsStore(config.data_dir)
    inputs = MotionInputs()
    health = HealthBoard(clock.now)

    sim, board = _add_simulation(robot) if needs_world(config) else (None, None)
    devices = _add_devices(robot, health, sim)
    primary = _add_primary(robot, inputs, health, settings, devices)
    store, localization, maps, wheels = _add_localization(robot, sim, devices, primary.driver)
    battery, sim_battery = _add_battery(robot, primary.driver, maps, sim)
    port, navigation, agent, watcher = _add_agent(robot, primary, inputs=inputs, health=health,
                                                  frame=_frame_reader(robot, devices.camera, "camera", sim),
                                                  devices=devices,
                                                  localization=localization, maps=maps, battery=battery)
    system_monitor = SystemMonitor(config.data_dir)  # scheduled last of the always-present parts, below
    robot.parts = RobotParts(
        settings=settings, inputs=inputs, health=health, devices=devices, driver=primary.driver, link=primary.link,
        pipeline=primary.pipeline, motion=primary.motion, map_store=store, localization=localization, maps=maps,
        wheels=wheels, port=port, navigation=navigation, agent=agent, reload_watcher=watcher,
        system_monitor=system_monitor, sim=sim, secondary_board=board, battery=battery, sim_battery=sim_battery,
    )
    if config.agent.routines:
        _add_routines(robot)
    _add_recorder(robot)
    if config.ui.enabled:
        from atemr.robot.dashboard import add_dashboard  # lazy: headless runs never import Flask

        add_dashboard(robot)
    elif config.ui.message_queue is not None:
        from atemr.robot.dashboard import add_state_publisher

        add_state_publisher(robot, config.ui.message_queue)
    else:
        # Headless: no web server is expected, so its absence is not a fault (0x153 bit 5 stays set).
        health.add("webserver", lambda now: ComponentHealth(True, "dashboard disabled (headless run)"))
    robot.add(system_monitor, RATES["system_monitor"])
    if config.control.enabled:
        _add_control(robot)


def _add_routines(robot: Robot) -> None:
    """The care routines (`atemr.robot.routines`): after the agent, on a calendar from the robot's clock (in
    simulation ``sim.start_time`` plus the simulated seconds, so a simulated day is repeatable)."""
    from atemr.io.routine_store import RoutineStore
    from atemr.robot.routines import RATE_HZ, Calendar, RoutineRunner, parse_start_time

    cfg, parts = robot.config, robot.parts
    if cfg.simulation:
        start = parse_start_time(cfg.sim.start_time)
        calendar = Calendar(robot.clock, start if start is not None else WallClock().wall_time())
    else:
        calendar = Calendar(robot.clock)
    localization, maps = parts.localization, parts.maps
    runner = RoutineRunner(RoutineStore(cfg.data_dir), parts.agent,
                           Path(parts.agent.spec.file or DEFAULT_AGENT_FILE).parent / "missions", calendar=calendar,
                           places=lambda: maps.places, localized=lambda: localization.localized, event=robot.event,
                           battery=parts.battery.forbids_task)
    robot.add(runner, RATE_HZ)
    robot.parts = replace(robot.parts, routines=runner)


def _add_battery(robot: Robot, driver: RmdDriver, maps: MapService,
                 sim: Simulation | None) -> tuple[BatteryGauge, SimBattery | None]:
    """The battery gauge (`atemr.robot.battery`), which the agent's Monitor reads through the port; in simulation
    with emulated motors, the simulated pack that supplies them (`atemr.io.sim.battery`), charging on the active
    map's dock. Added before the agent, so the Monitor sees each reading in the tick it was taken."""
    from atemr.io.sim.base import MountedWheel
    from atemr.io.sim.battery import SimBattery

    cfg = robot.config
    pack = None
    # the emulated motors' models, which the pack supplies (a wheel that is not a mounted motor model has none)
    motors = [w.model for w in (sim.left, sim.right) if isinstance(w, MountedWheel)] if sim is not None else []
    if sim is not None and driver_name(cfg, "motors") == "emulated" and len(motors) == 2:
        world = sim

        def dock_pose() -> Pose2D | None:
            dock = maps.places.dock()
            return None if dock is None else dock.pose

        pack = SimBattery(cfg.battery, motors, capacity_wh=cfg.sim.battery_wh,
                          percent=cfg.sim.battery_percent, base_load_w=cfg.sim.battery_base_load_w,
                          charge_s=cfg.sim.battery_charge_s, pose=lambda: world.pose, dock=dock_pose)
        robot.add(pack, 10.0)
    gauge = BatteryGauge(cfg.battery, driver, event=robot.event)
    robot.add(gauge, BATTERY_HZ)
    return gauge, pack


def _add_control(robot: Robot) -> None:
    """The local control channel (`atemr.robot.control`): a Unix socket another terminal of the same user
    runs missions through. Added after the agent at the agent's rate, so it sees each tick's outcome at once."""
    from atemr.robot.control import RobotControl

    control = RobotControl(robot, robot.parts.agent, localization=robot.parts.localization, sim=robot.parts.sim)
    robot.add(control, robot.config.agent.rate_hz)
    robot.parts = replace(robot.parts, control=control)


def _add_localization(robot: Robot, sim: Simulation | None, devices: Devices,
                      driver: RmdDriver) -> tuple[MapStore, LocalizationPipeline, MapService, WheelOdometryFeed]:
    """Odometry fusion + AMCL against the active map, and the map service (active map, mapping)."""
    cfg = robot.config
    # The shipped maps are maps of simulated worlds: a robot without one is offered only the maps it made
    # or was given.
    builtins = dict(BUILTIN_MAPS) if sim is not None else {}
    if sim is not None and sim.world.source is not None:
        builtins.setdefault(sim.world.name, sim.world.source)
    store = MapStore(cfg.data_dir, builtins=builtins, max_cells=cfg.ui.max_map_cells,
                     max_upload_bytes=int(cfg.ui.max_upload_mb * 1024 * 1024))
    simulated_lidar = driver_name(cfg, "lidar") == "sim"
    lidar_range_m = cfg.sim.lidar_range_m if simulated_lidar else cfg.devices.lidar.range_max_m
    rng = np.random.default_rng(cfg.localization.seed)
    localization = LocalizationPipeline(None, rng, localizer=cfg.localization.localizer_params(lidar_range_m))
    maps = MapService(store, localization, cfg.localization.slam_params(), on_event=robot.event)

    wheels = WheelOdometryFeed(driver, localization)
    robot.add(wheels, RATES["odometry"])
    robot.add(localization, cfg.sim.lidar_hz if simulated_lidar else RATES["localization"])
    devices.lidar.subscribe(localization.on_scan)
    devices.lidar.subscribe(maps.on_scan)
    devices.imu.subscribe(localization.on_imu)
    if cfg.simulation and sim is not None:
        # The simulated robot starts where its world says, on that world's map, localized there: as if
        # the operator had selected the map and clicked the initial pose.
        maps.activate(sim.world.name, sim.world.map)
        localization.set_initial_pose(robot.clock.now(), sim.world.start)
    else:
        # A real robot starts unlocalized, on the map the operator last selected (if any): never on a map
        # it was not given, and never at a pose nobody set.
        name = store.selected_name()
        if name is not None:
            maps.activate(name)
    return store, localization, maps, wheels


F = TypeVar("F")


def _frame_reader(robot: Robot, camera: Device[F] | None, kind: str, sim: Simulation | None,
                  ) -> Callable[[], F | None]:
    """How a part that needs one frame now reads the ``kind`` camera (``camera`` or ``depth``): the agent's mission
    step storing a picture, the recording when its next frame is due. The device's newest frame; from a simulated
    camera, rendered at once when no consumer has kept it rendering (`FrameSource.request`: both read on the
    scheduler's thread, where rendering is safe), so each frame they keep is rendered once."""
    if camera is None:
        return lambda: None
    if sim is not None and driver_name(robot.config, kind) == "sim":
        source: FrameSource[Any] = sim.camera_source if kind == "camera" else sim.depth_source
        now = robot.clock.now
        return lambda: source.request(now())
    return lambda: camera.latest


def _add_agent(
    robot: Robot, primary: _Primary, *, inputs: MotionInputs, health: HealthBoard, frame: Callable[[], Frame | None],
    devices: Devices, localization: LocalizationPipeline, maps: MapService, battery: BatteryGauge,
) -> tuple[RobotPortImpl, RobotNavigation, Agent, ReloadWatcher]:
    """The agent (lifecycle + trees + Monitor) over the robot's ports; when it halts, the robot stops."""
    cfg = robot.config
    port = RobotPortImpl(
        now=robot.clock.now, inputs=inputs, health=health, localization=localization, maps=maps, camera=frame,
        images_dir=cfg.data_dir / "media" / "images", wall_time=WallClock().wall_time,
        battery=battery.status, event=robot.event,
    )
    control = primary.motion

    def measured() -> Twist | None:
        return None if control.last is None else control.last.twist

    # The depth camera's obstacle layer (nav.depth_layer): up to the robot's height, into the costmap and the zones.
    voxels = VoxelLayerParams.for_body(cfg.robot_body()) if cfg.nav.depth_layer else None
    navigation = RobotNavigation(maps, localization, scan=lambda: devices.lidar.latest, velocity=measured,
                                 params=cfg.nav.nav_params(primary.pipeline.limits), depth=devices.depth,
                                 depth_layer=voxels, on_clearance=inputs.set_depth_clearance)
    agent = Agent.from_config(cfg, port, SecondaryLinkPort(primary.link), navigation=navigation, on_halt=robot.stop)
    robot.add(agent, cfg.agent.rate_hz)
    # Hot reload: edits of the agent document and the missions are validated and handed to the agent.
    watcher = ReloadWatcher(agent, Path(agent.spec.file or DEFAULT_AGENT_FILE))
    robot.add(watcher, RATES["reload_watcher"])
    return port, navigation, agent, watcher


def trace_path(config: Config, wall_time: float) -> Path:
    """Where this run's recording goes: ``trace.file``, else a new ``data_dir/traces/run-<local date-time>.mcap``."""
    if config.trace.file is not None:
        if config.trace.file.suffix.lower() != SUFFIX:
            raise ConfigError(f"recordings are MCAP files: name it *{SUFFIX}, got {config.trace.file.name!r}",
                              path="trace.file")
        return config.trace.file
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(wall_time))
    path = config.data_dir / "traces" / f"run-{stamp}{SUFFIX}"
    n = 1
    while path.exists():  # two runs in one second keep both recordings
        n += 1
        path = path.with_name(f"run-{stamp}-{n}{SUFFIX}")
    return path


def _recording_writer(robot: Robot, meta: dict[str, object]) -> RecordingWriter | None:
    """The MCAP writer when ``trace.enabled`` or ``trace.file`` is set: threaded on a paced robot, inline in a
    headless simulation (repeatable, nothing dropped)."""
    cfg = robot.config
    if not cfg.trace.enabled and cfg.trace.file is None:
        return None
    wall = WallClock().wall_time()
    metadata = {k: "" if v is None else str(v) for k, v in meta.items()}
    metadata["started"] = time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(wall))
    mode = cfg.trace.writer
    if mode == "auto":
        mode = "process" if robot.scheduler.realtime else "inline"
    options = {"max_bytes": int(cfg.trace.max_file_mb * 1024 * 1024),
               "max_files": None if cfg.trace.file is not None else cfg.trace.max_files,
               "prune": f"run-*{SUFFIX}", "metadata": metadata}
    path = trace_path(cfg, wall)
    if mode == "process":
        from atemr.io.recording.writer_process import ProcessRecordingWriter

        return ProcessRecordingWriter(path, **options)
    return RecordingWriter(path, threaded=mode == "thread", **options)  # type: ignore[arg-type]


def _add_recorder(robot: Robot) -> None:
    """Record the run (`RunRecorder` → `RecordingWriter`) and serve it live (``ui.foxglove``), when asked."""
    cfg, parts = robot.config, robot.parts
    sim = parts.sim
    meta: dict[str, object] = {"world": cfg.sim.world if sim is not None else None,
                               "seed": cfg.sim.seed if sim is not None else None,
                               "map": parts.maps.active_name, "simulation": cfg.simulation}
    writer = _recording_writer(robot, meta)
    live = None
    if cfg.ui.foxglove.enabled:
        try:
            from atemr.ui.foxglove import FoxgloveLive  # lazy: the SDK loads only when the live view is on
        except ImportError:
            raise ConfigError("the live view needs the Foxglove SDK: pip install 'atemr[foxglove]'",
                              path="ui.foxglove.enabled") from None
        live = FoxgloveLive(cfg.ui.foxglove.host, cfg.ui.foxglove.port, robot_name=cfg.secondary.robot_name)
    sinks: list[MessageSink] = []
    if writer is not None:
        sinks.append(writer)
    if live is not None:
        sinks.append(live)
    if not sinks:
        return
    sources = RecorderSources(devices=parts.devices, localization=parts.localization, maps=parts.maps,
                              navigation=parts.navigation, agent=parts.agent, health=parts.health, sim=sim,
                              can_tap=robot.open_bus(), jpeg=jpeg,
                              camera_frame=_frame_reader(robot, parts.devices.camera, "camera", sim),
                              depth_frame=_frame_reader(robot, parts.devices.depth, "depth", sim))
    recorder = RunRecorder(sources, sinks, camera_hz=cfg.trace.camera_hz, depth_hz=cfg.trace.depth_hz,
                           pose_hz=cfg.trace.pose_hz, meta=meta, threaded_maps=robot.scheduler.realtime)
    if writer is not None:
        writer.preamble = recorder.preamble
    recorder.attach()
    parts.wheels.subscribe(recorder.on_wheels)
    robot.event_listeners.append(recorder.on_event)
    if live is not None:
        robot.add(live, 1.0)  # started before the recorder, stopped after it
    robot.add(recorder, RECORDER_HZ)
    if writer is not None:
        robot.add(writer, 1.0)
    robot.parts = replace(parts, trace=writer, recorder=recorder, foxglove=live)


def _add_simulation(robot: Robot) -> tuple[Simulation, SecondaryCore | None]:
    """The simulated world, with the emulated CAN devices the configuration asks for in it.

    With ``emulated`` motors, the two motor emulators answer on the robot's bus and their models are the
    simulated base's wheels; with real motors, the world's wheels are models nobody commands (the world then
    only feeds the simulated sensors, for bench work). With an ``emulated`` secondary core, the emulated board
    answers on the bus and reads the world's cliff sensors.
    """
    from atemr.io.motors.emulator import RmdMotorEmulator
    from atemr.io.secondary_emulator.board import SecondaryCore
    from atemr.io.secondary_emulator.wiring import emulated_secondary
    from atemr.io.sim.base import MountedWheel
    from atemr.io.sim.simulation import build_simulation, params_from_config

    cfg = robot.config
    emulators: list[RmdMotorEmulator] = []
    wheels = None
    if driver_name(cfg, "motors") == "emulated":
        protocol = cfg.devices.motors.protocol
        left = RmdMotorEmulator(robot.open_bus(), cfg.motors.left_id, name="left_motor_emulator", steps_model=False,
                                protocol=protocol)
        right = RmdMotorEmulator(robot.open_bus(), cfg.motors.right_id, name="right_motor_emulator",
                                 steps_model=False, protocol=protocol)
        emulators = [left, right]
        wheels = (MountedWheel(left.model, cfg.motors.left_direction),
                  MountedWheel(right.model, cfg.motors.right_direction))
    params = params_from_config(cfg.sim, cfg.robot_body(), depth_mount(cfg.devices.depth))
    if driver_name(cfg, "depth") != "sim":
        params = replace(params, depth_hz=0.0)  # nobody reads the simulated depth camera: do not render it
    # Frames are rendered for the consumers the robot's parts register (`FrameSource`), never for nobody.
    params = replace(params, frames_on_demand=True)
    sim = build_simulation(cfg.sim.world, cfg.sim.seed, params=params, wheels=wheels)
    for component, rate in sim.components():
        robot.add(component, rate)
    for emulator in emulators:
        robot.add(emulator, RATES["motor_emulator"])
    board: SecondaryCore | None = None
    if driver_name(cfg, "secondary") == "emulated":
        for board_part, rate in emulated_secondary(cfg, robot.open_bus(), lambda: sim.cliff_source.latest):
            robot.add(board_part, rate)
            if isinstance(board_part, SecondaryCore):
                board = board_part
    return sim, board


def _add_devices(robot: Robot, health: HealthBoard, sim: Simulation | None) -> Devices:
    """The lidar, the IMU and the camera with their configured drivers (`atemr.io.devices.drivers`): the only
    way the rest of the robot reads its sensors. Each reports its own health under its kind's name."""
    devices = build_devices(DeviceContext(robot.config, robot.clock.now, sim))
    for device in devices.all():
        if device.rate_hz is not None:
            robot.add(device, device.rate_hz)
        health.add(device.name, device.health)
    return devices


@dataclass(frozen=True)
class _Primary:
    """What `_add_primary` wires: the motor driver, the secondary-core link, and the motion control."""

    driver: RmdDriver
    link: SecondaryLink
    pipeline: MotionPipeline
    motion: MotionControl


#: The safety-stop reason held while the CAN bus is faulted (`MotionInputs.set_safety_stop`).


def _add_can_bus(robot: Robot, inputs: MotionInputs, health: HealthBoard) -> BusSupervisor:
    """The primary's CAN bus and its supervisor, the one receiver for the driver and the link (`inbox`).

    A bus fault (bus-off, ``recv`` failing, the receive thread dead, a listener raising) holds a safety stop,
    so both motors are commanded to zero at once (no ramp), and makes ``can_bus`` unhealthy, which the agent's
    Monitor turns into a fault naming it (``trees/agent.yaml``). The fault is not critical (see
    `atemr.io.can.supervisor`): the agent waits in Error until `BusSupervisor.recover` sees the bus carry frames
    again with no error for its ``settle_s``, then the stop is released and the agent returns to Idle.
    """
    cfg = robot.config

    def on_fault(fault: HardwareError) -> None:
        inputs.set_safety_stop(CAN_BUS_STOP, True)
        robot.event("can bus", f"{fault}: motors stopped")

    supervisor = BusSupervisor(robot.open_bus(), threaded=not cfg.simulation, name="can_bus", on_fault=on_fault,
                               close_bus=False)  # the robot closes the bus after every part has shut down
    robot.add(supervisor, RATES["can_bus"])  # before the parts that read its inboxes
    health.add("can_bus", lambda now: ComponentHealth(supervisor.fault is None, supervisor.problem or ""))

    def clear_bus_fault() -> str | None:
        why = supervisor.recover()
        if why is None and CAN_BUS_STOP in inputs.safety_stops:
            inputs.set_safety_stop(CAN_BUS_STOP, False)
            robot.event("can bus", "cleared: frames arrive again")
        return why

    health.add_recovery("can_bus", clear_bus_fault)
    return supervisor


def _add_primary(robot: Robot, inputs: MotionInputs, health: HealthBoard, settings: SettingsStore,
                 devices: Devices) -> _Primary:
    """The primary core: CAN bus supervisor, secondary-core link, motion control, motor driver, odometry."""
    cfg = robot.config
    lidar = devices.lidar
    can_bus = _add_can_bus(robot, inputs, health)

    def on_heartbeat(ok: bool) -> None:
        # docs/testing.md#what-the-robot-promises: both cores stop the motors when the heartbeat fails for 2 s.
        inputs.set_safety_stop(HEARTBEAT_STOP, not ok)
        robot.event("heartbeat", "0x157 heartbeat " + ("restored" if ok else "lost: motors stopped"))

    link_inbox, motors_inbox = can_bus.inbox("secondary_link"), can_bus.inbox("motors")
    robot.buses += [link_inbox, motors_inbox]  # closed with the buses even if the supervisor never started
    link = build_secondary_link(cfg, link_inbox, on_heartbeat=on_heartbeat)
    robot.add(link, RATES["secondary_link"])

    def on_fault(fault: HardwareError) -> None:
        robot.event("motor fault", str(fault))

    driver = RmdDriver.from_config(motors_inbox, cfg.motors, protocol=cfg.devices.motors.protocol, on_fault=on_fault)
    stored = settings.load()
    limits = cfg.motion
    if isinstance(stored.get("motion"), dict):
        try:
            limits = checked_limits(stored["motion"], cfg.motion)
        except AtemrError as exc:
            log.error("ignoring stored speed limits: %s", exc)
    inputs.awareness = bool(stored.get("reactive", {}).get("awareness", False))
    pipeline = MotionPipeline(limits)

    def read(now: float) -> ControlInputs:
        return inputs.control_inputs(now, lidar.latest, link.latest_cliff())

    def command(wheels: WheelSpeeds) -> None:
        # A latched motor fault already stops both motors (the driver keeps sending the stop); the
        # pipeline's command is dropped until the agent's recovery resets the fault.
        if driver.fault is None:
            driver.set_speeds(wheels, robot.clock.now())

    control = MotionControl(pipeline, read, command)
    robot.add(control, RATES["motion"])
    robot.add(driver, cfg.motors.rate_hz)

    health.add("left_motor", lambda now: driver.side_health("left", now))
    health.add("right_motor", lambda now: driver.side_health("right", now))

    def clear_motor_fault() -> str | None:
        # The agent's Error state calls this while it waits: the latched fault is reset only once both motors
        # answer again (the driver keeps polling them) and report no error flag; until then why not.
        latched = driver.fault is not None
        why = driver.recover(robot.clock.now())
        if latched and why is None:
            robot.event("motor fault", "cleared: both motors answer with no error flag")
        return why

    health.add_recovery("motors", clear_motor_fault)

    def cliff(which: str) -> Callable[[float], ComponentHealth]:
        def probe(now: float) -> ComponentHealth:
            reading = link.latest_cliff()
            return fresh(None if reading is None else reading.t, now, FRESH_S["ir"], f"IR {which} frame")
        return probe

    health.add("ir_front", cliff("front"))
    health.add("ir_rear", cliff("rear"))

    def connectivity(now: float) -> ComponentHealth:
        # 0x153 agent bit 3: the robot has a network address the operator can reach it on.
        ip = link.network.ip_address()
        return ComponentHealth(ip is not None, f"address {ip}" if ip else "no network address")

    health.add("connectivity", connectivity)
    return _Primary(driver=driver, link=link, pipeline=pipeline, motion=control)


def _on_component_error(robot: Robot, component: Component, exc: BaseException) -> None:
    """A part's tick raised: record it for the operator; the loop goes on (the part's own health shows it)."""
    log.error("%s failed: %s", component.name, exc, exc_info=not isinstance(exc, AtemrError))
    robot.event("component error", f"{component.name}: {exc}")


__all__ = ["CAN_BUS_STOP", "RATES", "build_robot", "make_clock", "trace_path"]
