"""The dashboard's gateway over a real simulated robot: commands accepted or refused as the robot decides,
the snapshot, camera, video, maps, settings persisted across a rebuild, the simulation panel."""

from __future__ import annotations

import io
import itertools
import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import av
import numpy as np
import pytest
from PIL import Image

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.domain.status import ComponentHealth
from atemr.io.can.bus import unique_channel
from atemr.msgs import Pose2D, Twist
from atemr.robot import Robot, build_robot
from atemr.robot.gateway import RobotGatewayImpl
from atemr.robot.plain_words import plain_unconfirmed
from atemr.ui.gateway import RobotGateway
from atemr.ui.screen.words import plain_activity
from atemr.ui.state import state_problems

BOOTED_S = 4.0  # the secondary core boots for 3 s; the agent is IDLE soon after


def make_robot(data_dir: Path, **overrides: Any) -> tuple[Robot, RobotGatewayImpl]:
    config = load_config(environ={}, overrides={
        "data_dir": str(data_dir), "can.channel": unique_channel("gateway"), "sim.seed": 3,
        "secondary.portal_serve": False, "ui.enabled": False, "ui.port": 0, **overrides,
    })
    robot = build_robot(config, realtime=False, clock=SimClock())
    return robot, RobotGatewayImpl(robot)


@pytest.fixture
def booted(tmp_path: Path) -> Iterator[tuple[Robot, RobotGatewayImpl]]:
    robot, gateway = make_robot(tmp_path / "data")
    with robot:
        robot.run(until=BOOTED_S)
        assert robot.components["agent"].state == "IDLE.MANUAL"  # type: ignore[attr-defined]
        yield robot, gateway
    gateway.close()


def run(robot: Robot, seconds: float) -> None:
    robot.run(until=robot.clock.now() + seconds)


def agent_state(robot: Robot) -> str:
    return str(robot.components["agent"].state)  # type: ignore[attr-defined]


def drive(robot: Robot, gateway: RobotGatewayImpl, twist: Twist, seconds: float) -> None:
    """Hold the joystick as the page does (resent every 0.1 s)."""
    end = robot.clock.now() + seconds
    while robot.clock.now() < end - 1e-9:
        assert gateway.joystick(twist).ok
        run(robot, 0.1)


def test_the_snapshot_has_every_key_filled_from_the_robot(booted):
    robot, gateway = booted
    assert isinstance(gateway, RobotGateway)
    state = gateway.state()
    assert state_problems(state) == []
    assert state["agent_state"] == "IDLE" and state["mode"] == "MANUAL" and state["simulation"] is True
    assert state["robot"] == robot.config.secondary.robot_name == "KAY"
    assert state["active_map"] == "studio" and state["maps"][0] == "studio"
    assert "look-around" in state["missions"] and state["mission"] is None
    truth = robot.parts.sim.pose
    assert math.hypot(state["pose"]["x_m"] - truth.x_m, state["pose"]["y_m"] - truth.y_m) < 0.15
    scan = np.asarray(state["scan"])
    assert scan.ndim == 2 and scan.shape[1] == 2 and len(scan) > 100
    # the scan is drawn in the map frame: its points lie on the map's walls, within a few cells
    grid = robot.parts.maps.active
    rows, cols = grid.world_to_cell(scan[:, 0], scan[:, 1])
    inside = grid.contains(rows, cols)
    assert inside.mean() > 0.95
    assert state["level2"] == {k: True for k in ("left_motor", "right_motor", "imu", "lidar", "camera", "webserver",
                                                 "ir_front", "ir_rear")}
    assert state["level1"]["heartbeat"] and state["level1"]["hardware"]
    assert state["limits"] == {"linear_mps": 1.6, "angular_radps": 2.0}
    assert set(state["system"]) == {"t", "cpu_percent", "memory_percent", "disk_percent"}
    assert state["wheel_speeds"] == {"left_radps": pytest.approx(0.0, abs=0.05),
                                     "right_radps": pytest.approx(0.0, abs=0.05)}
    assert state["emergency"] is False and state["recording"] is False and state["mapping"] is False
    assert state["global_path"] == [] and state["local_path"] == [] and state["goal"] is None
    assert any(e["kind"] == "heartbeat" for e in state["events"])
    assert any(e["kind"].startswith("localization") for e in state["events"])  # drained by the gateway's pump


def test_the_depth_cameras_obstacles_are_in_the_state_where_they_are(booted):
    """Issue 24: what the D415's layer holds is drawn on the map. Turned towards the laundry basket (not on the
    map; the lidar sees its side, the depth camera its volume), the layer's cells lie on the basket."""
    robot, gateway = booted
    assert gateway.state()["depth_obstacles"] == []  # facing the TV wall: only what the map already has
    drive(robot, gateway, Twist(0.0, -0.6), 1.4)  # turn right, about 45 degrees
    run(robot, 1.0)
    cells = np.asarray(gateway.state()["depth_obstacles"])
    assert cells.ndim == 2 and len(cells) >= 5, cells
    basket = next(f for f in robot.parts.sim.world.furniture if f.name == "laundry basket")
    x, y, r = basket.params
    near = np.hypot(cells[:, 0] - x, cells[:, 1] - y) <= r + 0.1
    assert near.mean() > 0.9, cells[~near]


def test_joystick_drives_the_robot_and_the_pose_follows(booted):
    robot, gateway = booted
    x0 = gateway.state()["pose"]["x_m"]
    drive(robot, gateway, Twist(0.3, 0.0), 1.5)
    assert gateway.state()["wheel_speeds"]["left_radps"] > 0.5
    x1 = gateway.state()["pose"]["x_m"]
    assert x1 > x0 + 0.2
    assert abs(robot.parts.sim.pose.x_m - x1) < 0.15
    assert not gateway.joystick(Twist(math.nan, 0.0)).ok


def test_modes_goals_and_missions_are_accepted_or_refused_as_the_agent_decides(booted):
    robot, gateway = booted
    assert gateway.set_goal(Pose2D(2.0, 2.0, 0.0)).reason == "switch to AUTO first"
    assert gateway.cancel_goal().reason == ("There is nothing to cancel: the robot is not driving to a goal or "
                                            "running a mission.")  # plain words; the agent's stay on its page
    assert gateway.set_mode("MANUAL").ok  # already there: nothing to do
    assert not gateway.set_mode("TURBO").ok  # type: ignore[arg-type]
    assert gateway.start_mission("look-around").reason == "switch to AUTO first"

    assert gateway.set_mode("AUTO").ok
    run(robot, 0.3)
    assert agent_state(robot) == "IDLE.AUTO" and gateway.state()["mode"] == "AUTO"
    assert "AUTO" in gateway.joystick(Twist(0.2, 0.0)).reason
    assert "MANUAL" in gateway.begin_mapping().reason
    assert "non-finite" in gateway.set_goal(Pose2D(math.inf, 0.0, 0.0)).reason
    grid = robot.parts.maps.active
    row, col = np.argwhere(grid.data == 100)[len(np.argwhere(grid.data == 100)) // 2]
    wx, wy = grid.cell_to_world(row, col)
    wall = gateway.set_goal(Pose2D(float(wx), float(wy), 0.0))  # in a wall: refused, with or without navigation
    assert not wall.ok and wall.reason
    assert "no mission named 'nope'" in gateway.start_mission("nope").reason

    assert gateway.start_mission("look-around").ok
    run(robot, 1.0)
    assert agent_state(robot) == "EXEC"
    mission = gateway.state()["mission"]
    assert mission["name"] == "look-around" and mission["state"] == "running" and 0 < mission["progress"] < 1
    assert "busy with a goal or a mission" in gateway.begin_mapping().reason
    # a second mission while one runs: the carer's words, not the agent's ("'start_mission' is not valid in ...")
    assert gateway.start_mission("look-around").reason == ("Cannot start a mission now: the robot is busy with a "
                                                          "goal or a mission; cancel it first.")
    assert gateway.stop_mission().ok
    run(robot, 0.3)
    assert agent_state(robot) == "IDLE.AUTO"
    assert gateway.state()["events"][-1]["kind"] == "mission"
    assert gateway.state()["events"][-1]["text"].startswith("Mission 'look-around' cancelled")
    assert gateway.set_mode("MANUAL").ok
    run(robot, 0.3)
    assert agent_state(robot) == "IDLE.MANUAL"


def test_a_refusal_by_a_guard_is_answered_at_once_or_reported_as_an_event(booted):
    robot, gateway = booted
    unplugged = [False]
    robot.parts.health.add("lidar", lambda now: ComponentHealth(not unplugged[0], "test: lidar unplugged"))
    assert gateway.set_mode("AUTO").ok  # every guard holds now: queued
    unplugged[0] = True  # ... and the lidar goes before the agent's tick: its guard decides then
    run(robot, 0.3)
    assert agent_state(robot) in ("IDLE.MANUAL", "ERROR")
    refused = [e for e in robot.recent_events(50) if e["kind"] == "refused"]
    assert any("set_auto" in e["text"] and "lidar" in e["text"] for e in refused), refused
    if agent_state(robot) == "IDLE.MANUAL":
        now = gateway.set_mode("AUTO")  # while the guard would refuse, the answer says so at once
        assert not now.ok and "level-1 status not OK" in now.reason and "lidar" in now.reason


def test_auto_goals_and_missions_wait_for_a_pose_after_a_map_switch(booted):
    """Issue 21: selecting another map drops the pose and says so; AUTO, goals and missions are refused with
    the reason until a pose is set (the mode switch no longer says "accepted" first)."""
    robot, gateway = booted
    store = robot.parts.map_store
    store.save("flat-copy", store.load("studio"))
    gateway.maps_changed()
    assert gateway.set_mode("AUTO").ok
    run(robot, 0.3)
    assert agent_state(robot) == "IDLE.AUTO" and gateway.state()["localization"]["localized"]
    assert gateway.select_map("flat-copy").ok
    run(robot, 0.3)
    state = gateway.state()
    assert state["active_map"] == "flat-copy" and state_problems(state) == []
    loc = state["localization"]
    assert not loc["localized"] and loc["confidence"] == 0.0 and loc["state"] == "uninitialized"
    assert state["pose"] is None and not state["level1"]["localization"]  # 0x153 bit 4, as the secondary core hears
    assert any(e["kind"] == "localization map_changed" and "not localized" in e["text"] for e in state["events"])
    mission = gateway.start_mission("look-around")
    assert not mission.ok and mission.reason == (  # in the carer's words (robot.plain_words)
        "Cannot start a mission: the robot is not sure where it is (0% sure, it needs 70%). Set its position on "
        "the map (SET POSITION) or press FIND POSITION.")
    goal = gateway.set_goal(Pose2D(4.0, 2.0, 0.0))
    assert not goal.ok and goal.reason.startswith("Cannot drive to a goal: the robot is not sure where it is")
    assert gateway.set_mode("MANUAL").ok
    run(robot, 0.3)
    auto = gateway.set_mode("AUTO")
    assert not auto.ok and "not sure where it is" in auto.reason and agent_state(robot) == "IDLE.MANUAL"
    assert gateway.set_initial_pose(robot.parts.sim.pose).ok
    run(robot, 0.5)
    assert gateway.state()["localization"]["localized"] and gateway.set_mode("AUTO").ok
    run(robot, 0.3)
    assert agent_state(robot) == "IDLE.AUTO"


def test_mapping_begin_end_save_and_select(booted):
    robot, gateway = booted
    version = gateway.state()["map_version"]
    first = gateway.map_image()
    assert first is not None and first.width_px == 200 and first.height_px == 190
    assert gateway.map_image() is first  # rendered once per version
    assert "no mapping session" in gateway.end_mapping().reason
    assert gateway.begin_mapping().ok
    run(robot, 0.3)
    assert gateway.state()["agent_state"] == "MAPPING" and gateway.state()["mapping"]
    drive(robot, gateway, Twist(0.0, 0.8), 4.0)
    assert gateway.state()["map_version"] > version
    assert gateway.map_image() is not first
    assert gateway.end_mapping().ok
    assert "built-in" in gateway.save_map("studio").reason
    assert not gateway.save_map("../etc/passwd").ok
    assert "no map named 'nope'" in gateway.select_map("nope").reason
    assert "IDLE only" in gateway.select_map("studio").reason
    assert gateway.save_map("lounge").ok
    run(robot, 0.3)
    state = gateway.state()
    assert state["agent_state"] == "IDLE" and state["active_map"] == "lounge" and "lounge" in state["maps"]
    assert "already exists" in gateway.save_map("lounge").reason
    robot.parts.map_store.delete("lounge")  # the media page deleted it
    gateway.maps_changed()
    assert "lounge" not in gateway.state()["maps"]
    assert "lounge was deleted" in robot.recent_events(1)[0]["text"]
    assert gateway.select_map("studio").ok
    run(robot, 0.3)
    assert gateway.state()["active_map"] == "studio"
    assert robot.parts.map_store.active_name() == "studio"  # persisted


def test_initial_pose_is_set_on_the_robot_thread(booted):
    robot, gateway = booted
    assert "outside the map" in gateway.set_initial_pose(Pose2D(50.0, 50.0, 0.0)).reason
    assert "non-finite" in gateway.set_initial_pose(Pose2D(math.nan, 0.0, 0.0)).reason
    truth = robot.parts.sim.pose
    assert gateway.set_initial_pose(truth).ok
    run(robot, 1.0)
    pose = gateway.state()["pose"]
    assert pose is not None and math.hypot(pose["x_m"] - truth.x_m, pose["y_m"] - truth.y_m) < 0.2


def test_camera_jpeg_capture_and_video(booted):
    robot, gateway = booted
    data = gateway.camera_jpeg()
    assert data is not None and Image.open(io.BytesIO(data)).size == (640, 480)
    assert gateway.camera_jpeg() is data  # encoded once per frame, whoever asks
    frame = gateway.camera_frame()  # the same frame raw, for the WebRTC drive video
    assert frame is robot.parts.devices.camera.latest and frame.shape == (480, 640, 3)
    assert gateway.capture_image().ok
    images = list((robot.config.data_dir / "media" / "images").glob("*.jpg"))
    assert len(images) == 1
    with Image.open(images[0]) as image:
        assert image.size == (640, 480)

    assert "no video" in gateway.record_video(False).reason
    assert gateway.record_video(True).ok
    assert "already recording" in gateway.record_video(True).reason
    assert gateway.state()["recording"] is True
    run(robot, 1.0)
    assert gateway.record_video(False).ok
    videos = list((robot.config.data_dir / "media" / "videos").iterdir())
    assert [v.suffix for v in videos] == [".mp4"]  # finished: no .part left
    with av.open(str(videos[0])) as container:
        stream = container.streams.video[0]
        assert stream.codec_context.name == "h264"
        pictures = [frame.to_image() for frame in container.decode(stream)]
    camera_hz = robot.parts.sim.params.camera_hz
    assert abs(len(pictures) - camera_hz) <= 1
    assert pictures[0].size == (640, 480)
    assert gateway.state()["recording"] is False


def test_limits_and_awareness_are_applied_and_survive_a_rebuild(tmp_path):
    robot, gateway = make_robot(tmp_path / "data")
    with robot:
        assert gateway.set_limits(0.8, 1.5).ok
        refused = gateway.set_limits(5.0, 1.0)
        assert not refused.ok and "max_linear_mps" in refused.reason and "1.8" in refused.reason
        assert not gateway.set_limits(math.nan, 1.0).ok
        assert gateway.state()["limits"] == {"linear_mps": 0.8, "angular_radps": 1.5}
        assert gateway.set_awareness(True).ok and gateway.state()["awareness"] is True
        assert not gateway.set_awareness("yes").ok  # type: ignore[arg-type]
    gateway.close()
    robot, gateway = make_robot(tmp_path / "data")
    with robot:
        assert gateway.state()["limits"] == {"linear_mps": 0.8, "angular_radps": 1.5}
        assert robot.parts.pipeline.limits.max_linear_mps == 0.8
        assert gateway.state()["awareness"] is True
    gateway.close()


def test_wifi_joins_through_the_link_and_reports_failure(booted):
    robot, gateway = booted
    assert gateway.set_wifi("lab", "password1").ok
    assert gateway.state()["wifi_ssid"] == "lab"
    assert "8-63" in gateway.set_wifi("lab", "short").reason
    assert "1-32" in gateway.set_wifi("", "password1").reason
    robot.components["secondary_link"].network.fail_with = "wrong password"  # type: ignore[attr-defined]
    failed = gateway.set_wifi("other", "password2")
    assert not failed.ok and "wrong password" in failed.reason
    assert gateway.state()["wifi_ssid"] == "lab"


def test_simulation_panel_kidnap_obstacle_button_and_screen(booted):
    robot, gateway = booted
    sim = robot.parts.sim
    assert "outside the simulated world" in gateway.sim_kidnap(Pose2D(-50.0, 0.0, 0.0)).reason
    grid = sim.world.map
    row, col = np.argwhere(grid.data == 100)[0]
    wx, wy = grid.cell_to_world(row, col)
    assert "overlaps" in gateway.sim_kidnap(Pose2D(float(wx), float(wy), 0.0)).reason
    before = sim.pose
    # somewhere free about 1 m away, with room for a box 1 m further along x
    steps = (-1.5, -1.0, -0.5, 0.5, 1.0, 1.5)
    target = next(Pose2D(before.x_m + dx, before.y_m + dy, 1.0) for dx in steps for dy in steps
                  if sim.clearance_at(before.x_m + dx, before.y_m + dy).clearance_m > 0
                  and sim.clearance_at(before.x_m + dx + 1.0, before.y_m + dy).clearance_m > 0)
    assert gateway.sim_kidnap(target).ok
    assert sim.pose == before  # applied at the next physics tick, on the robot's thread
    run(robot, 0.1)
    assert sim.pose.distance_to(target) < 0.05
    assert sim.clearance_at(target.x_m + 1.0, target.y_m).clearance_m > 0
    assert gateway.sim_drop_obstacle(target.x_m + 1.0, target.y_m).ok
    run(robot, 0.1)
    assert sim.clearance_at(target.x_m + 1.0, target.y_m).clearance_m < 0  # the box is there
    assert not gateway.sim_drop_obstacle(math.nan, 0.0).ok

    assert "0-10" in gateway.sim_button(0.0).reason
    png = gateway.secondary_screen_png()
    assert png is not None and Image.open(io.BytesIO(png)).size == (256, 128)
    assert gateway.sim_button(0.2).ok


def test_add_dashboard_serves_and_reports_the_webserver_healthy(tmp_path):
    from atemr.robot.dashboard import add_dashboard

    config = load_config(environ={}, overrides={
        "data_dir": str(tmp_path / "data"), "can.channel": unique_channel("dash"), "secondary.portal_serve": False,
        "ui.enabled": False, "ui.port": 0,
    })
    robot = build_robot(config, realtime=False, clock=SimClock())
    server = add_dashboard(robot, hash_method="scrypt:1024:8:1")
    assert robot.parts.health.collect()["webserver"].ok is False  # not serving yet
    with robot:
        assert server.running and server.port > 0
        assert robot.parts.health.collect()["webserver"].ok
        robot.run(until=BOOTED_S)
        assert agent_state(robot) == "IDLE.MANUAL"
        assert server.pushes > 0
        client = server.app.test_client()
        assert client.get("/auth/first-start").status_code == 200
    assert not server.running
    assert robot.parts.health.collect()["webserver"].ok is False
    robot.parts.gateway.close()


def test_auto_goal_shows_the_paths_and_is_reached(booted):
    robot, gateway = booted
    assert gateway.set_mode("AUTO").ok
    run(robot, 0.3)
    start = robot.parts.sim.pose
    goal = Pose2D(start.x_m + 1.0, start.y_m + 0.5, 0.0)
    assert gateway.set_goal(goal).ok
    run(robot, 1.0)
    state = gateway.state()
    assert state["agent_state"] == "EXEC"
    assert state["goal"] == {"x_m": goal.x_m, "y_m": goal.y_m, "yaw_rad": 0.0}
    path = np.asarray(state["global_path"])
    assert len(path) > 2 and np.hypot(*(path[-1] - [goal.x_m, goal.y_m])) < 0.2
    assert len(state["local_path"]) > 0
    # a single goal is no mission: the robot's screen says where it goes, not "Doing the task 'goal'"
    assert state["mission"] is None and plain_activity(state) == "Going to a goal"
    progress = state["navigation"]
    assert progress is not None and 0.3 < (progress["distance_left_m"] or 0) < 1.6 and (progress["eta_s"] or 0) > 0
    for _ in range(30):
        run(robot, 1.0)
        if agent_state(robot) != "EXEC":
            break
    assert agent_state(robot) == "IDLE.AUTO"
    assert robot.parts.sim.pose.distance_to(goal) < 0.3
    after = gateway.state()
    assert after["goal"] is None and after["global_path"] == [] and after["navigation"] is None
    last = after["events"][-1]
    assert last == {"t": last["t"], "kind": "goal", "text": "Goal reached.", "unix_s": last["unix_s"]}
    assert time.time() - 120 < last["unix_s"] <= time.time()  # the wall clock the carer's Events list shows


def test_the_state_says_why_the_robot_is_held_stopped(booted):
    robot, gateway = booted
    assert gateway.state()["stop_cause"] is None
    inputs = robot.parts.inputs
    inputs.set_safety_stop("CAN bus fault", True)
    assert gateway.state()["stop_cause"] == "bus"
    inputs.set_safety_stop("heartbeat lost", True)
    assert gateway.state()["stop_cause"] == "heartbeat"  # the more urgent of the two
    inputs.set_safety_stop("heartbeat lost", False)
    inputs.set_safety_stop("CAN bus fault", False)
    sim = robot.parts.sim
    grid = sim.world.map
    walls = np.argwhere(grid.data == 100)
    # drive straight at the nearest wall until the stop zone brakes the base
    here = np.asarray([sim.pose.x_m, sim.pose.y_m])
    cells = np.asarray([grid.cell_to_world(r, c) for r, c in walls[:: max(1, len(walls) // 400)]])
    nearest = cells[np.argmin(np.hypot(*(cells - here).T))]
    heading = math.atan2(nearest[1] - here[1], nearest[0] - here[0])
    assert gateway.sim_kidnap(Pose2D(float(here[0]), float(here[1]), heading)).ok
    run(robot, 0.2)
    for _ in range(80):
        assert gateway.joystick(Twist(0.3, 0.0)).ok
        run(robot, 0.1)
        if gateway.state()["stop_cause"] == "obstacle":
            break
    assert gateway.state()["stop_cause"] == "obstacle" and gateway.state()["emergency"] is True


def test_autonomy_level_confirm_and_reload_through_the_gateway(booted):
    robot, gateway = booted
    state = gateway.state()["autonomy"]
    assert state["level"] == "full" and state["pending"] is None and state["levels"] == ["off", "low", "high", "full"]
    assert "unknown autonomy level" in gateway.set_autonomy("max", "alice").reason
    assert gateway.set_autonomy("low", "alice").ok
    assert gateway.set_mode("AUTO").ok
    run(robot, 0.3)
    assert gateway.start_mission("look-around").ok
    run(robot, 0.3)
    pending = gateway.state()["autonomy"]["pending"]
    assert agent_state(robot) == "IDLE.AUTO" and pending["trigger"] == "start_mission" and pending["dest"] == "EXEC"
    assert "no longer pending" in gateway.answer_transition(pending["id"] + 7, True, "alice").reason
    assert gateway.answer_transition(pending["id"], True, "alice").ok
    run(robot, 0.3)
    assert agent_state(robot) == "EXEC" and gateway.state()["autonomy"]["pending"] is None
    confirmed = next(t for t in gateway.agent_snapshot()["transitions"] if t["decision"] == "confirmed")
    assert confirmed["decided_by"] == "alice" and confirmed["dest"] == "EXEC"
    assert any(e["kind"] == "autonomy" and "confirmed by alice" in e["text"] for e in gateway.state()["events"])
    assert gateway.reload_agent().ok
    run(robot, 1.2)
    assert gateway.agent_snapshot()["reloads"][-1]["status"] == "unchanged"


def test_a_denied_or_unanswered_step_is_said_in_plain_words(booted):
    """The carer read "Start mission: started" while the robot stood still after a denial or a timeout: the
    robot now says what it did not do and why (kind "unconfirmed", which settles the page's acknowledgement)."""
    robot, gateway = booted
    assert gateway.set_autonomy("low", "alice").ok and gateway.set_mode("AUTO").ok
    run(robot, 0.3)
    assert gateway.start_mission("look-around").ok
    run(robot, 0.3)
    pending = gateway.state()["autonomy"]["pending"]
    assert gateway.answer_transition(pending["id"], False, "bob").ok
    run(robot, 0.3)
    said = [e["text"] for e in gateway.state()["events"] if e["kind"] == "unconfirmed"]
    assert said == ["The robot did not start a mission: bob denied it. It stays where it is."]
    assert agent_state(robot) == "IDLE.AUTO"
    assert plain_unconfirmed("goal", "timed_out", "timeout") == (
        "The robot did not drive to a goal: nobody confirmed it in time. It stays where it is.")


def test_global_localization_finds_a_robot_carried_elsewhere(booted):
    """The operator does not know where the robot is either: FIND POSE spreads the particles over the map and
    the robot finds itself, standing still, where it truly is."""
    robot, gateway = booted
    sim = robot.parts.sim
    sim.kidnap(Pose2D(2.0, 3.3, 1.0))  # carried into the other half of the living room; localization not told
    assert gateway.localize_globally().ok
    events: list[dict[str, Any]] = []
    for _ in range(40):
        run(robot, 0.5)
        events = [e for e in robot.recent_events(30) if e["kind"].startswith("localization ")]
        if events and events[-1]["kind"] == "localization localized":
            break
    started = [e for e in events if e["kind"] == "localization global_start"]
    assert started and started[0]["text"] == "global localization: requested by the operator", events
    assert events[-1]["kind"] == "localization localized", events
    pose, truth = gateway.state()["pose"], sim.pose
    assert pose is not None
    assert math.hypot(pose["x_m"] - truth.x_m, pose["y_m"] - truth.y_m) < 0.15, (pose, truth)
    assert abs(math.remainder(pose["yaw_rad"] - truth.yaw_rad, math.tau)) < 0.1


def test_find_position_in_look_alike_rooms_turns_the_robot_in_place_once_round(tmp_path):
    """Two alike rooms: FIND POSITION answers ambiguous, and since the operator asked, the robot turns in place
    by itself (in MANUAL, the joystick idle) to see more, says so on its screen and the Control page, and stops
    after one revolution; it never leaves its spot, and is never localized in the wrong room. STOP (a zero
    joystick command in MANUAL) and mapping end the look for good: the robot does not start turning again."""
    from atemr.ui.screen.words import plain_activity

    robot, gateway = make_robot(tmp_path / "data", **{"sim.world": "twin_rooms"})

    def look(until: Any) -> tuple[list[bool], list[float]]:
        assert gateway.localize_globally().ok
        yaws, looked = [], []
        for _ in range(50):
            run(robot, 0.5)
            state = gateway.state()
            looked.append(state["localization"]["looking_around"])
            yaws.append(sim.pose.yaw_rad)
            if looked[-1]:
                assert plain_activity(state) == "Turning to look around: finding where I am"
            if until(looked):
                break
        return looked, yaws

    def turned(yaws: list[float]) -> float:
        return sum(abs(math.remainder(b - a, math.tau)) for a, b in itertools.pairwise(yaws))

    def stands_still() -> None:
        before = sim.pose.yaw_rad
        run(robot, 3.0)
        assert abs(math.remainder(sim.pose.yaw_rad - before, math.tau)) < 0.05
        assert not gateway.state()["localization"]["looking_around"]

    with robot:
        robot.run(until=BOOTED_S)
        sim = robot.parts.sim
        start = Pose2D(6.2, 1.2, 1.0)
        sim.kidnap(start)
        looked, yaws = look(lambda looked: any(looked) and not looked[-1])
        assert any(looked) and not looked[-1], looked
        loc = gateway.state()["localization"]
        if loc["state"] == "ambiguous":  # a whole turn; the twin is still among the places
            assert math.tau - 0.5 < turned(yaws) < math.tau + 0.3, turned(yaws)
            texts = [e["text"] for e in robot.recent_events(30) if e["kind"] == "localization ambiguous"]
            assert "turning in place" in texts[0] and "turned once round" in texts[-1], texts
        else:  # the rooms differ by a table's place: a turn may tell them apart, never for the twin
            pose = gateway.state()["pose"]
            assert loc["localized"] and pose is not None and math.hypot(pose["x_m"] - 6.2, pose["y_m"] - 1.2) < 0.3
        assert math.hypot(sim.pose.x_m - start.x_m, sim.pose.y_m - start.y_m) < 0.15
        stands_still()
        # STOP while it looks around: it stops, and stays stopped
        sim.kidnap(start)
        looked, _ = look(lambda looked: looked[-1])
        assert looked[-1], looked
        assert gateway.joystick(Twist()).ok
        run(robot, 0.5)
        stands_still()
        # so does mapping (the mapping state's joystick never turns by itself)
        sim.kidnap(start)
        looked, _ = look(lambda looked: looked[-1])
        assert looked[-1] and gateway.begin_mapping().ok
        run(robot, 0.5)
        assert agent_state(robot).startswith("MAPPING")
        stands_still()
    gateway.close()


def test_global_localization_needs_an_active_map(tmp_path):
    robot, gateway = make_robot(tmp_path / "data")
    with robot:
        robot.parts.maps.active = None
        assert "no active map" in gateway.localize_globally().reason
    gateway.close()


def test_the_recording_being_written_is_the_file_in_use(tmp_path):
    """The media page keeps the recording's current part (`files_in_use`): the part the writer has open, in the
    folder the media page lists as traces."""
    robot, gateway = make_robot(tmp_path / "data", **{"trace.enabled": True, "trace.writer": "inline"})
    assert tuple(gateway.files_in_use()) == ()  # nothing written before the robot starts
    with robot:
        robot.run(until=1.0)
        (part,) = gateway.files_in_use()
        assert part.parent == tmp_path / "data" / "traces" and part.suffix == ".mcap" and part.exists()
    assert tuple(gateway.files_in_use()) == ()  # the recording ended with the robot: the file may go now
    gateway.close()
