"""`RobotParts`: everything `build_robot` wires, by name and type.

The scheduler knows the robot's components by their names (`Robot.components`); code that needs a part as
what it is (the gateway reading the map service, a test poking the simulation) takes it from here, typed, so
mypy checks the wiring and a newcomer sees in one place what a robot is made of.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from atemr.fsm.agent import Agent
    from atemr.io.devices.drivers import Devices
    from atemr.io.map_store import MapStore
    from atemr.io.motors.driver import RmdDriver
    from atemr.io.recording.mcap_writer import RecordingWriter
    from atemr.io.secondary_emulator.board import SecondaryCore
    from atemr.io.secondary_link import SecondaryLink
    from atemr.io.sim.battery import SimBattery
    from atemr.io.sim.simulation import Simulation
    from atemr.io.system_monitor import SystemMonitor
    from atemr.robot.battery import BatteryGauge
    from atemr.robot.control import RobotControl
    from atemr.robot.gateway import RobotGatewayImpl
    from atemr.robot.health import HealthBoard
    from atemr.robot.inputs import MotionInputs
    from atemr.robot.mapping import MapService
    from atemr.robot.navigation import RobotNavigation
    from atemr.robot.port import RobotPortImpl
    from atemr.robot.recorder import RunRecorder
    from atemr.robot.reload import ReloadWatcher
    from atemr.robot.routines import RoutineRunner
    from atemr.robot.settings_store import SettingsStore
    from atemr.robot.wheels import WheelOdometryFeed
    from atemr.skills.localization.pipeline import LocalizationPipeline
    from atemr.skills.motion_pipeline import MotionControl, MotionPipeline
    from atemr.ui.foxglove import FoxgloveLive
    from atemr.ui.message_queue import StatePublisher
    from atemr.ui.server import DashboardServer


@dataclass(frozen=True)
class RobotParts:
    """The parts of one assembled robot (see `atemr.robot.assembly` for how they connect).

    ``sim`` is the simulated world when one runs (in simulation, or for devices driven by it); the dashboard,
    the state publisher, the control socket, the recording and the Foxglove server
    exist when the configuration asks for them.
    """

    settings: SettingsStore
    inputs: MotionInputs
    health: HealthBoard
    devices: Devices
    driver: RmdDriver
    link: SecondaryLink
    pipeline: MotionPipeline
    motion: MotionControl
    map_store: MapStore
    localization: LocalizationPipeline
    maps: MapService
    wheels: WheelOdometryFeed
    port: RobotPortImpl
    navigation: RobotNavigation
    agent: Agent
    reload_watcher: ReloadWatcher
    system_monitor: SystemMonitor
    #: The state of charge from the motors' supply voltage (the agent's Monitor reacts to it).
    battery: BatteryGauge
    sim: Simulation | None = None
    #: The emulated secondary core's board, when the simulation runs one (its screen and button on the page).
    secondary_board: SecondaryCore | None = None
    #: The MCAP recording of this run (``trace.enabled`` or ``trace.file``).
    trace: RecordingWriter | None = None
    recorder: RunRecorder | None = None
    foxglove: FoxgloveLive | None = None
    gateway: RobotGatewayImpl | None = None
    dashboard: DashboardServer | None = None
    state_publisher: StatePublisher | None = None
    control: RobotControl | None = None
    #: The care routines (scheduled missions), `atemr.robot.routines`.
    routines: RoutineRunner | None = None
    #: The simulated pack (simulation with emulated motors): the truth the estimate is checked against.
    sim_battery: SimBattery | None = None
