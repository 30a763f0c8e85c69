"""The robot's configuration: one typed object, built once at start-up from layers.

Precedence, lowest first: defaults < config file (YAML) < environment (``ATEMR_SECTION__KEY``) <
explicit arguments (the CLI). Every layer is validated by `atemr.typed.merge_into`, so an error names
the key and where it came from, unknown keys are errors, and a bad layer changes nothing.
Issues add their own section dataclass here; nothing else in the package reads the environment.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from atemr.errors import ConfigError
from atemr.io.devices.config import DevicesConfig
from atemr.skills.battery import BatteryParams
from atemr.skills.body import BodyConfig, RobotBody
from atemr.skills.localization.config import LocalizationConfig
from atemr.skills.nav.config import NavConfig
from atemr.skills.ramp import MotionLimits
from atemr.typed import Source, field_paths, merge_into, nest
from atemr.ui.permissions import PERMISSIONS, Permission
from atemr.yamlsafe import load_yaml

ENV_PREFIX = "ATEMR_"
#: Environment variables with the prefix that are not configuration keys: the configuration file's path, and
#: the Python the ``./run`` and ``./test`` launchers use.
ENV_RESERVED = {"ATEMR_CONFIG", "ATEMR_PYTHON"}
#: The test suite's and the benchmarks' own switches (``ATEMR_TEST_SOAK=1``) live under this prefix, so that
#: setting one never makes the robot they start refuse its configuration.
ENV_TEST_PREFIX = "ATEMR_TEST_"

#: URL schemes of the Socket.IO message queues the dashboard accepts (Redis, plain or TLS).
QUEUE_SCHEMES = ("redis://", "rediss://")

LogLevel = Literal["DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"]


def default_data_dir() -> Path:
    """Where maps, media, users and traces live: ``$XDG_DATA_HOME/atemr`` or ``~/.local/share/atemr``."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "atemr"


@dataclass(frozen=True)
class SimConfig:
    """The built-in simulator (used unless ``simulation`` is false)."""

    world: str = field(default="studio", metadata={"help": "a shipped world's name or a path to a world/map YAML"})
    seed: int = field(default=0, metadata={"min": 0, "help": "seed of every random source in the simulation"})
    speed: float = field(
        default=1.0, metadata={"min": 0.01, "max": 1000.0, "help": "real-time factor when locked to real time"}
    )
    physics_hz: float = field(default=100.0, metadata={"min": 10.0, "max": 2000.0, "help": "base physics rate"})
    lidar_hz: float = field(default=10.0, metadata={"min": 0.5, "max": 100.0, "help": "lidar revolutions per second"})
    lidar_beams: int = field(default=360, metadata={"min": 8, "max": 8192, "help": "beams per revolution"})
    lidar_noise_m: float = field(default=0.01, metadata={"min": 0.0, "max": 0.5, "help": "lidar range noise (std)"})
    lidar_range_m: float = field(default=8.0, metadata={
        "min": 1.0, "max": 40.0, "help": "farthest return the robot uses (the thesis robot: 8 m; the A2M8 measures to "
                                         "12 m); localization follows it"})
    lidar_dropout: float = field(
        default=0.005, metadata={"min": 0.0, "max": 0.9, "help": "fraction of beams with no return (NaN)"}
    )
    imu_hz: float = field(default=50.0, metadata={"min": 1.0, "max": 1000.0})
    cliff_hz: float = field(default=20.0, metadata={"min": 1.0, "max": 1000.0})
    camera_hz: float = field(default=10.0, metadata={"min": 0.0, "max": 60.0, "help": "camera frames/s (0: off)"})
    depth_hz: float = field(default=10.0, metadata={
        "min": 0.0, "max": 90.0, "help": "depth camera frames/s when the depth camera is the simulator's (0: off)"})
    camera_width: int = field(default=640, metadata={"min": 16, "max": 4096})
    camera_height: int = field(default=480, metadata={"min": 16, "max": 4096})
    camera_counter: bool = field(default=False, metadata={
        "help": "draw each camera frame's number as black/white blocks in its top-left corner (to measure video "
                "latency from capture to display: benchmarks/bench_drive_video.py)"})
    wheel_slip: float = field(default=0.02, metadata={"min": 0.0, "max": 0.4, "help": "typical wheel slip fraction"})
    odom_noise: float = field(
        default=0.01, metadata={"min": 0.0, "max": 0.4, "help": "encoder speed noise (fraction, std)"}
    )
    battery_wh: float = field(default=176.0, metadata={"min": 0.01, "max": 10_000.0,
                                                       "help": "simulated pack's energy when full, Wh"})
    battery_percent: float = field(default=100.0, metadata={"min": 0.0, "max": 100.0,
                                                            "help": "simulated pack's charge at start, %"})
    battery_base_load_w: float = field(default=15.0, metadata={"min": 0.0, "max": 1000.0,
                                                               "help": "what the electronics draw, W"})
    battery_charge_s: float = field(default=10_800.0, metadata={
        "min": 1.0, "max": 86_400.0, "help": "time on the dock that charges the simulated pack from empty to full, s"})
    start_time: str = field(default="", metadata={
        "help": "the calendar date and time the simulation starts at, for routines (ISO 8601 with its offset, "
                "e.g. 2026-03-29T08:55+02:00; empty: the wall clock when it starts)"})


@dataclass(frozen=True)
class CanConfig:
    """The CAN bus shared by the motors and the secondary core."""

    interface: str = field(default="virtual", metadata={"help": "python-can interface: virtual, socketcan, ..."})
    channel: str = field(default="atemr", metadata={"help": "bus channel (can0 on the robot)"})
    bitrate: int = field(default=1_000_000, metadata={"min": 10_000, "max": 1_000_000})
    log_file: Path | None = field(default=None, metadata={"help": "record the bus (.log, .asc, .blf)"})


@dataclass(frozen=True)
class MotorsConfig:
    """The two RMD-L-7015 drive motors on the CAN bus (requests on 0x140 + id; the protocol version is
    ``devices.motors.protocol``) and their driver's watchdogs."""

    left_id: int = field(default=1, metadata={"min": 1, "max": 32, "help": "left motor's RMD id (not 16-23)"})
    right_id: int = field(default=2, metadata={"min": 1, "max": 32, "help": "right motor's RMD id (not 16-23)"})
    left_direction: int = field(default=1, metadata={"choices": (1, -1), "help": "+1/-1: shaft sign for forward"})
    right_direction: int = field(default=-1, metadata={"choices": (1, -1), "help": "+1/-1: shaft sign for forward"})
    rate_hz: float = field(default=50.0, metadata={"min": 10.0, "max": 500.0, "help": "driver tick rate"})
    command_timeout_s: float = field(default=0.5, metadata={"min": 0.05, "max": 5.0, "help": "command watchdog"})
    silence_timeout_s: float = field(default=0.3, metadata={"min": 0.05, "max": 5.0, "help": "silent motor → fault"})
    status_period_s: float = field(default=0.2, metadata={"min": 0.02, "max": 5.0, "help": "status-1 poll period"})


@dataclass(frozen=True)
class FoxgloveConfig:
    """The live Foxglove WebSocket server (`atemr.ui.foxglove`): the recording's channels, live."""

    enabled: bool = field(default=False, metadata={"help": "serve the robot's channels to Foxglove"})
    host: str = field(default="127.0.0.1", metadata={"help": "address it listens on (0.0.0.0: all)"})
    port: int = field(default=8765, metadata={"min": 0, "max": 65535, "help": "TCP port (0: any free port)"})


#: What an ICE server URL starts with (RFC 7064, RFC 7065).
ICE_SCHEMES = ("stun:", "stuns:", "turn:", "turns:")


@dataclass(frozen=True)
class UiConfig:
    """The operator dashboard (Flask + Socket.IO). Paths left empty live under ``data_dir``."""

    enabled: bool = field(default=True, metadata={"help": "serve the dashboard (false: headless runs)"})
    host: str = field(default="127.0.0.1", metadata={"help": "address the dashboard listens on (0.0.0.0: all)"})
    port: int = field(default=5000, metadata={"min": 0, "max": 65535, "help": "TCP port (0: any free port)"})
    database: Path | None = field(default=None, metadata={"help": "users SQLite file (default data_dir/users.sqlite3)"})
    secret_key_file: Path | None = field(
        default=None, metadata={"help": "session signing key, generated on first start (default data_dir/ui.key)"}
    )
    max_upload_mb: float = field(default=50.0, metadata={"min": 0.001, "max": 4096.0, "help": "largest upload"})
    max_map_cells: int = field(default=4_000_000, metadata={
        "min": 10_000, "max": 50_000_000,
        "help": "largest map read (uploaded, stored or selected), in cells: width x height of its image, checked "
                "from the header before decoding (4 M = 2000 x 2000, 100 m x 100 m at 5 cm)"})
    login_max_failures: int = field(default=5, metadata={"min": 1, "help": "failed logins before HTTP 429"})
    login_lockout_s: float = field(default=300.0, metadata={"min": 1.0, "help": "how long a lockout lasts"})
    message_queue: str | None = field(
        default=None,
        metadata={"help": "Socket.IO message queue (redis://host:port/db): robots publish state there and "
                          "every dashboard worker on it delivers it; unset: one process",
                  "prefixes": QUEUE_SCHEMES},
    )
    login_max_failures_per_address: int = field(default=20, metadata={
        "min": 1, "help": "failed logins from one address (any usernames) within login_lockout_s before HTTP 429"})
    trusted_hosts: tuple[str, ...] = field(default=(), metadata={
        "help": "host names the dashboard answers to besides localhost, 127.0.0.1, ::1 and ui.host (others: "
                "HTTP 400, against DNS rebinding); comma-separated in the environment"})
    max_connections: int = field(default=64, metadata={
        "min": 4, "max": 10_000, "help": "connections served at once (pages, sockets, streams); more: HTTP 503"})
    user_permissions: tuple[Permission, ...] = field(default=(), metadata={
        "help": "destructive or safety actions the user role may do too (admin always may): any of "
                + ", ".join(PERMISSIONS) + "; comma-separated in the environment"})
    screen_auto_answer: bool = field(default=False, metadata={
        "help": "the robot's screen answers a call at once (for a resident who cannot reach the screen)"})
    ice_servers: tuple[str, ...] = field(default=(), metadata={
        "help": "STUN/TURN server URLs for calls (stun:host:3478, turn:host:3478?transport=udp, turns:...); empty: "
                "host candidates only, enough on one LAN; comma-separated in the environment"})
    ice_username: str | None = field(default=None, metadata={"help": "username for the turn:/turns: servers"})
    ice_credential: str | None = field(default=None, metadata={"help": "credential for the turn:/turns: servers"})
    ice_secret: str | None = field(default=None, metadata={
        "help": "the TURN server's shared secret (coturn: use-auth-secret, static-auth-secret): each call and "
                "drive video gets its own credentials, valid for ui.ice_credential_ttl_s, instead of the fixed "
                "ui.ice_username/ui.ice_credential that every browser would keep"})
    ice_credential_ttl_s: float = field(default=3600.0, metadata={
        "min": 60.0, "max": 7 * 86400.0, "help": "how long a TURN credential made from ui.ice_secret is valid"})
    drive_video: Literal["webrtc", "mjpeg"] = field(default="webrtc", metadata={
        "help": "how the Control page gets the drive camera: webrtc (lower latency; needs aiortc, the webrtc extra; "
                "MJPEG whenever WebRTC cannot be had) or mjpeg only"})
    drive_video_max_peers: int = field(default=3, metadata={
        "min": 1, "max": 32, "help": "pages the robot sends WebRTC drive video to at once (each costs an encoder; "
                                     "more get MJPEG)"})
    tls_cert: Path | None = field(default=None, metadata={
        "help": "serve HTTPS with this PEM certificate (chain), e.g. from 'atemr tls make-cert': browsers give a "
                "page the camera and microphone (calls) only over HTTPS, or on localhost"})
    tls_key: Path | None = field(default=None, metadata={"help": "the private key (PEM) of ui.tls_cert"})
    foxglove: FoxgloveConfig = field(default_factory=FoxgloveConfig)

    def __post_init__(self) -> None:
        if (self.tls_cert is None) != (self.tls_key is None):
            missing = "ui.tls_key" if self.tls_key is None else "ui.tls_cert"
            raise ConfigError("HTTPS needs both ui.tls_cert and ui.tls_key", path=missing)
        for url in self.ice_servers:
            if not url.startswith(ICE_SCHEMES):
                raise ConfigError(f"ui.ice_servers: {url!r} must start with {', '.join(ICE_SCHEMES)}")
        if self.ice_secret is not None and (self.ice_username or self.ice_credential):
            raise ConfigError("set ui.ice_secret (credentials made per call) or ui.ice_username and "
                              "ui.ice_credential (fixed ones), not both", path="ui.ice_secret")
        turn = any(u.startswith(("turn:", "turns:")) for u in self.ice_servers)
        if turn and not (self.ice_username or self.ice_secret):
            raise ConfigError("ui.ice_servers names a TURN server: set ui.ice_secret (the server's shared secret), "
                              "or ui.ice_username and ui.ice_credential too")


@dataclass(frozen=True)
class SecondaryConfig:
    """The secondary core (the ESP32, or its emulator: ``devices.secondary.driver``) and the primary's side of
    its link."""

    robot_name: str = field(
        default="KAY",
        metadata={"help": "the robot's name: on the board's screens and in the dashboard's state (tells robots "
                          "apart on a shared message queue)"},
    )
    boot_s: float = field(default=3.0, metadata={"min": 0.0, "max": 60.0, "help": "length of the power-on sequence"})
    portal_serve: bool = field(default=True, metadata={"help": "serve the emulated captive portal while in CONFIG"})
    portal_host: str = field(default="127.0.0.1", metadata={"help": "captive portal address (0.0.0.0: all)"})
    portal_port: int = field(default=5001, metadata={"min": 0, "max": 65535, "help": "captive portal TCP port"})
    wifi_interface: str | None = field(default=None, metadata={"help": "WiFi device for nmcli (default: any)"})


@dataclass(frozen=True)
class AgentConfig:
    """The agent (`atemr.fsm.agent.Agent`): its lifecycle/tree document and tick rate."""

    file: Path | None = field(default=None, metadata={"help": "agent YAML (default: the shipped trees/agent.yaml)"})
    rate_hz: float = field(default=10.0, metadata={"min": 1.0, "max": 100.0, "help": "agent tick rate"})
    autonomy: Literal["off", "low", "high", "full"] = field(default="full", metadata={
        "help": "robot autonomy level at start: a transition above it waits for the operator (full: none wait)"})
    confirm_timeout_s: float = field(default=30.0, metadata={
        "min": 1.0, "max": 3600.0, "help": "robot seconds a gated transition waits for the operator (then: deny)"})
    routines: bool = field(default=True, metadata={
        "help": "start the care routines of data_dir/routines.yaml when they are due (false: never, as in "
                "atemr mission run --headless, which runs its mission alone)"})


@dataclass(frozen=True)
class TraceConfig:
    """Recording every run to MCAP under ``data_dir/traces``: the agent (transitions, node statuses, blackboard
    writes), the sensors, odometry, poses, transforms, map, path, camera, CAN frames and health."""

    enabled: bool = field(default=True, metadata={"help": "record every run under data_dir/traces"})
    file: Path | None = field(default=None, metadata={"help": "record to this file instead (atemr mission run "
                                                               "--trace); its parts are never deleted"})
    max_file_mb: float = field(default=64.0, metadata={"min": 0.004, "max": 4096.0,
                                                       "help": "a recording past this size continues in a new part"})
    max_files: int = field(default=20, metadata={"min": 1, "max": 100_000,
                                                 "help": "recorded run-*.mcap parts kept (oldest deleted, uploads "
                                                         "never)"})
    pose_hz: float = field(default=2.0, metadata={"min": 0.0, "max": 50.0,
                                                  "help": "agent poses recorded per second for the replay map "
                                                          "(0: none)"})
    camera_hz: float = field(default=1.0, metadata={"min": 0.0, "max": 30.0,
                                                    "help": "camera frames recorded per second as JPEG (0: none)"})
    depth_hz: float = field(default=1.0, metadata={"min": 0.0, "max": 30.0,
                                                   "help": "depth frames recorded per second (16-bit millimetres, "
                                                           "with the camera's intrinsics; 0: none)"})
    writer: Literal["auto", "process", "thread", "inline"] = field(default="auto", metadata={
        "help": "who encodes and writes: a process of its own (auto on a paced robot), a thread, or the robot's "
                "loop (auto in a headless simulation: repeatable, nothing dropped)"})


@dataclass(frozen=True)
class ControlConfig:
    """The local control channel of a running robot (``atemr mission run`` without ``--headless``)."""

    enabled: bool = field(default=True, metadata={"help": "serve the control socket while the robot runs"})
    socket: Path | None = field(
        default=None,
        metadata={"help": "Unix socket path, mode 0600: only the robot's user (default data_dir/control.sock)"},
    )


@dataclass(frozen=True)
class Config:
    """Everything that can be configured; see docs/running.md#configuration."""

    log_level: LogLevel = "INFO"
    data_dir: Path = field(default_factory=default_data_dir)
    simulation: bool = field(default=True, metadata={"help": "run in the built-in simulator (false: real robot)"})
    power_off_command: str | None = field(default=None, metadata={
        "help": "run after the power-off is acknowledged (the robot: systemctl poweroff); none by default"})
    sim: SimConfig = field(default_factory=SimConfig)
    #: Which driver runs each device (`atemr.io.devices.config`): the simulator's or the real hardware's.
    devices: DevicesConfig = field(default_factory=DevicesConfig)
    can: CanConfig = field(default_factory=CanConfig)
    motors: MotorsConfig = field(default_factory=MotorsConfig)
    ui: UiConfig = field(default_factory=UiConfig)
    secondary: SecondaryConfig = field(default_factory=SecondaryConfig)
    agent: AgentConfig = field(default_factory=AgentConfig)
    trace: TraceConfig = field(default_factory=TraceConfig)
    control: ControlConfig = field(default_factory=ControlConfig)
    #: Speed limits, slow/stop zones, idle time (`atemr.skills.ramp`); start values, the settings page
    #: changes them at run time through `MotionPipeline.set_limits`.
    motion: MotionLimits = field(default_factory=MotionLimits)
    localization: LocalizationConfig = field(default_factory=LocalizationConfig)
    nav: NavConfig = field(default_factory=NavConfig)
    #: The battery pack, its state-of-charge estimator and the limits the robot reacts at (`atemr.skills.battery`).
    battery: BatteryParams = field(default_factory=BatteryParams)
    #: The robot's height profile above its footprint (``nav.robot_radius_m``): base, mast, tablet
    #: (`atemr.skills.body`); the simulator's collisions and the depth obstacle layer's heights use it.
    body: BodyConfig = field(default_factory=BodyConfig)

    def robot_body(self) -> RobotBody:
        """The robot's volume: the footprint of ``nav`` with the profile of ``body``."""
        return self.body.body(self.nav.robot_radius_m)


def env_layer(environ: Mapping[str, str]) -> dict[str, Any]:
    """The configuration keys set in ``environ`` (``ATEMR_SIM__SEED=3`` → ``{"sim": {"seed": "3"}}``)."""
    known = field_paths(Config)
    flat: dict[str, Any] = {}
    for name, value in environ.items():
        if not name.startswith(ENV_PREFIX) or name in ENV_RESERVED or name.startswith(ENV_TEST_PREFIX):
            continue
        dotted = name[len(ENV_PREFIX):].lower().replace("__", ".")
        if dotted not in known:
            import difflib

            close = difflib.get_close_matches(dotted, list(known), n=1)
            hint = f" (did you mean ATEMR_{close[0].upper().replace('.', '__')}?)" if close else ""
            raise ConfigError(f"unknown configuration variable{hint}", path=f"environment {name}")
        flat[dotted] = value
    return nest(flat)


def load_config(
    file: str | Path | None = None,
    *,
    environ: Mapping[str, str] | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> Config:
    """Build the configuration from all layers.

    ``file`` defaults to ``$ATEMR_CONFIG`` when set. ``overrides`` are explicit values (from the CLI)
    as dotted keys, ``{"sim.seed": 3}``; ``None`` values are ignored so unset options do not override.
    """
    environ = os.environ if environ is None else environ
    config = Config()
    if file is None and environ.get("ATEMR_CONFIG"):
        file = environ["ATEMR_CONFIG"]
    if file is not None:
        document = load_yaml(file)
        if document is not None:
            config = merge_into(config, document, Source("file", str(file)))
    config = merge_into(config, env_layer(environ), Source("env"))
    if overrides:
        given = {k: v for k, v in overrides.items() if v is not None}
        config = merge_into(config, nest(given), Source("argument"))
    return config


def to_dict(config: Config) -> dict[str, Any]:
    """A plain mapping of the configuration (paths as strings), for display and JSON."""

    def plain(value: Any) -> Any:
        if isinstance(value, Path):
            return str(value)
        if isinstance(value, tuple):
            return [plain(v) for v in value]
        return value

    return {k: plain(v) for k, v in _flatten(dataclasses.asdict(config)).items()}


def _flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        path = f"{prefix}.{k}" if prefix else k
        if isinstance(v, Mapping):
            out.update(_flatten(v, path))
        else:
            out[path] = v
    return out

