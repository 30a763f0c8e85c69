"""The WT901 IMU: the WIT codec on frames built from the documented formula, the mounting rotation and the
gyro bias on hand-made frames, and the driver end to end against the emulator on a pty (unplug, replug)."""

import errno
import logging
import math
import os
import time
import tty
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from atemr.errors import ProtocolError
from atemr.io.devices import wt901_protocol as wit
from atemr.io.devices.base import DeviceInfo
from atemr.io.devices.config import ImuDeviceConfig
from atemr.io.devices.wt901 import GyroBiasEstimator, SampleAssembler, Wt901Driver
from atemr.io.devices.wt901_emulator import Wt901Emulator
from atemr.msgs import ImuSample

G = wit.STANDARD_GRAVITY
GYRO_LSB = math.radians(2000.0) / 32768  # rad/s of one raw unit
ACCEL_LSB = 16 * G / 32768


def frame_bytes(frame_type: int, *values: int) -> bytes:
    """A frame built by hand from the documented layout, independently of `encode_frame`."""
    body = bytes([0x55, frame_type]) + b"".join(v.to_bytes(2, "little", signed=True) for v in values)
    return body + bytes([sum(body) % 256])


# -- the codec -------------------------------------------------------------------------------------------------
def test_a_gyro_frame_is_laid_out_as_documented():
    # wz raw 16384 = 1000 °/s; checksum = (0x55 + 0x52 + 0x40) & 0xFF = 0xE7
    expected = bytes([0x55, 0x52, 0, 0, 0, 0, 0x00, 0x40, 0, 0, 0xE7])
    assert wit.encode_frame(wit.FrameType.GYRO, (0, 0, 16384, 0)) == expected
    assert wit.gyro_frame((0.0, 0.0, math.radians(1000.0))) == expected
    frame = wit.decode_frame(expected)
    assert frame == wit.Frame(0x52, (0, 0, 16384, 0))
    assert wit.angular_velocity_radps(frame) == pytest.approx((0.0, 0.0, math.radians(1000.0)))


def test_acceleration_and_angle_frames_convert_to_si_units():
    accel = wit.decode_frame(frame_bytes(0x51, 2048, -1024, 32767, 2512))  # 1 g, -0.5 g, ~16 g, 25.12 °C
    assert wit.accel_mps2(accel) == pytest.approx((G, -0.5 * G, 32767 / 32768 * 16 * G))
    assert wit.temperature_c(accel) == pytest.approx(25.12)
    angle = wit.decode_frame(frame_bytes(0x53, 8192, 0, -16384, 0))  # 45°, 0°, -90°
    assert wit.angles_rad(angle) == pytest.approx((math.pi / 4, 0.0, -math.pi / 2))
    assert wit.checksum(frame_bytes(0x53, 8192, 0, -16384, 0)[:10]) == frame_bytes(0x53, 8192, 0, -16384, 0)[10]


def test_encoders_quantize_saturate_and_wrap_like_the_sensor():
    assert wit.decode_frame(wit.accel_frame((0.0, 0.0, 20 * G))).values[2] == 32767  # beyond ±16 g: clipped
    assert wit.decode_frame(wit.accel_frame((G, 0.0, 0.0), temperature=31.5)).values == (2048, 0, 0, 3150)
    assert wit.decode_frame(wit.angle_frame((0.0, 0.0, 1.5 * math.pi))).values[2] == -16384  # 270° is -90°
    assert wit.register_write(wit.REG_RATE, 0x08) == bytes([0xFF, 0xAA, 0x03, 0x08, 0x00])
    assert bytes([0xFF, 0xAA, 0x69, 0x88, 0xB5]) == wit.UNLOCK
    assert bytes([0xFF, 0xAA, 0x00, 0x00, 0x00]) == wit.SAVE


@pytest.mark.parametrize(("data", "why"), [
    (frame_bytes(0x51, 1, 2, 3, 4)[:10], "10 bytes"),
    (b"\x54" + frame_bytes(0x51, 1, 2, 3, 4)[1:], "header 0x54"),
    (frame_bytes(0x51, 1, 2, 3, 4)[:10] + b"\x00", "checksum 0x00"),
    (bytes([0x55, 0x40]) + bytes(9), "type 0x40"),
])
def test_a_malformed_frame_says_what_is_wrong(data, why):
    with pytest.raises(ProtocolError, match=why):
        wit.decode_frame(data)


def test_encoding_refuses_what_does_not_fit():
    with pytest.raises(ProtocolError, match="int16"):
        wit.encode_frame(0x52, (0, 0, 40000, 0))
    with pytest.raises(ProtocolError, match="type 0x30"):
        wit.encode_frame(0x30, (0, 0, 0, 0))
    with pytest.raises(ProtocolError, match="4 values"):
        wit.encode_frame(0x52, (0, 0, 0))


@pytest.mark.parametrize("chunk", [1, 4, 11, 1000])
def test_the_decoder_drops_a_bad_frame_counts_it_and_resyncs_mid_stream(chunk):
    first = frame_bytes(0x51, 100, 200, 300, 2500)
    bad = bytearray(frame_bytes(0x52, 10, 20, 30, 40))
    bad[10] ^= 0x01  # a flipped bit in the checksum
    last = frame_bytes(0x53, 1000, -1000, 5000, 0)
    # the stream starts mid-frame and has a stray 0x55 that no frame type follows
    stream = frame_bytes(0x52, 7, 8, 9, 10)[5:] + b"\x55\x13" + first + bytes(bad) + last
    decoder = wit.FrameDecoder()
    frames = []
    for i in range(0, len(stream), chunk):
        frames += decoder.feed(stream[i : i + chunk])
    assert frames == [wit.decode_frame(first), wit.decode_frame(last)]
    assert decoder.bad_frames == 1
    assert decoder.skipped_bytes == 6 + 2 + 10  # the partial frame, the stray pair, the bad frame less its 0x55
    assert decoder.feed(frame_bytes(0x54, 1, 2, 3, 4)) == [wit.Frame(0x54, (1, 2, 3, 4))]  # others decode too


def test_a_real_frame_hidden_behind_a_false_header_is_found():
    good = frame_bytes(0x51, 1, 2, 3, 4)
    decoder = wit.FrameDecoder()
    assert decoder.feed(b"\x55\x51\x00" + good) == [wit.decode_frame(good)]
    assert decoder.bad_frames == 1


def test_rotation_matrix_and_its_euler_angles_round_trip():
    for angles in [(0.1, -0.2, 0.3), (math.pi, 0.0, 0.0), (0.0, 0.5, -2.5)]:
        assert wit.euler_from_matrix(wit.rotation_matrix(*angles)) == pytest.approx(angles)
    upside_down = wit.rotation_matrix(math.pi, 0.0, 0.0)
    assert upside_down @ (0.0, 0.0, 1.0) == pytest.approx((0.0, 0.0, -1.0))


# -- rotation and bias on hand-made frames -----------------------------------------------------------------------
def assemble(rotation, accel_raw, gyro_raw, bias_s=0.0, t=0.0):
    assembler = SampleAssembler(rotation, GyroBiasEstimator(bias_s))
    assert assembler.add(wit.decode_frame(frame_bytes(0x51, *accel_raw, 2500)), t) is None
    return assembler, assembler.add(wit.decode_frame(frame_bytes(0x52, *gyro_raw, 0)), t)


def test_an_upside_down_sensor_reports_the_base_yaw_rate_with_the_right_sign():
    # mounted with roll = π its z axis points down: turning left (+yaw) it measures a negative wz, and gravity
    # on its -z; its y axis points right, so the base's +y acceleration shows as -y
    _, sample = assemble((math.pi, 0.0, 0.0), (0, -205, -2048), (0, 0, -8192))  # ay = -1 m/s², wz = -500 °/s
    assert sample is not None
    assert sample.yaw_rate_radps == pytest.approx(math.radians(500.0))
    assert sample.accel_x_mps2 == pytest.approx(0.0, abs=1e-9)
    assert sample.accel_y_mps2 == pytest.approx(205 * ACCEL_LSB)


def test_a_sensor_turned_a_quarter_left_reports_its_x_on_the_base_y():
    _, sample = assemble((0.0, 0.0, math.pi / 2), (2048, 0, 2048), (0, 0, 1000))
    assert sample is not None
    assert sample.accel_x_mps2 == pytest.approx(0.0, abs=1e-9)
    assert sample.accel_y_mps2 == pytest.approx(G)
    assert sample.yaw_rate_radps == pytest.approx(1000 * GYRO_LSB)


def test_only_a_gyro_frame_after_an_acceleration_frame_makes_a_sample():
    assembler, sample = assemble((0.0, 0.0, 0.0), (0, 0, 2048), (0, 0, 10))
    assert sample is not None
    for other in (0x53, 0x54, 0x59, 0x50):
        assert assembler.add(wit.Frame(other, (1, 2, 3, 4)), 0.1) is None
    assert assembler.add(wit.Frame(0x52, (0, 0, 10, 0)), 0.1) is None  # its acceleration frame was lost
    assert assembler.incomplete == 1


def test_the_bias_is_the_mean_of_the_still_readings_and_a_move_is_logged(caplog):
    bias = GyroBiasEstimator(1.0)
    for i, wz in enumerate([0.01, 0.03, 1.0, 0.02]):  # 1 rad/s: the robot was pushed
        bias.update(i * 0.1, (0.0, 0.0, wz))
    assert not bias.settled
    assert bias.bias == pytest.approx((0.0, 0.0, 0.02))
    with caplog.at_level(logging.INFO):
        bias.update(1.0, (0.0, 0.0, 0.5))
    assert bias.settled
    assert bias.bias == pytest.approx((0.0, 0.0, 0.02))
    assert "moved" in caplog.text and "3 still readings of 4" in caplog.text


def test_no_still_reading_means_no_bias_and_a_warning(caplog):
    bias = GyroBiasEstimator(0.5)
    bias.update(0.0, (0.0, 0.0, 1.0))
    with caplog.at_level(logging.WARNING):
        bias.update(0.6, (0.0, 0.0, 0.0))
    assert bias.settled and bias.bias == (0.0, 0.0, 0.0)
    assert "no bias is subtracted" in caplog.text
    assert GyroBiasEstimator(0.0).settled  # bias_s = 0: no measurement at all


def test_a_wrong_mounting_rotation_is_reported(caplog):
    # the sensor is upside down but configured as upright: gravity shows on the base's -z
    assembler = SampleAssembler((0.0, 0.0, 0.0), GyroBiasEstimator(0.2))
    with caplog.at_level(logging.WARNING):
        for i in range(5):
            assembler.add(wit.decode_frame(frame_bytes(0x51, 0, 0, -2048, 2500)), i * 0.1)
            assembler.add(wit.decode_frame(frame_bytes(0x52, 0, 0, 3, 0)), i * 0.1)
    assert "mounting rotation" in caplog.text


# -- the emulator on its own ---------------------------------------------------------------------------------------
def test_the_emulator_streams_the_sensor_s_view_of_the_base_motion():
    with Wt901Emulator(rotation=(math.pi, 0.0, 0.0), gyro_bias_radps=(0.0, 0.0, 0.01)) as emu:
        cycle = emu.cycle(ImuSample(0.0, 1.0, 2.0, 0.0), 0.5)
        cycle += emu.cycle(ImuSample(0.0, 1.0, 2.0, 0.0), 0.5)
        assert Path(emu.port).is_symlink()
        directory = Path(emu.port).parent
    assert not directory.exists()  # close removed the link and its directory
    frames = wit.FrameDecoder().feed(cycle)
    assert [f.type for f in frames] == [0x51, 0x52, 0x53] * 2
    assert wit.accel_mps2(frames[0]) == pytest.approx((2.0, 0.0, -G), abs=ACCEL_LSB)
    assert wit.temperature_c(frames[0]) == pytest.approx(25.0)
    assert wit.angular_velocity_radps(frames[1]) == pytest.approx((0.0, 0.0, -1.0 + 0.01), abs=GYRO_LSB)
    roll, _, yaw = wit.angles_rad(frames[5])
    assert abs(roll) == pytest.approx(math.pi, abs=1e-3)  # upside down
    assert abs(yaw) == pytest.approx(1.0, abs=1e-3)  # two half-second cycles at 1 rad/s


# -- the driver against the emulator -------------------------------------------------------------------------------
class Motion:
    """A feed the test steers: the base's yaw rate and acceleration."""

    def __init__(self) -> None:
        self.yaw_rate = 0.0
        self.accel = (0.0, 0.0)

    def __call__(self) -> ImuSample:
        return ImuSample(time.monotonic(), self.yaw_rate, *self.accel)


def poll(driver: Wt901Driver, condition: Callable[[], bool], timeout_s: float = 2.0) -> bool:
    """Tick the driver until ``condition`` holds or ``timeout_s`` passes."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        driver.tick(time.monotonic())
        if condition():
            return True
        time.sleep(0.01)
    driver.tick(time.monotonic())
    return condition()


@pytest.fixture
def rig() -> Iterator[Callable[..., tuple[Wt901Emulator, Wt901Driver, Motion]]]:
    """Make an emulator and a driver on its port; both are closed at the end."""
    made: list[tuple[Wt901Emulator, Wt901Driver]] = []

    def make(rotation=(0.0, 0.0, 0.0), gyro_bias=(0.0, 0.0, 0.0), bias_s=0.0, **emulator):
        motion = Motion()
        emu = Wt901Emulator(motion, rotation=rotation, gyro_bias_radps=gyro_bias, **emulator)
        driver = Wt901Driver(emu.port, now=time.monotonic, rotation=rotation, bias_s=bias_s)
        made.append((emu, driver))
        emu.start()
        driver.start()
        return emu, driver, motion

    yield make
    for emu, driver in made:
        driver.shutdown()
        emu.close()


def test_the_driver_reads_the_emulator_end_to_end(rig):
    emu, driver, motion = rig(rotation=(math.pi, 0.0, 0.3))
    motion.yaw_rate, motion.accel = -0.7, (0.5, -0.25)
    assert poll(driver, lambda: driver.count >= 20)
    sample = driver.latest
    assert sample is not None
    assert sample.yaw_rate_radps == pytest.approx(-0.7, abs=2 * GYRO_LSB)
    assert (sample.accel_x_mps2, sample.accel_y_mps2) == pytest.approx((0.5, -0.25), abs=3 * ACCEL_LSB)
    assert driver.health(time.monotonic()).ok
    assert driver.sample_rate_hz == pytest.approx(50.0, rel=0.3)
    assert driver.bad_frames == 0
    assert driver.info() == DeviceInfo(kind="imu", driver="wt901", port=emu.port, model="WT901")


def test_a_gyro_bias_measured_standing_still_is_subtracted(rig):
    _, driver, motion = rig(gyro_bias=(0.0, 0.0, math.radians(1.5)), bias_s=0.3)
    assert poll(driver, lambda: driver.bias_settled and driver.count >= 20)
    sample = driver.latest
    assert sample is not None
    assert abs(sample.yaw_rate_radps) < math.radians(0.1)
    assert driver.gyro_bias_radps[2] == pytest.approx(math.radians(1.5), abs=GYRO_LSB)
    motion.yaw_rate = 0.4
    assert poll(driver, lambda: driver.latest is not None and driver.latest.yaw_rate_radps > 0.3)
    assert poll(driver, lambda: driver.count >= 30)
    assert driver.latest.yaw_rate_radps == pytest.approx(0.4, abs=math.radians(0.1))


def test_corrupted_frames_are_dropped_and_counted_while_samples_flow(rig):
    emu, driver, _ = rig()
    assert poll(driver, lambda: driver.count >= 5)
    emu.corrupt_next(6)  # two whole cycles
    count = driver.count
    assert poll(driver, lambda: driver.bad_frames >= 6 and driver.count >= count + 5)
    assert driver.health(time.monotonic()).ok


def test_unplugging_makes_the_imu_unhealthy_and_replugging_brings_it_back(rig):
    emu, driver, _ = rig(gyro_bias=(0.0, 0.0, math.radians(1.0)), bias_s=0.2)
    assert poll(driver, lambda: driver.health(time.monotonic()).ok and driver.bias_settled)
    emu.unplug()
    assert poll(driver, lambda: not driver.health(time.monotonic()).ok, timeout_s=1.0)
    assert poll(driver, lambda: "does not exist" in driver.health(time.monotonic()).detail, timeout_s=1.0)
    emu.replug()
    count = driver.count
    assert poll(driver, lambda: driver.health(time.monotonic()).ok and driver.count >= count + 5)
    assert driver.reconnects == 1
    # the bias is measured again after the reconnection (a re-plugged WT901 has restarted)
    assert poll(driver, lambda: driver.bias_settled and driver.count >= count + 15)
    assert abs(driver.latest.yaw_rate_radps) < math.radians(0.1)


def test_a_missing_port_is_an_unhealthy_device_that_says_what_to_check(tmp_path):
    driver = Wt901Driver(str(tmp_path / "ttyUSB9"), now=time.monotonic)
    driver.start()
    try:
        assert poll(driver, lambda: "does not exist" in driver.health(time.monotonic()).detail, timeout_s=1.0)
        assert "is the WT901 plugged in" in driver.health(time.monotonic()).detail
    finally:
        driver.shutdown()
    assert not driver.health(time.monotonic()).ok


def test_a_permission_error_points_at_the_dialout_group():
    driver = Wt901Driver("/dev/ttyUSB1", now=time.monotonic)
    hint = driver.missing_hint(PermissionError(errno.EACCES, "Permission denied"))
    assert "/dev/ttyUSB1" in hint and "dialout" in hint


def test_bytes_without_frames_suggest_a_wrong_baud_rate(tmp_path):
    master, slave = os.openpty()
    tty.setraw(slave)
    link = tmp_path / "imu"
    link.symlink_to(os.ttyname(slave))
    driver = Wt901Driver(str(link), now=time.monotonic, baudrate=115200)
    driver.start()
    try:
        def garbled() -> bool:
            os.write(master, bytes(range(0x60, 0x80)))  # no 0x55 header: noise at a wrong baud rate
            return "baud rate 115200" in driver.health(time.monotonic()).detail
        assert poll(driver, garbled)
        assert driver.count == 0
    finally:
        driver.shutdown()
        os.close(master)
        os.close(slave)


def test_from_config_takes_the_devices_imu_section():
    cfg = ImuDeviceConfig(driver="wt901", port="/dev/imu", baudrate=115200, rotation=(math.pi, 0.0, 0.0), bias_s=2.0)
    driver = Wt901Driver.from_config(cfg, now=time.monotonic, name="imu0")
    assert (driver.name, driver.port, driver.baudrate) == ("imu0", "/dev/imu", 115200)
    assert not driver.bias_settled
    assert not driver.health(0.0).ok  # not started
    with pytest.raises(ValueError, match="rotation"):
        Wt901Driver("/dev/imu", now=time.monotonic, rotation=(0.0, 0.0))
