"""The emulated board as the robot wires it, from the configuration."""

from __future__ import annotations

import can

from atemr.clock import SimClock
from atemr.config import load_config
from atemr.io.network import NmcliBackend, RecordingNetworkBackend
from atemr.io.secondary_emulator.board import SecondaryCore
from atemr.io.secondary_emulator.portal import PortalHost
from atemr.io.secondary_emulator.wiring import emulated_secondary
from atemr.io.secondary_link import InlineExecutor, build_secondary_link
from atemr.msgs import CliffReadings
from atemr.scheduler import Scheduler
from secondary_core.harness import unique_channel


def test_emulated_secondary_and_link_from_config_run_together() -> None:
    config = load_config(environ={"ATEMR_SECONDARY__BOOT_S": "1", "ATEMR_SECONDARY__ROBOT_NAME": "ROBBIE",
                                  "ATEMR_SECONDARY__PORTAL_PORT": "0"})
    channel = unique_channel("wiring")
    buses = [can.Bus(interface="virtual", channel=channel) for _ in range(2)]
    clock = SimClock()
    sched = Scheduler(clock)
    parts = emulated_secondary(config, buses[0], lambda: CliffReadings(clock.now(), 0.06, 0.06, 0.06))
    link = build_secondary_link(config, buses[1])
    try:
        assert isinstance(link.network, RecordingNetworkBackend) and isinstance(link.executor, InlineExecutor)
        assert [type(c) for c, _ in parts] == [SecondaryCore, PortalHost]
        for component, rate in parts:
            sched.add(component, rate)
        sched.add(link, 50.0)
        sched.start()
        core = parts[0][0]
        assert isinstance(core, SecondaryCore)
        sched.run(duration=0.5)
        assert "ATEMR - ROBBIE" in core.screen_text()
        sched.run(duration=0.7)
        assert core.state == "ready"
        core.button.hold(1.0)
        sched.run(duration=1.1)
        link.set_power_state(1)
        sched.run(duration=1.0)
        assert core.state == "ops" and link.heartbeat_ok and link.latest_cliff() is not None
    finally:
        sched.shutdown()
        for bus in buses:
            bus.shutdown()


def test_real_robot_uses_nmcli_in_a_worker_thread() -> None:
    config = load_config(environ={}, overrides={"simulation": False, "secondary.wifi_interface": "wlan0"})
    bus = can.Bus(interface="virtual", channel=unique_channel("wiring"))
    link = build_secondary_link(config, bus)
    try:
        assert isinstance(link.network, NmcliBackend) and link.network.ifname == "wlan0"
        assert not isinstance(link.executor, InlineExecutor)
    finally:
        link.shutdown()
        bus.shutdown()
