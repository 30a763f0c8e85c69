"""``atemr hw check | echo | emulate`` and the real robot's start-up check, against the byte-level emulators
and against nothing at all (what a user sees with no device attached)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import can
import numpy as np
import pytest

from atemr.cli.main import main
from atemr.config import load_config
from atemr.io.can.bus import unique_channel
from atemr.io.devices.rplidar_emulator import RplidarEmulator
from atemr.io.devices.wt901_emulator import Wt901Emulator
from atemr.io.sim.simulation import build_simulation

ROOT = Path(__file__).resolve().parents[1]


def write_config(path: Path, **devices: str) -> Path:
    lines = ["simulation: false", "devices:"] + [f"  {kind}: {spec}" for kind, spec in devices.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def emulated(tmp_path: Path):
    """An RPLidar and a WT901 on pseudo-terminals, fed by the studio world standing still."""
    sim = build_simulation("studio", 0)
    scan = sim.read_lidar(0.0)
    scan.ranges_m[10], scan.ranges_m[20] = np.inf, np.nan  # a return beyond the range; none at all
    sample = sim.read_imu(0.0)
    with RplidarEmulator(lambda: scan, directory=tmp_path) as lidar, \
            Wt901Emulator(lambda: sample, directory=tmp_path) as imu:
        yield tmp_path, lidar, imu, scan


def test_check_lists_every_device_and_exits_0_when_the_critical_ones_answer(emulated, capsys) -> None:
    folder, lidar, imu, _ = emulated
    config = write_config(folder / "robot.yaml", lidar=f"{{driver: rplidar, port: {lidar.port}}}",
                          imu=f"{{driver: wt901, port: {imu.port}}}", camera="{driver: none}",
                          motors="{driver: emulated}", secondary="{driver: emulated}")
    assert main(["hw", "check", "--config", str(config), "--seconds", "1.5", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    rows = {r["device"]: r for r in report["devices"]}
    assert report["ok"] and list(rows) == ["lidar", "imu", "camera", "depth", "motors", "secondary"]
    assert rows["lidar"]["ok"] and rows["lidar"]["port"] == lidar.port and "A2M8" in rows["lidar"]["model"]
    assert "fw 1.29" in rows["lidar"]["model"] and 7 <= rows["lidar"]["rate_hz"] <= 13  # 10 revolutions/s
    assert rows["imu"]["ok"] and rows["imu"]["model"] == "WT901" and 35 <= rows["imu"]["rate_hz"] <= 65  # 50 Hz
    assert rows["motors"]["driver"] == "emulated" and rows["motors"]["ok"]


def test_echo_prints_readings_as_json_lines(emulated, capsys) -> None:
    folder, lidar, imu, scan = emulated
    config = write_config(folder / "robot.yaml", lidar=f"{{driver: rplidar, port: {lidar.port}, beams: 360}}",
                          imu=f"{{driver: wt901, port: {imu.port}}}")
    assert main(["hw", "echo", "lidar", "--config", str(config), "--count", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2
    first = json.loads(lines[0])
    assert set(first) == {"t", "angle_min", "angle_increment", "ranges"} and len(first["ranges"]) == 360
    # the sensor frame, counter-clockwise from the lidar's forward axis, metres; "inf" for a return beyond the
    # range, null for none (the fixture's scan has beam 10 beyond the range and beam 20 without a return)
    ahead = first["ranges"][180]
    assert ahead is not None and abs(ahead - float(scan.ranges_m[180])) < 0.05
    assert first["ranges"][10] == "inf" and first["ranges"][20] is None
    assert main(["hw", "echo", "imu", "--config", str(config), "--count", "3"]) == 0
    samples = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(samples) == 3 and set(samples[0]) == {"t", "yaw_rate_radps", "acc_mps2"}
    assert abs(samples[-1]["acc_mps2"][2] - 9.81) < 0.2  # standing on a level floor


def test_a_beam_keeps_its_non_finite_meaning_in_json() -> None:
    from atemr.cli.hw import range_json

    assert [range_json(v) for v in (1.23456, math.inf, -math.inf, math.nan)] == [1.2346, "inf", "-inf", None]


def test_echo_prints_the_depth_cameras_frames(tmp_path: Path, capsys, monkeypatch) -> None:
    """The real RealSense driver on the emulated D415 (pyrealsense2's API): a wall 1.5 m ahead, the left
    eighth of the image without data (the stereo shadow); then unplugged, echo says why it stopped."""
    from atemr.io.devices.realsense_emulator import FakeD415

    d415 = FakeD415(wall_mm=1500)
    monkeypatch.setitem(sys.modules, "pyrealsense2", d415.module())
    config = write_config(tmp_path / "robot.yaml", depth="{driver: realsense, serial: '822512060000'}")
    assert main(["hw", "echo", "depth", "--config", str(config), "--count", "2"]) == 0
    frames = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(frames) == 2 and (frames[0]["width"], frames[0]["height"]) == (424, 240)
    assert frames[0]["valid"] == pytest.approx(7 / 8, abs=0.01)
    assert frames[0]["min_m"] == frames[0]["median_m"] == frames[0]["max_m"] == 1.5
    assert (frames[0]["fx"], frames[0]["cx"]) == (305.0, 211.5)
    assert ("device", "822512060000") in d415.streams and d415.stopped >= 1
    d415.plugged = False
    assert main(["hw", "echo", "depth", "--config", str(config), "--count", "1", "--timeout", "1"]) == 1
    assert "no depth reading" in capsys.readouterr().err


def test_the_d415s_colour_stream_is_checked_and_echoed_as_the_camera(emulated, capsys, monkeypatch) -> None:
    """``camera: realsense`` with ``depth: realsense``: the check opens the D415 once for both rows, and echo
    prints the colour stream's frames (the emulator's picture: red on the left half, blue on the right)."""
    from atemr.io.devices.realsense_emulator import LEFT_RGB, RIGHT_RGB, FakeD415

    folder, lidar, imu, _ = emulated
    d415 = FakeD415()
    monkeypatch.setitem(sys.modules, "pyrealsense2", d415.module())
    config = write_config(folder / "robot.yaml", lidar=f"{{driver: rplidar, port: {lidar.port}}}",
                          imu=f"{{driver: wt901, port: {imu.port}}}",
                          camera="{driver: realsense, width: 424, height: 240, fps: 15}", depth="{driver: realsense}",
                          motors="{driver: emulated}", secondary="{driver: emulated}")
    assert main(["hw", "check", "--config", str(config), "--seconds", "1.5", "--json"]) == 0
    rows = {r["device"]: r for r in json.loads(capsys.readouterr().out)["devices"]}
    for kind in ("camera", "depth"):
        assert rows[kind]["ok"] and rows[kind]["driver"] == "realsense", rows[kind]
        assert "D415" in rows[kind]["model"]
    assert d415.started == 1 and d415.running == 0  # one pipeline for both rows, closed after the check
    assert main(["hw", "echo", "camera", "--config", str(config), "--count", "2"]) == 0
    frames = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(frames) == 2 and (frames[0]["width"], frames[0]["height"]) == (424, 240)
    halves = [(left + right) / 2 for left, right in zip(LEFT_RGB, RIGHT_RGB, strict=True)]
    assert frames[0]["mean_rgb"] == pytest.approx(halves, abs=0.5)


def test_echo_refuses_the_simulator(tmp_path: Path, capsys) -> None:
    config = write_config(tmp_path / "robot.yaml", lidar="{driver: sim}")
    assert main(["hw", "echo", "lidar", "--config", str(config)]) == 2
    assert "reads a device, not the simulator" in capsys.readouterr().err


def test_check_with_nothing_attached_says_what_is_missing(tmp_path: Path, capsys) -> None:
    config = write_config(tmp_path / "robot.yaml", lidar=f"{{driver: rplidar, port: {tmp_path}/ttyUSB0}}",
                          imu=f"{{driver: wt901, port: {tmp_path}/ttyUSB1}}", camera="{driver: none}")
    (tmp_path / "robot.yaml").write_text((tmp_path / "robot.yaml").read_text()
                                         + "can: {interface: socketcan, channel: can0}\n")
    assert main(["hw", "check", "--config", str(config), "--seconds", "0.5"]) == 1
    out = capsys.readouterr().out
    lines = {line.split()[0]: line for line in out.splitlines() if line.split()}
    assert "MISSING" in lines["lidar"] and f"{tmp_path}/ttyUSB0 does not exist" in lines["lidar"]
    assert "MISSING" in lines["imu"] and f"{tmp_path}/ttyUSB1" in lines["imu"]
    # no CAN in this kernel (errno 97): the row says how to bring the bus up on the robot
    for device in ("motors", "secondary"):
        assert "MISSING" in lines[device] and "ip link set can0 up type can bitrate 1000000" in lines[device]
    assert out.splitlines()[-1] == "4 critical device(s) missing: lidar, imu, motors, secondary"


def test_run_real_with_nothing_attached_fails_start_up_without_powering_off(tmp_path: Path, capsys,
                                                                           monkeypatch) -> None:
    """One line per missing device, exit 1, and never the power-off acknowledgement (0x150 byte 0 = 2) that
    would make the ESP32 cut the power. Nothing answers here whatever the wait: the check waits 1 s, not the
    robot's 5 s."""
    monkeypatch.setattr("atemr.cli.run.STARTUP_CHECK_S", 1.0)
    channel = unique_channel("nothing")
    config = write_config(tmp_path / "robot.yaml", lidar=f"{{driver: rplidar, port: {tmp_path}/ttyUSB0}}",
                          imu=f"{{driver: wt901, port: {tmp_path}/ttyUSB1}}", camera="{driver: none}")
    with can.Bus(interface="virtual", channel=channel) as bus:
        code = main(["run", "--config", str(config), "--real", "--can-interface", "virtual", "--can-channel",
                     channel, "--duration", "1"])
        frames = []
        while (msg := bus.recv(timeout=0)) is not None:
            frames.append(msg)
    err = capsys.readouterr().err
    assert code == 1
    missing = [line for line in err.splitlines() if line.startswith("atemr run: ") and "is missing" in line]
    assert [line.split()[2] for line in missing] == ["lidar", "imu", "motors", "secondary"], err
    assert "no reply from the left (id 1), right (id 2) motor" in err and "no heartbeat answer" in err
    assert "not started (the robot was not powered off)" in err
    assert not [m for m in frames if m.arbitration_id == 0x150 and m.data[0] == 2]


def test_emulate_serves_devices_a_check_finds(tmp_path: Path) -> None:
    out = tmp_path / "emulated.yaml"
    proc = subprocess.Popen([sys.executable, "-m", "atemr", "hw", "emulate", "--duration", "20", "--config-out",
                             str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 15
        while not out.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert out.exists(), proc.stderr.read() if proc.poll() is not None else "no configuration written"
        config = load_config(out, environ={})
        assert config.devices.lidar.driver == "rplidar" and config.devices.imu.driver == "wt901"
        check = subprocess.run([sys.executable, "-m", "atemr", "hw", "check", "--config", str(out), "--json"],
                               capture_output=True, text=True, timeout=60)
        assert check.returncode == 0, check.stdout + check.stderr
        assert json.loads(check.stdout)["ok"]
    finally:
        proc.terminate()
        proc.communicate(timeout=20)


def test_the_robots_example_configuration_loads() -> None:
    config = load_config(ROOT / "deploy" / "robot.yaml", environ={})
    assert not config.simulation and config.power_off_command == "systemctl poweroff"
    assert (config.devices.lidar.driver, config.devices.imu.driver, config.devices.camera.driver,
            config.devices.motors.driver, config.devices.secondary.driver) == ("rplidar", "wt901", "opencv", "rmd",
                                                                                "esp32")
    assert config.devices.depth.driver == "realsense"
    assert config.can.interface == "socketcan" and config.can.channel == "can0"
