"""Start-up → idle → mission → idle → power-off with the real CAN link and the emulated secondary core on a
virtual python-can bus, checked frame by frame: 0x150 power bytes, 0x153 state codes, 0x157 heartbeat."""

from __future__ import annotations

import itertools
from pathlib import Path

import can

from atemr.domain.status import PowerRequest, PowerState, StateCode
from atemr.fsm.agent import Agent
from atemr.fsm.spec import AgentSpec
from atemr.io.can import Heartbeat, Power, PrimaryStatus
from atemr.robot.port import SecondaryLinkPort
from atemr.trees.fakes import RecordingPort
from atemr.trees.missions import load_mission
from secondary_core.harness import LinkBench

LOOK_AROUND = Path(__file__).resolve().parents[2] / "trees" / "missions" / "look-around.yaml"


def collapse(values: list[int]) -> list[int]:
    return [v for v, _ in itertools.groupby(values)]


def primary_frames(bench: LinkBench, arbitration_id: int, decode: type) -> list[tuple[float, object]]:
    """Frames with ``arbitration_id`` as the primary sent them (the spy sees both ends)."""
    out = []
    for t, msg in bench.frames_with_id(arbitration_id):
        value = decode.decode(msg)
        out.append((t, value))
    return out


def test_start_idle_mission_idle_power_off_frame_by_frame(agent_spec: AgentSpec) -> None:
    with LinkBench() as bench:
        port = RecordingPort(dt_s=0.1)
        agent = Agent(agent_spec, port, SecondaryLinkPort(bench.link), on_halt=lambda: bench.pause("link"))
        bench.run(bench.core.config.boot_s + 0.1)
        bench.core.button.hold(1.0)  # the operator powers the primary on
        bench.run(1.1)
        t_on = bench.now
        bench.scheduler.add(agent, 10.0)  # the primary's software starts
        bench.run_until(lambda: agent.state == "IDLE.MANUAL", timeout_s=5.0)
        agent.submit("set_auto")
        bench.run(0.3)
        agent.submit("start_mission", mission=load_mission(LOOK_AROUND))
        bench.run_until(lambda: agent.state == "EXEC", timeout_s=1.0)
        bench.run_until(lambda: agent.state == "IDLE.AUTO", timeout_s=40.0)
        t_mission_done = bench.now
        assert len(port.images) == 4
        bench.core.button.hold(5.0)  # the operator holds the button: power-off request
        bench.run_until(lambda: agent.halted, timeout_s=7.0)
        t_halt = bench.now
        bench.run(1.0)

        # 0x153: the state codes the primary reported, in order, and at least at 2 Hz while it ran.
        statuses = [(t, s) for t, s in primary_frames(bench, 0x153, PrimaryStatus) if t >= t_on]
        codes = collapse([int(s.state) for _, s in statuses])  # type: ignore[attr-defined]
        assert codes[codes.index(StateCode.STARTUP):] == [StateCode.STARTUP, StateCode.IDLE, StateCode.EXEC,
                                                          StateCode.IDLE, StateCode.SHUTDOWN]
        gaps = [b[0] - a[0] for a, b in itertools.pairwise(statuses) if b[0] <= t_halt]
        assert max(gaps) <= 0.5 + 0.021
        auto = [s.auto_mode for t, s in statuses if t_on + 1.0 < t < t_mission_done]  # type: ignore[attr-defined]
        assert auto[-1] is True

        # 0x150: the primary's power byte goes initialising → running → power-off acknowledged, and the
        # acknowledgement comes after the secondary's request.
        power = [(t, p) for t, p in primary_frames(bench, 0x150, Power)]
        mine = [p.state for t, p in power if p.request == PowerRequest.NORMAL]  # type: ignore[attr-defined]
        assert collapse([int(s) for s in mine]) == [PowerState.INITIALISING, PowerState.RUNNING,
                                                    PowerState.POWER_OFF_ACK]
        request_t = min(t for t, p in power if p.request == PowerRequest.POWER_OFF)  # type: ignore[attr-defined]
        ack_t = min(t for t, p in power if p.state == PowerState.POWER_OFF_ACK)  # type: ignore[attr-defined]
        assert request_t < ack_t <= request_t + 0.5
        assert bench.core.power_off_acknowledged

        # 0x157: the primary pings every 0.5 s and the board answers each ping while the primary runs.
        beats = primary_frames(bench, 0x157, Heartbeat)
        pings = [t for t, h in beats if h.from_primary and t_on <= t <= t_halt]  # type: ignore[attr-defined]
        answers = [t for t, h in beats if not h.from_primary and t_on <= t <= t_halt]  # type: ignore[attr-defined]
        assert all(abs(b - a - 0.5) < 1e-6 for a, b in itertools.pairwise(pings))
        assert len(answers) >= len(pings) - 1
        assert all(t <= t_halt + 0.021 for t, h in beats if h.from_primary)  # type: ignore[attr-defined]

        # The agent's own trace tells the same story.
        accepted = [r.dest for r in agent.trace if r.accepted]
        assert accepted == ["STARTUP", "IDLE.MANUAL", "IDLE.AUTO", "EXEC", "IDLE.AUTO", "SHUTDOWN.POWEROFF"]
        assert isinstance(bench.spy, can.BusABC)
