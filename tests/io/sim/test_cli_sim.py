"""``atemr sim``: headless runs with a JSON summary, determinism, errors."""

import json

from atemr.cli.main import main


def run_json(capsys, *args):
    if "--stack" not in args:
        args = ("--stack", "bare", *args)
    assert main(["sim", "--headless", "--json", *args]) == 0
    return json.loads(capsys.readouterr().out)


def test_headless_json_summary(capsys):
    out = run_json(capsys, "--duration", "2", "--seed", "3", "--camera-hz", "5", "--twist", "0.5", "0.2")
    assert out["world"] == "studio" and out["seed"] == 3
    assert out["sim_seconds"] == 2.0
    assert out["wall_seconds"] > 0 and out["real_time_factor"] > 0
    assert out["scans"] == 21 and out["imu_samples"] == 101 and out["cliff_readings"] == 41 and out["frames"] == 11
    assert out["collisions"] == len(out["collision_events"])
    assert set(out["final_pose"]) == {"x_m", "y_m", "yaw_rad"}
    assert out["distance_m"] > 0.5


def test_the_depth_camera_runs_at_its_rate_and_is_turned_off_from_the_command_line(capsys):
    """``--depth-hz`` as ``--camera-hz``: the D415's frames per second, 0 for none (both cameras off is what
    issue 22 measures: ``atemr sim --headless --camera-hz 0 --depth-hz 0``)."""
    assert run_json(capsys, "--duration", "2", "--camera-hz", "0", "--depth-hz", "5")["depth_frames"] == 11
    whole = run_json(capsys, "--stack", "robot", "--duration", "1", "--camera-hz", "0", "--depth-hz", "0")
    assert whole["depth_frames"] == 0 and whole["frames"] == 0 and whole["scans"] == 11


def test_same_seed_same_final_pose(capsys):
    a = run_json(capsys, "--duration", "1", "--seed", "5", "--camera-hz", "0", "--twist", "0.4", "0.3")
    b = run_json(capsys, "--duration", "1", "--seed", "5", "--camera-hz", "0", "--twist", "0.4", "0.3")
    assert a["final_pose"] == b["final_pose"]


def test_external_map_as_world(capsys, shared_dir):
    path = shared_dir / "worlds" / "external" / "nav2_tb3_sandbox.yaml"
    out = run_json(capsys, "--world", str(path), "--duration", "0.5", "--camera-hz", "0")
    assert out["world"] == "nav2_tb3_sandbox" and out["scans"] == 6


def test_bad_world_is_a_one_line_error(capsys, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("image: missing.pgm\nresolution: 0.05\norigin: [0, 0]\nnegate: 0\n"
                   "occupied_thresh: 0.65\nfree_thresh: 0.2\n")
    assert main(["sim", "--headless", "--world", str(bad), "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:3:9 origin: expected three numbers" in err


def test_real_time_run_is_paced(capsys):
    # 0.2 simulated seconds at 4x real time: about 50 ms of wall time
    args = ["sim", "--stack", "bare", "--duration", "0.2", "--speed", "4", "--camera-hz", "0", "--json"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["wall_seconds"] >= 0.045
    assert out["real_time_factor"] <= 4.5


def test_the_whole_robot_drives_with_the_operator_joystick(capsys):
    """Default stack: the twist is held on the operator's joystick; the agent must reach IDLE.MANUAL and
    forward it through the mux, the driver and the motor emulators over virtual CAN."""
    bare = run_json(capsys, "--stack", "bare", "--duration", "9", "--seed", "1", "--camera-hz", "0",
                    "--twist", "0.3", "0.0")
    robot = run_json(capsys, "--stack", "robot", "--duration", "9", "--seed", "1", "--camera-hz", "0",
                     "--twist", "0.3", "0.0")
    assert robot["stack"] == "robot" and bare["stack"] == "bare"
    assert robot["agent_state"] == "IDLE.MANUAL"
    assert [t["dest"] for t in robot["agent_trace"] if t["accepted"]][:2] == ["STARTUP", "IDLE.MANUAL"]
    # the robot only drives once start-up has finished and the secondary core released its brakes
    assert 0.3 < robot["distance_m"] < bare["distance_m"]
