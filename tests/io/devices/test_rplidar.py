"""The RPLidar A2M8: the protocol codec against byte examples built from SLAMTEC's protocol document, and the
driver against the pty emulator (scans, device info, corruption, health error, unplug and replug)."""

from __future__ import annotations

import errno
import math
import os
import time
import tty
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from atemr.errors import ProtocolError
from atemr.io.devices import rplidar
from atemr.io.devices import rplidar_protocol as rp
from atemr.io.devices.config import LidarDeviceConfig
from atemr.io.devices.rplidar import RplidarDriver
from atemr.io.devices.rplidar_emulator import A2M8_INFO, RplidarEmulator, distances_mm
from atemr.msgs import LaserScan, Pose2D

BEAMS = 360
INC = 2 * math.pi / BEAMS


# -- the codec ---------------------------------------------------------------------------------------------------


def test_requests_are_encoded_as_the_protocol_document_shows():
    assert rp.encode_request(rp.Command.STOP) == bytes.fromhex("a5 25")
    assert rp.encode_request(rp.Command.SCAN) == bytes.fromhex("a5 20")
    assert rp.encode_request(rp.Command.GET_HEALTH) == bytes.fromhex("a5 52")
    # checksum: XOR of every byte before it, 0xA5 included (A5^82^05 = 22)
    assert rp.express_scan_request() == bytes.fromhex("a5 82 05 00 00 00 00 00 22")
    assert rp.motor_pwm_request(660) == bytes.fromhex("a5 f0 02 94 02") + bytes((0xA5 ^ 0xF0 ^ 0x02 ^ 0x94 ^ 0x02,))
    with pytest.raises(ProtocolError, match="no payload"):
        rp.encode_request(rp.Command.STOP, b"\x00")


def test_request_parser_skips_noise_and_bad_checksums():
    parser = rp.RequestParser()
    stream = b"\x00\x11" + rp.encode_request(rp.Command.STOP) + bytes.fromhex("a5 f0 02 94 02 00")
    stream += rp.motor_pwm_request(660)
    got = parser.feed(stream[:5]) + parser.feed(stream[5:])
    assert got == [rp.Request(rp.Command.STOP), rp.Request(rp.Command.MOTOR_PWM, (660).to_bytes(2, "little"))]
    assert parser.bad_requests == 1


def test_descriptors():
    scan = rp.parse_descriptor(bytes.fromhex("a5 5a 05 00 00 40 81"))
    assert scan == rp.ResponseDescriptor(5, rp.SendMode.MULTIPLE, rp.AnswerType.MEASUREMENT)
    assert rp.parse_descriptor(bytes.fromhex("a5 5a 14 00 00 00 04")) == rp.ResponseDescriptor(20, 0, 0x04)
    assert rp.parse_descriptor(bytes.fromhex("a5 5a 03 00 00 00 06")) == rp.ResponseDescriptor(3, 0, 0x06)
    assert rp.parse_descriptor(bytes.fromhex("a5 5a 54 00 00 40 82")).length == 84
    assert rp.encode_descriptor(5, 1, 0x81) == bytes.fromhex("a5 5a 05 00 00 40 81")
    with pytest.raises(ProtocolError, match="A5 5A"):
        rp.parse_descriptor(bytes.fromhex("a5 5b 05 00 00 40 81"))
    with pytest.raises(ProtocolError, match="need 7"):
        rp.parse_descriptor(b"\xa5\x5a")


def test_get_info_and_get_health_replies():
    reply = bytes.fromhex("28 1d 01 07") + bytes(range(16))
    info = rp.parse_info(reply)
    assert (info.model, info.model_name, info.firmware, info.hardware) == (0x28, "A2M8", "1.29", 7)
    assert info.serial_number == "000102030405060708090A0B0C0D0E0F"
    assert rp.encode_info(info) == reply
    health = rp.parse_health(bytes.fromhex("02 34 12"))
    assert (health.status, health.error_code, health.status_name) == (2, 0x1234, "error")
    assert rp.encode_health(health) == bytes.fromhex("02 34 12")
    with pytest.raises(ProtocolError, match="GET_INFO"):
        rp.parse_info(reply[:19])


def test_a_sample_decodes_to_degrees_and_millimetres():
    # quality 15, S=1: 15<<2 | !S<<1 | S = 0x3D; 90° = 5760/64: (5760<<1)|C = 0x2D01; 1000.25 mm = 4001/4 = 0x0FA1
    sample = bytes.fromhex("3d 01 2d a1 0f")
    assert rp.ScanDecoder().feed(sample) == [rp.ScanSample(90.0, 1000.25, 15, True)]
    assert rp.encode_sample(90.0, 1000.25, 15, start=True) == sample
    # no return: distance 0; angle 359.984375 = 23039/64 is the largest
    assert rp.ScanDecoder().feed(rp.encode_sample(23039 / 64, 0.0, 0)) == [rp.ScanSample(23039 / 64, 0.0, 0, False)]


def test_vectorised_encoding_matches_the_scalar_one():
    angles, dists = np.array([0, 5760, 23039]), np.array([0, 4001, 65535])
    many = rp.encode_samples(angles, dists, np.array([0, 15, 63]), np.array([True, False, False]))
    one = b"".join(rp.encode_sample(a / 64, d / 4, q, s) for a, d, q, s in
                   zip(angles, dists, (0, 15, 63), (True, False, False), strict=True))
    assert many == one


def test_the_decoder_skips_samples_with_wrong_check_bits_and_resynchronises():
    good = [rp.encode_sample(10.0 * k, 500.0 + k, 20, start=k == 0) for k in range(4)]
    noise = bytes.fromhex("03 02 00")  # S = !S = 1; then S/!S fine but C = 0; then S = !S = 0
    c_clear = bytes.fromhex("3d 00 2d 00 00")  # a sample whose check bit C is 0 (0x2D then fails on C too)
    stream = good[0] + noise + good[1] + c_clear + good[2] + good[3]
    decoder = rp.ScanDecoder()
    got = decoder.feed(stream)
    assert [s.angle_deg for s in got] == [0.0, 10.0, 20.0, 30.0]
    assert [s.distance_mm for s in got] == [500.0, 501.0, 502.0, 503.0]
    assert decoder.bad_bytes == len(noise) + len(c_clear)
    # the same, a byte at a time (reads split samples anywhere)
    decoder = rp.ScanDecoder()
    assert [s for b in stream for s in decoder.feed(bytes((b,)))] == got
    assert decoder.bad_bytes == 8


def test_an_angle_of_a_full_turn_or_more_is_a_false_synchronisation():
    bad = bytes((0x3D, (23040 << 1 | 1) & 0xFF, (23040 << 1 | 1) >> 8, 0, 1))
    decoder = rp.ScanDecoder()
    assert decoder.feed(bad + rp.encode_sample(1.0, 100.0)) == [rp.ScanSample(1.0, 100.0, 47, False)]
    assert decoder.bad_bytes == 5


def test_revolutions_are_cut_at_the_start_flags():
    def s(angle: float, start: bool = False) -> rp.ScanSample:
        return rp.ScanSample(angle, 100.0, 10, start)

    assembler = rp.RevolutionAssembler(min_samples=3)
    assert assembler.push([s(300.0), s(350.0), s(0.0, True), s(180.0)]) == []  # the partial one is dropped
    assert assembler.push([s(359.0), s(0.5, True)]) == [[s(0.0, True), s(180.0), s(359.0)]]
    assert assembler.push([s(1.0), s(0.2, True)]) == [] and assembler.short == 1  # too short to be a scan


def test_a_start_flag_where_the_angle_did_not_wrap_is_not_believed():
    stream = b"".join(rp.encode_sample(a, 100.0, start=st) for a, st in
                      [(350.0, False), (0.1, True), (90.0, False), (180.0, True), (270.0, False), (0.3, True)])
    decoder = rp.ScanDecoder()
    assert [s.start for s in decoder.feed(stream)] == [False, True, False, False, False, True]
    assert decoder.false_starts == 1


def scan_of(samples: list[tuple[float, float]], beams: int = BEAMS, pose: Pose2D | None = None) -> LaserScan:
    return rp.revolution_to_scan([rp.ScanSample(a, d, 30, i == 0) for i, (a, d) in enumerate(samples)], 1.5,
                                 beams=beams, range_min_m=0.15, range_max_m=12.0, pose=pose or Pose2D())


def index_at(angle_rad: float, beams: int = BEAMS) -> int:
    return round((angle_rad + math.pi) / (2 * math.pi / beams)) % beams


def test_clockwise_degrees_become_counter_clockwise_bins_over_minus_pi_to_pi():
    scan = scan_of([(0.0, 1000.0), (90.0, 2000.0), (270.0, 3000.0), (180.0, 4000.0)])
    assert scan.angle_min_rad == -math.pi and scan.angle_increment_rad == pytest.approx(INC)
    assert len(scan.ranges_m) == BEAMS and scan.t == 1.5
    assert scan.ranges_m[index_at(0.0)] == 1.0  # straight ahead
    assert scan.ranges_m[index_at(-math.pi / 2)] == 2.0  # 90° clockwise: the sensor's right
    assert scan.angles_rad[index_at(-math.pi / 2)] == pytest.approx(-math.pi / 2)
    assert scan.ranges_m[index_at(math.pi / 2)] == 3.0  # 270° clockwise: the left
    assert scan.ranges_m[0] == 4.0  # behind: -pi
    assert np.isnan(scan.ranges_m).sum() == BEAMS - 4  # bins without a sample have no return


def test_binning_keeps_the_nearest_return_and_marks_what_is_out_of_range():
    scan = scan_of([(10.0, 3000.0), (10.3, 2500.0), (9.8, 0.0),  # nearest of three (one without return)
                    (20.0, 0.0),  # only "no return": NaN
                    (30.0, 100.0), (30.2, 5000.0),  # in range wins over closer than range_min
                    (40.0, 100.0),  # only too close: -inf
                    (50.0, 13000.0)])  # only too far: +inf
    r = scan.ranges_m
    assert r[index_at(math.radians(-10))] == 2.5
    assert np.isnan(r[index_at(math.radians(-20))])
    assert r[index_at(math.radians(-30))] == 5.0
    assert r[index_at(math.radians(-40))] == -np.inf
    assert r[index_at(math.radians(-50))] == np.inf


def test_the_mounting_pose_is_carried_and_an_empty_revolution_has_no_return():
    pose = Pose2D(0.1, -0.02, math.pi)
    scan = scan_of([], beams=720, pose=pose)
    assert scan.sensor_pose == pose and len(scan.ranges_m) == 720 and np.isnan(scan.ranges_m).all()


def test_express_capsules_round_trip_and_bad_checksums_are_skipped():
    offsets = [k % 4 for k in range(32)]
    first = rp.encode_capsule(10 * 64, list(range(100, 132)), offsets, new_scan=True)
    second = rp.encode_capsule(24 * 64, [0] * 32, offsets)
    assert len(first) == rp.CAPSULE_LEN and first[0] >> 4 == 0xA and first[1] >> 4 == 0x5
    decoder = rp.ExpressScanDecoder()
    assert decoder.feed(first) == []  # a capsule's angles need the next one's start angle
    got = decoder.feed(second)
    expected = rp.capsule_sample_angles(10.0, 24.0, [o / 8 for o in offsets])
    assert [s.angle_deg for s in got] == pytest.approx(expected)
    assert expected[1] == pytest.approx(10.0 + 14.0 / 32 - 0.125)
    assert [s.distance_mm for s in got] == list(range(100, 132))
    broken = bytearray(second)
    broken[40] ^= 0xFF
    decoder.feed(bytes(broken))
    assert decoder.bad_capsules == 1 and decoder.bad_bytes >= 1
    # signed compensations (protocol document: the top bit is the sign)
    third = rp.encode_capsule(40 * 64, [5] * 32, [-8] * 32)
    fourth = rp.encode_capsule(54 * 64, [5] * 32, [0] * 32)
    decoder = rp.ExpressScanDecoder()
    assert decoder.feed(third + fourth)[0].angle_deg == pytest.approx(41.0)


def test_benchmark_helpers_decode_every_sample():
    data = rp.synthetic_scan_bytes(10_000)
    assert len(data) == 50_000
    assert rp.decode_stream(data) == 10_000


def test_the_emulator_looks_scans_up_clockwise():
    ranges = np.full(BEAMS, np.nan)  # no return
    ranges[index_at(math.pi / 2)] = 2.0  # an obstacle on the left
    ranges[index_at(-math.pi / 2)] = 20.0  # a range the scan itself calls invalid: no return
    ranges[index_at(math.pi)] = np.inf  # a return beyond the range: the device measures one farther away
    feed = LaserScan(0.0, ranges, -math.pi, INC, 0.15, 12.0)
    assert distances_mm(feed, np.array([270.0, 90.0, 0.0, 180.0])).tolist() == [2000.0, 0.0, 0.0, 13000.0]
    assert distances_mm(None, np.array([1.0])).tolist() == [0.0]


# -- the driver against the emulator --------------------------------------------------------------------------


def known_scan() -> LaserScan:
    """A smooth room with a few beams without return and one whose return lies beyond the range, in the sensor
    frame (counter-clockwise)."""
    angles = -math.pi + INC * np.arange(BEAMS)
    ranges = 2.0 + 0.8 * np.sin(angles) + 0.3 * np.cos(3 * angles)
    ranges[[5, 90]] = np.nan
    ranges[200] = np.inf
    return LaserScan(0.0, ranges, -math.pi, INC, 0.15, 12.0)


FEED = known_scan()


def wait_for(condition: Callable[[], bool], driver: RplidarDriver, timeout_s: float = 3.0) -> float:
    """Tick ``driver`` until ``condition()``; the time it took (fails after ``timeout_s``)."""
    t0 = time.monotonic()
    while not condition():
        if time.monotonic() - t0 > timeout_s:
            pytest.fail(f"not within {timeout_s} s; health: {driver.health(time.monotonic())}")
        driver.tick(time.monotonic())
        time.sleep(0.005)
    return time.monotonic() - t0


@pytest.fixture
def emulator() -> Iterator[RplidarEmulator]:
    with RplidarEmulator(lambda: FEED) as emu:
        yield emu


@pytest.fixture
def make_driver() -> Iterator[Callable[..., RplidarDriver]]:
    drivers: list[RplidarDriver] = []

    def make(port: str, **settings: object) -> RplidarDriver:
        cfg = LidarDeviceConfig(driver="rplidar", port=port, pose=(0.1, 0.0, 0.0), **settings)
        driver = RplidarDriver.from_config(cfg, now=time.monotonic)
        drivers.append(driver)
        driver.start()
        return driver

    yield make
    for driver in drivers:
        driver.shutdown()


def assert_matches_feed(scan: LaserScan, tolerance_m: float) -> None:
    """Same bins as the feed: the emulator and the driver bin the same quantised angles, so only the distance
    quantisation remains (1/4 mm in SCAN, 1 mm in express capsules)."""
    assert scan.angle_min_rad == -math.pi and scan.angle_increment_rad == pytest.approx(INC)
    assert scan.sensor_pose == Pose2D(0.1, 0.0, 0.0)
    expected = FEED.ranges_m  # a beam without return stays NaN, one beyond the range +inf (REP 117)
    np.testing.assert_array_equal(np.isnan(scan.ranges_m), np.isnan(expected))
    np.testing.assert_array_equal(np.isposinf(scan.ranges_m), np.isposinf(expected))
    np.testing.assert_allclose(scan.ranges_m, expected, atol=tolerance_m, rtol=0)


@pytest.mark.parametrize(("scan_mode", "tolerance_m"), [("standard", 0.000125 + 1e-9), ("express", 0.0005 + 1e-9)])
def test_scans_match_the_feed_and_info_comes_from_get_info(emulator, make_driver, scan_mode, tolerance_m):
    driver = make_driver(emulator.port, scan_mode=scan_mode)
    wait_for(lambda: driver.count >= 3, driver)
    assert driver.health(time.monotonic()).ok
    assert_matches_feed(driver.latest, tolerance_m)
    assert driver.bad_bytes == 0
    info = driver.info()
    assert (info.kind, info.driver, info.port) == ("lidar", "rplidar", emulator.port)
    assert info.model == "RPLidar A2M8 (hardware 7)" and info.firmware == "1.29"
    assert info.serial_number == A2M8_INFO.serial_number
    # stop what runs, ask, start the motor (a pty has no DTR line: PWM only), scan
    scan_cmd = rp.Command.SCAN if scan_mode == "standard" else rp.Command.EXPRESS_SCAN
    assert emulator.commands[:5] == [rp.Command.STOP, rp.Command.GET_HEALTH, rp.Command.GET_INFO,
                                     rp.Command.MOTOR_PWM, scan_cmd]
    assert emulator.motor_pwm == 660 and driver.motor_line is False
    assert emulator.scanning == scan_mode


def test_corrupted_bytes_are_skipped_and_counted_and_scans_go_on(emulator, make_driver):
    driver = make_driver(emulator.port)
    wait_for(lambda: driver.count >= 2, driver)
    emulator.inject(bytes(7))
    emulator.corrupt_next(10)  # two whole samples zeroed
    wait_for(lambda: driver.bad_bytes >= 17, driver)
    count = driver.count
    wait_for(lambda: driver.count >= count + 3, driver)
    assert driver.bad_bytes == 17
    assert_matches_feed(driver.latest, 0.000125 + 1e-9)


def test_a_health_error_is_reported_with_its_code_and_the_device_reset(make_driver):
    with RplidarEmulator(lambda: FEED, health_status=rp.HealthStatus.ERROR, health_error_code=0x1234) as emu:
        driver = make_driver(emu.port)
        wait_for(lambda: "0x1234" in driver.health(time.monotonic()).detail, driver)
        # the driver says why, then resets: the emulator reads the reset from its pty a moment later
        wait_for(lambda: rp.Command.RESET in emu.commands, driver)
        status = driver.health(time.monotonic())
        assert not status.ok and "0x1234" in status.detail and "reports an error" in status.detail
        assert rp.Command.SCAN not in emu.commands and driver.count == 0
        emu.set_health(rp.HealthStatus.GOOD)  # the reset cleared it: the driver retries by itself
        wait_for(lambda: driver.count >= 2, driver)
        assert driver.health(time.monotonic()).ok


def test_a_health_warning_still_scans(make_driver):
    with RplidarEmulator(lambda: FEED, health_status=rp.HealthStatus.WARNING, health_error_code=7) as emu:
        driver = make_driver(emu.port)
        wait_for(lambda: driver.count >= 1, driver)
        assert driver.lidar_health == rp.LidarHealth(1, 7)


def test_unplug_is_unhealthy_within_a_second_and_replug_reconnects(emulator, make_driver):
    driver = make_driver(emulator.port)
    wait_for(lambda: driver.count >= 2, driver)
    emulator.unplug()
    took = wait_for(lambda: not driver.health(time.monotonic()).ok, driver, timeout_s=1.0)
    assert took < 1.0
    wait_for(lambda: "does not exist" in driver.health(time.monotonic()).detail, driver)
    count = driver.count
    emulator.replug()
    wait_for(lambda: driver.count >= count + 2, driver)
    assert driver.health(time.monotonic()).ok and driver.reconnects >= 1
    assert_matches_feed(driver.latest, 0.000125 + 1e-9)


def test_a_device_that_stops_streaming_is_restarted(emulator, make_driver, monkeypatch):
    monkeypatch.setattr(rplidar, "SILENCE_RESTART_S", 0.3)
    driver = make_driver(emulator.port)
    wait_for(lambda: driver.count >= 2, driver)
    emulator.reboot()  # a power glitch: the stream stops, the port stays
    wait_for(lambda: driver.reconnects >= 1, driver)
    count = driver.count
    wait_for(lambda: driver.count >= count + 2, driver)
    assert emulator.scanning == "standard" and driver.health(time.monotonic()).ok


def test_samples_per_second_are_measured(emulator, make_driver):
    driver = make_driver(emulator.port)
    wait_for(lambda: driver.sample_rate_hz is not None, driver)
    assert 6000 < driver.sample_rate_hz < 10000


def test_a_missing_port_says_what_to_do(tmp_path, make_driver):
    driver = make_driver(str(tmp_path / "rplidar"))
    wait_for(lambda: "does not exist" in driver.health(time.monotonic()).detail, driver)
    assert "plugged in" in driver.health(time.monotonic()).detail
    hint = driver.missing_hint(PermissionError(errno.EACCES, "Permission denied"))
    assert "dialout" in hint and str(tmp_path) in hint


def test_a_port_where_nothing_answers_says_so(make_driver, monkeypatch):
    monkeypatch.setattr(rplidar, "ANSWER_TIMEOUT_S", 0.2)
    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        driver = make_driver(os.ttyname(slave))
        wait_for(lambda: "no answer to GET_HEALTH" in driver.health(time.monotonic()).detail, driver)
        assert "is it an RPLidar, at 115200 baud?" in driver.health(time.monotonic()).detail
        driver.shutdown()
    finally:
        os.close(master)
        os.close(slave)
