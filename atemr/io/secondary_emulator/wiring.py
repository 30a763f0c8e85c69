"""How the robot runs the emulated board: the components and their rates, from the configuration.

`atemr.robot.assembly` calls `emulated_secondary` in simulation; on the real robot the ESP32 is on the bus
instead and nothing here runs.
"""

from __future__ import annotations

from collections.abc import Callable

import can

from atemr.config import Config, SecondaryConfig
from atemr.io.secondary_emulator.board import BoardConfig, SecondaryCore
from atemr.io.secondary_emulator.portal import PortalHost
from atemr.msgs import CliffReadings
from atemr.scheduler import Component

#: Tick rates (Hz): the board polls its bus every 20 ms; the portal host only starts/stops a server.
BOARD_RATE_HZ = 50.0
PORTAL_RATE_HZ = 5.0


def board_config(cfg: SecondaryConfig) -> BoardConfig:
    """The board's settings from the ``secondary`` configuration section."""
    return BoardConfig(robot_name=cfg.robot_name, boot_s=cfg.boot_s)


def emulated_secondary(
    config: Config, bus: can.BusABC, cliff_source: Callable[[], CliffReadings | None] | None
) -> list[tuple[Component, float]]:
    """The emulated board (and its captive portal host, if served), each with its tick rate.

    ``bus`` is the board's own Bus instance on the robot's channel; ``cliff_source`` gives the simulator's
    latest cliff readings (e.g. ``lambda: sim.cliff_source.latest``).
    """
    core = SecondaryCore(bus, cliff_source=cliff_source, config=board_config(config.secondary))
    parts: list[tuple[Component, float]] = [(core, BOARD_RATE_HZ)]
    if config.secondary.portal_serve:
        host = PortalHost(core, host=config.secondary.portal_host, port=config.secondary.portal_port)
        parts.append((host, PORTAL_RATE_HZ))
    return parts
