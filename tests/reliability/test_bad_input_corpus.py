"""Bad input corpus: every loader, map, goal, scan and CAN frame a hostile or careless user can produce gets a
clear error naming what is wrong and where, and nothing that is running changes.

YAML documents go through every loader of the project (configuration, agent document, mission, world,
fuzzy engine); maps through the map loader and the upload path; goals through the whole robot's agent;
scans through the motion pipeline and localization; CAN frames into the motor driver, the secondary link and
the emulated secondary core.
"""

from __future__ import annotations

import math
import random
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.errors import AtemrError, ConfigError
from atemr.fsm.agent import Agent
from atemr.fsm.spec import load_agent
from atemr.io.can.bus import unique_channel
from atemr.io.map_store import MapStore
from atemr.io.motors.driver import RmdDriver
from atemr.io.sim.maps import load_map
from atemr.io.sim.world import load_world
from atemr.msgs import CliffReadings, LaserScan, Pose2D, Twist
from atemr.robot import build_robot
from atemr.skills.fuzzy.loader import load_engine
from atemr.skills.motion_pipeline import ControlInputs, MotionPipeline, TimedTwist
from atemr.trees.context import clear_blackboard
from atemr.trees.fakes import RecordingLink, RecordingPort
from atemr.trees.missions import load_mission
from secondary_core.harness import LinkBench

ROOT = Path(__file__).resolve().parents[2]
AGENT_YAML = ROOT / "trees" / "agent.yaml"
MISSION_YAML = ROOT / "trees" / "missions" / "look-around.yaml"
WORLD_DIR = ROOT / "atemr" / "worlds" / "studio"
ENGINE_YAML = ROOT / "atemr" / "skills" / "fuzzy" / "engines" / "idle.yaml"


# -- YAML: every loader, every kind of bad document -------------------------------------------------------------
def _config(path: Path) -> Any:
    return load_config(path, environ={})


def _world(path: Path) -> Any:
    target = path.parent / "world.yaml"
    if path != target:
        path.rename(target)
    for name in ("studio.yaml", "studio.pgm"):
        if not (path.parent / name).exists():
            shutil.copy(WORLD_DIR / name, path.parent / name)
    return load_world(target)


LOADERS: dict[str, tuple[Callable[[Path], Any], str]] = {
    # name: (loader, a valid document of that kind to derive unknown keys and wrong types from)
    "config": (_config, "sim:\n  seed: 3\n"),
    "agent": (load_agent, AGENT_YAML.read_text()),
    "mission": (load_mission, MISSION_YAML.read_text()),
    "world": (_world, (WORLD_DIR / "world.yaml").read_text()),
    "fuzzy": (load_engine, ENGINE_YAML.read_text()),
}

#: Kind of bad document → (its text from a valid one, words the error must contain, case-insensitive).
CORPUS: dict[str, tuple[Callable[[str], str], tuple[str, ...]]] = {
    "syntax": (lambda good: good + "\nbroken: [1, 2\n", (".yaml:",)),  # file:line:column
    "python_tag": (lambda good: "!!python/object/apply:os.system ['echo pwned']\n", ("python",)),
    "python_tag_inside": (lambda good: good + "\nextra: !!python/name:os.system ''\n", ("python",)),
    "duplicate_key": (lambda good: good + "\n" + good.splitlines()[next(
        i for i, ln in enumerate(good.splitlines()) if ln and not ln.startswith(("#", " ")))] + "\n", ("duplicate",)),
    "huge": (lambda good: "x: '" + "a" * (10 * 1024 * 1024) + "'\n", ("limit",)),
    "deep": (lambda good: "x: " + "[" * 5000 + "]" * 5000 + "\n", ("nest",)),
    "unknown_key": (lambda good: good + "\nno_such_key_anywhere: 1\n", ("no_such_key_anywhere",)),
    "not_a_mapping": (lambda good: "- just\n- a list\n", ()),
    "empty_mapping_wrong_type": (lambda good: "42\n", ()),
}


#: A mission file's only top-level key is 'mission': an unknown one next to it is refused by saying so.
EXPECT = {("mission", "unknown_key"): ("top-level key", ":")}


@pytest.mark.parametrize("kind", list(CORPUS))
@pytest.mark.parametrize("loader_name", list(LOADERS))
def test_bad_yaml_is_a_config_error_naming_the_file_and_the_problem(tmp_path: Path, loader_name: str,
                                                                    kind: str) -> None:
    loader, good = LOADERS[loader_name]
    make, words = CORPUS[kind]
    words = EXPECT.get((loader_name, kind), words)
    path = tmp_path / "bad.yaml"
    path.write_text(make(good))
    with pytest.raises(ConfigError) as err:
        loader(path)
    message = str(err.value)
    assert "yaml" in message, f"{loader_name}/{kind}: the error does not say which file: {message[:300]}"
    for word in words:
        assert word in message.lower(), f"{loader_name}/{kind}: {word!r} not in {message[:300]}"
    assert len(message) < 2000, f"{loader_name}/{kind}: the error echoes the document ({len(message)} chars)"


def test_the_valid_documents_the_corpus_starts_from_do_load(tmp_path: Path) -> None:
    for name, (loader, good) in LOADERS.items():
        path = tmp_path / name / "good.yaml"
        path.parent.mkdir()
        path.write_text(good)
        assert loader(path) is not None, name


WRONG_TYPES = {
    "config": ("sim:\n  seed: twelve\n", "sim.seed"),
    "agent": (AGENT_YAML.read_text().replace("initial: STARTUP", "initial: [STARTUP]"), "initial"),
    "mission": (MISSION_YAML.read_text().replace("retries: 1", "retries: many"), "retries"),
    "world": ((WORLD_DIR / "world.yaml").read_text().replace("wall_height_m: 2.5", "wall_height_m: tall"),
              "wall_height_m"),
    "fuzzy": (ENGINE_YAML.read_text().replace("range: [0.0, 1.2]", "range: wide", 1), "range"),
}


@pytest.mark.parametrize("loader_name", list(WRONG_TYPES))
def test_wrong_types_name_the_key(tmp_path: Path, loader_name: str) -> None:
    loader, _ = LOADERS[loader_name]
    text, key = WRONG_TYPES[loader_name]
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=key):
        loader(path)


@pytest.fixture
def idle_agent() -> Iterator[tuple[Agent, RecordingPort]]:
    clear_blackboard()
    port = RecordingPort()
    agent = Agent(load_agent(AGENT_YAML), port, RecordingLink())
    t = 0.0
    while agent.state != "IDLE.MANUAL" and t < 10:
        agent.tick(t)
        t += 0.1
    yield agent, port
    agent.shutdown()
    clear_blackboard()


@pytest.mark.parametrize("kind", ["syntax", "python_tag", "duplicate_key", "huge", "deep", "unknown_key"])
def test_a_bad_agent_document_is_refused_and_the_agent_keeps_running(tmp_path: Path, idle_agent: Any,
                                                                     kind: str) -> None:
    agent, _ = idle_agent
    before_spec, before_state = agent.spec, agent.state
    path = tmp_path / "agent.yaml"
    path.write_text(CORPUS[kind][0](AGENT_YAML.read_text()))
    command = agent.submit_reload(path)
    agent.tick(20.0)
    result = agent.result(command)
    assert result is not None and not result.accepted, result
    assert "agent.yaml" in result.reason, result.reason
    assert agent.spec is before_spec and agent.state == before_state
    agent.submit("set_auto")
    agent.tick(20.1)
    assert agent.state == "IDLE.AUTO"  # still answering commands on the last good document


# -- maps ---------------------------------------------------------------------------------------------------------
MAP_YAML = "image: room.pgm\nresolution: {res}\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n" \
           "free_thresh: 0.196\n"


def pgm(width: int, height: int, body: bytes | None = None) -> bytes:
    return f"P5\n{width} {height}\n255\n".encode() + (body if body is not None else bytes(width * height))


@pytest.mark.parametrize(("res", "image", "words"), [
    ("0.05", pgm(10, 10, b"\x00" * 17), ("room.pgm",)),                  # truncated pixel data
    ("0.05", b"\x89PNG\r\n\x1a\n" + b"\x00" * 40, ("room.pgm",)),         # a PNG header and nothing else
    ("0.05", pgm(60000, 60000, b""), ("room.pgm", "too large")),          # a decompression-bomb header
    ("0", pgm(4, 4), ("resolution",)),
    ("-0.05", pgm(4, 4), ("resolution",)),
    ("1e-300", pgm(4, 4), ("resolution",)),
    ("1e300", pgm(4, 4), ("resolution",)),
    (".nan", pgm(4, 4), ("resolution",)),
    (".inf", pgm(4, 4), ("resolution",)),
])
def test_corrupt_maps_are_refused_by_the_loader_and_the_upload(tmp_path: Path, res: str, image: bytes,
                                                               words: tuple[str, ...]) -> None:
    (tmp_path / "room.yaml").write_text(MAP_YAML.format(res=res))
    (tmp_path / "room.pgm").write_bytes(image)
    with pytest.raises(ConfigError) as err:
        load_map(tmp_path / "room.yaml")
    for word in words:
        assert word in str(err.value), str(err.value)
    store = MapStore(tmp_path / "data")
    before = store.names()
    with pytest.raises(ConfigError):
        store.upload({"room.yaml": MAP_YAML.format(res=res).encode(), "room.pgm": image})
    assert store.names() == before


# -- goals through the whole robot -----------------------------------------------------------------------------------
def test_bad_goals_are_refused_with_the_reason_and_the_robot_stays_put(tmp_path: Path) -> None:
    config = load_config(environ={}, overrides={"data_dir": str(tmp_path), "can.channel": unique_channel("goals"),
                                                "sim.seed": 5, "secondary.portal_serve": False, "ui.enabled": False})
    robot = build_robot(config, realtime=False, clock=SimClock())
    bad = {
        "nan": (Pose2D(math.nan, 1.0, 0.0), "finite"),
        "inf": (Pose2D(1.0, math.inf, 0.0), "finite"),
        "nan_yaw": (Pose2D(3.0, 2.0, math.nan), "finite"),
        "outside": (Pose2D(-50.0, 3.0, 0.0), "outside the map"),
        "obstacle": (Pose2D(0.6, 2.2, 0.0), "obstacle"),  # on the sofa
    }
    with robot:
        agent, sim = robot.components["agent"], robot.parts.sim
        robot.run(until=7.0)
        agent.submit("set_auto")
        robot.run(until=7.5)
        start = sim.pose
        t = 7.5
        for name, (goal, words) in bad.items():
            agent.submit("set_auto")  # an error ends in IDLE.MANUAL: the operator switches back
            t += 0.5
            robot.run(until=t)
            assert agent.state == "IDLE.AUTO", (name, agent.state)
            seen = len(agent.trace)
            agent.submit("goal", goal=goal)
            t += 1.5
            robot.run(until=t)
            records = agent.trace[seen:]
            error = next((r for r in records if r.dest == "ERROR"), None)
            assert error is not None, (name, [(r.trigger, r.dest, r.reason) for r in records])
            assert words in error.reason.lower(), (name, error.reason)
            assert not any(r.dest == "EXEC" for r in records), name
            assert agent.state.startswith("IDLE"), (name, agent.state)
        assert sim.pose.distance_to(start) < 0.02
        assert not sim.collisions


# -- scans through the motion pipeline and localization -----------------------------------------------------------
def scan(ranges: Any) -> LaserScan:
    values = np.asarray(ranges, dtype=np.float64)
    return LaserScan(1.0, values, -math.pi, 2 * math.pi / max(len(values), 1), 0.05, 12.0)


BAD_SCANS = {
    "all_nan": scan(np.full(360, np.nan)),
    "all_inf": scan(np.full(360, np.inf)),
    "all_zero": scan(np.zeros(360)),
    "empty": scan(np.zeros(0)),
    "one_beam": scan([0.5]),
    # the wrong shape: two rows of 180 (a LaserScan has no angle_max, so a short 1-D scan is just a partial one)
    "wrong_shape": LaserScan(1.0, np.full((2, 180), 2.0), -math.pi, 2 * math.pi / 360, 0.05, 12.0),
}


@pytest.mark.parametrize("name", list(BAD_SCANS))
def test_bad_scans_never_drive_the_base_into_the_unknown(name: str) -> None:
    """A scan with no valid return is no obstacle information: the base may creep at slow-zone limits at most
    (never faster), and an obstacle seen before is not forgotten faster than the pipeline allows."""
    pipeline = MotionPipeline()
    cliff = CliffReadings(1.0, 0.06, 0.06, 0.06)
    try:
        result = pipeline.tick(ControlInputs(now=1.0, scan=BAD_SCANS[name], cliff=cliff,
                                             joystick=TimedTwist(Twist(1.5, 0.0), 1.0)))
    except AtemrError as exc:  # refusing the scan is fine, if it says so
        assert "scan" in str(exc).lower()
        return
    assert abs(result.twist.linear_mps) <= pipeline.limits.slow_linear_mps + 1e-9, (name, result.twist)


def test_minus_inf_is_an_obstacle_in_the_stop_zone() -> None:
    pipeline = MotionPipeline()
    ranges = np.full(360, 5.0)
    ranges[170:190] = -np.inf  # straight ahead (angle 0 is index 180)
    result = pipeline.tick(ControlInputs(now=1.0, scan=scan(ranges), cliff=CliffReadings(1.0, 0.06, 0.06, 0.06),
                                         joystick=TimedTwist(Twist(0.3, 0.0), 1.0)))
    assert result.emergency and result.twist.linear_mps == 0.0


@pytest.mark.parametrize("name", list(BAD_SCANS))
def test_bad_scans_leave_localization_where_it_was(tmp_path: Path, name: str) -> None:
    """A robot localized on a real scan stays localized where it was through a scan with nothing in it (an
    operator's pose counts only once a scan agrees with it, so the robot is localized on the simulator's own
    scan first)."""
    from atemr.io.sim.simulation import build_simulation
    from atemr.skills.localization.pipeline import LocalizationPipeline

    sim = build_simulation(WORLD_DIR / "world.yaml", 1)
    loc = LocalizationPipeline(load_map(WORLD_DIR / "studio.yaml"), np.random.default_rng(1))
    loc.set_initial_pose(0.0, sim.pose)
    loc.on_scan(sim.read_lidar(0.5))
    loc.tick(0.5)
    before, used = loc.map_pose(), loc.scans_used
    assert before is not None and loc.localized and before.distance_to(sim.pose) < 0.05
    try:
        loc.on_scan(BAD_SCANS[name])
    except AtemrError as exc:  # refused at the door: named, and nothing reaches the filter
        assert "scan" in str(exc).lower() and "ranges_m" in str(exc), str(exc)
        loc.tick(1.0)
        assert loc.scans_used == used
        return
    loc.tick(1.0)
    after = loc.map_pose()
    assert after is not None and loc.localized and after.distance_to(before) < 0.05, (name, before, after)
    assert all(math.isfinite(v) for v in (after.x_m, after.y_m, after.yaw_rad))


# -- CAN frames on every ID ----------------------------------------------------------------------------------------
def test_random_frames_on_every_id_into_the_motor_driver() -> None:
    rng = random.Random(7)
    channel = unique_channel("junk")
    junk_bus = can.Bus(interface="virtual", channel=channel)
    driver = RmdDriver(can.Bus(interface="virtual", channel=channel), silence_timeout_s=100.0)
    try:
        driver.tick(0.0)
        for arbitration_id in range(0x800):
            for _ in range(2):
                data = bytes(rng.randrange(256) for _ in range(rng.randrange(9)))
                junk_bus.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False))
        for arbitration_id in rng.sample(range(1 << 29), 200):
            junk_bus.send(can.Message(arbitration_id=arbitration_id, data=b"\x9c" + bytes(7), is_extended_id=True))
        driver.tick(0.02)  # reads every frame; never raises
        assert driver.bad_frames > 0  # malformed replies on 0x141/0x142 are counted, not trusted
        # frames on other IDs change nothing; random bytes on a motor's own ID may decode as a valid reply
        # (indistinguishable from the motor), and a reply with an error flag then stops both motors: safe
        assert driver.fault is None or "reports" in str(driver.fault)
        assert driver.commanded.left_radps == 0.0 and driver.commanded.right_radps == 0.0
    finally:
        driver.shutdown()
        junk_bus.shutdown()


def test_random_frames_on_every_id_into_the_link_and_the_board() -> None:
    """tests/secondary_core/test_robustness.py covers 0x140-0x158 by hypothesis; this sweeps all 2048 IDs."""
    rng = random.Random(8)
    with LinkBench() as bench:
        bench.bring_up()
        before = bench.core.state
        for arbitration_id in range(0x800):
            if 0x150 <= arbitration_id <= 0x157:
                continue  # the protocol's own IDs carry commands a random frame may legitimately be
            data = bytes(rng.randrange(256) for _ in range(rng.randrange(9)))
            bench.spy.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False))
            if arbitration_id % 64 == 0:
                bench.run(0.02)
        bench.run(0.5)
        assert bench.core.state == before == "ops"
        assert bench.link.heartbeat_ok
        assert bench.link.diagnostics()["frames_in"] > 0
