"""Device drivers: how far the decoders run ahead of what the devices can send.

The peers here are the devices themselves: an RPLidar A2M8 sends at most 8,000 samples/s in standard SCAN
mode, a WT901 at most 200 output cycles (600 frames: acceleration, angular velocity, angle) per second. Rows:

* RPLidar samples decoded per second (`ScanDecoder` plus `RevolutionAssembler`, fed in 4 KiB reads as the
  driver reads them) against the device's 8,000 samples/s;
* the same, plus each revolution binned into a `LaserScan` (`revolution_to_scan`, 360 bins): the driver's
  whole path from bytes to scans;
* WT901 frames decoded per second (`FrameDecoder`, 4 KiB reads) against the device's 600 frames/s.

Run: ``benchmarks/run devices`` (or ``atemr bench devices``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from atemr.io.devices import rplidar_protocol as rp
from atemr.io.devices import wt901_protocol as wit
from atemr.msgs import Pose2D

RPLIDAR_SAMPLES_PER_S = 8000.0
WT901_FRAMES_PER_S = 600.0


def best_of(fn: Callable[[], Any], repeat: int) -> float:
    """Shortest wall time of ``repeat`` runs (the machine may be busy)."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def decode_and_bin(data: bytes, chunk: int = 4096) -> int:
    """Bytes → samples → revolutions → 360-bin scans, as the driver does; the scans made."""
    decoder, revolutions = rp.ScanDecoder(), rp.RevolutionAssembler()
    scans = 0
    for i in range(0, len(data), chunk):
        for revolution in revolutions.push(decoder.feed(data[i:i + chunk])):
            rp.revolution_to_scan(revolution, 0.0, beams=360, range_min_m=0.15, range_max_m=8.0, pose=Pose2D())
            scans += 1
    return scans


def wt901_stream(cycles: int) -> bytes:
    """``cycles`` output cycles of a WT901 turning slowly."""
    out = bytearray()
    for k in range(cycles):
        out += wit.accel_frame((0.1, 0.0, 9.81)) + wit.gyro_frame((0.0, 0.0, 0.01 * (k % 50)))
        out += wit.angle_frame((0.0, 0.0, 0.001 * k))
    return bytes(out)


def decode_wt901(data: bytes, chunk: int = 4096) -> int:
    decoder = wit.FrameDecoder()
    frames = 0
    for i in range(0, len(data), chunk):
        frames += len(decoder.feed(data[i:i + chunk]))
    return frames


def run(quick: bool = False) -> list[dict[str, Any]]:
    """Measure and return the rows (see the module docstring)."""
    samples = 40_000 if quick else 400_000
    data = rp.synthetic_scan_bytes(samples)
    repeat = 1 if quick else 3
    decoded = rp.decode_stream(data)
    if decoded != samples:
        raise AssertionError(f"decoded {decoded} of {samples} samples")
    decode_s = best_of(lambda: rp.decode_stream(data), repeat)
    scans = decode_and_bin(data)
    binned_s = best_of(lambda: decode_and_bin(data), repeat)
    cycles = 2_000 if quick else 20_000
    stream = wt901_stream(cycles)
    if decode_wt901(stream) != 3 * cycles:
        raise AssertionError("the WT901 decoder lost frames")
    wt_s = best_of(lambda: decode_wt901(stream), repeat)
    return [
        {"what": f"RPLidar SCAN samples decoded ({samples:,} samples in 4 KiB reads) vs the A2M8's 8,000/s",
         "ours": samples / decode_s, "baseline": RPLIDAR_SAMPLES_PER_S, "ratio": samples / decode_s
         / RPLIDAR_SAMPLES_PER_S, "goal": 10.0, "unit": "samples/s"},
        {"what": f"RPLidar bytes to 360-bin scans ({scans} revolutions of 800 samples) vs the A2M8's 8,000/s",
         "ours": samples / binned_s, "baseline": RPLIDAR_SAMPLES_PER_S,
         "ratio": samples / binned_s / RPLIDAR_SAMPLES_PER_S, "goal": 10.0, "unit": "samples/s"},
        {"what": f"WT901 frames decoded ({3 * cycles:,} frames) vs the device's 600 frames/s at 200 Hz",
         "ours": 3 * cycles / wt_s, "baseline": WT901_FRAMES_PER_S, "ratio": 3 * cycles / wt_s / WT901_FRAMES_PER_S,
         "goal": 10.0, "unit": "frames/s"},
    ]
