"""CAN codec throughput: our encode+decode of a realistic frame mix against cantools decoding the same frames
with the shipped DBC, and against the frame rate a 1 Mbit/s bus can carry.

The mix is one second of this robot's bus: the driver at 50 Hz (speed command + status-2 reply per motor),
status 1 at 5 Hz per motor, IR sensors at 20 Hz, the 0x153 status at 10 Hz, heartbeats at 2 Hz each way
and the power frame at 1 Hz. Run: ``.venv/bin/python benchmarks/bench_can.py`` (or ``atemr bench can``).

The last row is the in-process bus the simulated robot runs on (`atemr.io.can.inprocess.InProcessBus`) against
python-can's ``virtual`` bus: one simulated second of the robot's bus, the frames above sent from their
senders' ticks at 50 Hz and five participants (primary, two motor emulators, secondary core, recorder tap)
draining it with ``recv(timeout=0)`` every tick, as the simulation does. Median CPU time of interleaved trials.
"""

from __future__ import annotations

import math
import random
import statistics
import time
from collections.abc import Callable
from typing import Any

import can

from atemr.io.can import protocol as p
from atemr.io.can.bus import unique_channel
from atemr.io.can.dbc import load_database
from atemr.io.can.inprocess import InProcessBus
from atemr.io.motors import rmd_codec as r

#: Frames per second an 8-byte standard frame allows at 1 Mbit/s (≈125 bits each with stuffing).
BUS_FRAMES_PER_S = 8000.0


def frame_mix(seed: int = 0) -> list[tuple[Any, Callable[[can.Message], Any]]]:
    """One second of traffic as (message, the decoder its receiver uses), shuffled with ``seed``."""
    rng = random.Random(seed)
    mix: list[tuple[Any, Callable[[can.Message], Any]]] = []
    for k in range(50):
        for motor in (1, 2):
            speed = math.sin(k / 7 + motor) * 10
            mix.append((r.RmdRequest(motor, r.RmdCommand.SPEED_CONTROL, speed), r.decode_request))
            mix.append((r.Status2Reply(motor, r.RmdCommand.SPEED_CONTROL, 31, 1.5, speed, (k * 331) % 16384),
                        r.decode_reply))
    for _ in range(5):
        for motor in (1, 2):
            mix.append((r.RmdRequest(motor, r.RmdCommand.READ_STATUS_1), r.decode_request))
            mix.append((r.Status1Reply(motor, r.RmdCommand.READ_STATUS_1, 31, 24.3, r.MotorErrorFlags.NONE),
                        r.decode_reply))
    for k in range(20):
        mix.append((p.IrFront(10.0 + k * 0.1, 11.0), p.decode))
        mix.append((p.IrRear(12.5), p.decode))
    for _ in range(10):
        mix.append((p.PrimaryStatus(p.AgentBits(0x1F), p.HardwareBits(0xFF), p.StateCode.EXEC), p.decode))
    for _ in range(2):
        mix.append((p.Heartbeat(True), p.decode))
        mix.append((p.Heartbeat(False), p.decode))
    mix.append((p.Power(p.PowerState.RUNNING), p.decode))
    rng.shuffle(mix)
    return mix


def _best_rate(fn: Callable[[], int], repeats: int) -> float:
    """Frames per second of the best of ``repeats`` runs of ``fn`` (which returns the frames it handled)."""
    best = math.inf
    frames = 0
    for _ in range(repeats):
        t0 = time.perf_counter()
        frames = fn()
        best = min(best, time.perf_counter() - t0)
    return frames / best


def run(quick: bool = False) -> list[dict[str, Any]]:
    """Rows for the harness: ours vs cantools, and ours vs the bus's frame rate."""
    mix = frame_mix()
    rounds = 3 if quick else 25
    repeats = 3 if quick else 7
    frames = [m.encode() for m, _ in mix]
    raw = [(f.arbitration_id, bytes(f.data)) for f in frames]
    db = load_database()
    db_decode = db.decode_message

    def ours_encode_decode() -> int:
        for _ in range(rounds):
            for message, decoder in mix:
                decoder(message.encode())
        return rounds * len(mix)

    def ours_decode() -> int:
        for _ in range(rounds):
            for (_, decoder), frame in zip(mix, frames, strict=True):
                decoder(frame)
        return rounds * len(mix)

    def cantools_decode() -> int:
        for _ in range(rounds):
            for frame_id, data in raw:
                db_decode(frame_id, data)
        return rounds * len(raw)

    ours_full = _best_rate(ours_encode_decode, repeats)
    ours_dec = _best_rate(ours_decode, repeats)
    theirs = _best_rate(cantools_decode, repeats)
    return [
        {"what": "encode+decode, realistic mix vs cantools decode only", "ours": ours_full, "baseline": theirs,
         "ratio": ours_full / theirs, "goal": 1.0, "unit": "frames/s"},
        {"what": "decode only vs cantools decode", "ours": ours_dec, "baseline": theirs,
         "ratio": ours_dec / theirs, "goal": 1.0, "unit": "frames/s"},
        {"what": "encode+decode vs a full 1 Mbit/s bus", "ours": ours_full, "baseline": BUS_FRAMES_PER_S,
         "ratio": ours_full / BUS_FRAMES_PER_S, "goal": 20.0, "unit": "frames/s"},
        in_process_bus(frames, 3 if quick else 15),
    ]


def in_process_bus(frames: list[can.Message], trials: int, participants: int = 5, ticks: int = 50
                   ) -> dict[str, Any]:
    """One simulated second of the robot's bus on our in-process bus and on python-can's virtual bus (see the
    module docstring): simulated seconds per CPU second, and the ratio."""
    per_tick = [frames[k::ticks] for k in range(ticks)]

    def one_second(open_bus: Callable[[str], can.BusABC]) -> Callable[[], int]:
        channel = unique_channel("bench-bus")
        buses = [open_bus(channel) for _ in range(participants)]

        def run_once() -> int:
            delivered = 0
            for k, batch in enumerate(per_tick):
                sender = buses[k % participants]
                for frame in batch:
                    sender.send(frame)
                for bus in buses:
                    while bus.recv(timeout=0) is not None:
                        delivered += 1
            return delivered

        run_once.buses = buses  # type: ignore[attr-defined]
        return run_once

    runs = {"ours": one_second(InProcessBus),
            "python-can": one_second(lambda channel: can.Bus(interface="virtual", channel=channel))}
    times: dict[str, list[float]] = {name: [] for name in runs}
    delivered = {}
    try:
        for _ in range(trials):
            for name, run_once in runs.items():
                t0 = time.thread_time()
                delivered[name] = run_once()
                times[name].append(time.thread_time() - t0)
    finally:
        for run_once in runs.values():
            for bus in run_once.buses:  # type: ignore[attr-defined]
                bus.shutdown()
    assert delivered["ours"] == delivered["python-can"] == len(frames) * (participants - 1), delivered
    ours, theirs = statistics.median(times["ours"]), statistics.median(times["python-can"])
    return {"what": f"in-process bus, 1 s of the robot's bus ({len(frames)} frames, {participants} participants "
                    f"polling at {ticks} Hz) vs python-can's virtual bus",
            "ours": 1.0 / ours, "baseline": 1.0 / theirs, "ratio": theirs / ours, "goal": 1.0,
            "unit": "bus s per CPU s"}


if __name__ == "__main__":
    for row in run():
        print(f"{row['what']:<55} ours {row['ours']:>10,.0f}  baseline {row['baseline']:>10,.0f} {row['unit']}"
              f"  ratio {row['ratio']:6.2f}x (goal >= {row['goal']}x)")
