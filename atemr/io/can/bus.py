"""Open the robot's CAN bus from configuration: one place that knows which interfaces exist.

Like python-can's own ``BACKENDS`` table, bus kinds live in a registry (``atemr.can_buses`` entry
points add more): ``virtual`` (the default: in-process, one channel name per robot so tests never
share one), ``socketcan`` (the real robot, ``can0``; the bit rate is set on the interface with
``ip link set can0 type can bitrate 1000000``), and any other python-can interface by its name.
Every participant (primary side, each motor emulator, the secondary core, a recorder) opens its own
Bus instance on the same channel; ``virtual`` is this project's python-can interface
`atemr.io.can.inprocess.InProcessBus`, which delivers between them without copying frames and shares
python-can's virtual channels (a python-can ``virtual`` bus on the same channel hears the robot).
"""

from __future__ import annotations

import difflib
import itertools
from collections.abc import Callable
from typing import Any

import can

from atemr.config import CanConfig
from atemr.errors import BusError, ConfigError
from atemr.io.can.inprocess import InProcessBus
from atemr.registry import Registry

BusOpener = Callable[[CanConfig], can.BusABC]
#: Bus kinds by name; an interface not registered here is passed to python-can as is.
bus_kinds: Registry[BusOpener] = Registry("can_buses")

_channel_counter = itertools.count(1)


def unique_channel(prefix: str = "atemr") -> str:
    """A virtual channel name no other robot in this process uses (``atemr-1``, ``atemr-2``, ...)."""
    return f"{prefix}-{next(_channel_counter)}"


def _python_can(interface: str, channel: str, **kwargs: Any) -> can.BusABC:
    try:
        return can.Bus(interface=interface, channel=channel, **kwargs)
    except (can.CanError, OSError, ImportError, ValueError, TypeError) as exc:
        raise BusError(f"cannot open {interface} bus on channel {channel!r}: {exc}", component="can",
                       critical=True) from exc


@bus_kinds.register("virtual")
def open_virtual(config: CanConfig) -> can.BusABC:
    """The in-process bus of the simulation: every Bus on the same channel sees the others' frames."""
    return InProcessBus(config.channel, bitrate=config.bitrate)


@bus_kinds.register("socketcan")
def open_socketcan(config: CanConfig) -> can.BusABC:
    """Linux SocketCAN (the robot: ``can0`` at 1 Mbit/s, configured with ``ip link``)."""
    return _python_can("socketcan", config.channel)


def open_bus(config: CanConfig) -> can.BusABC:
    """A new Bus instance on the configured interface and channel.

    An interface neither registered nor known to python-can is a `ConfigError` with the closest names;
    a bus that cannot be opened is a critical `BusError`.
    """
    name = config.interface
    if name in bus_kinds:
        return bus_kinds.get(name)(config)
    known = sorted(set(can.interfaces.VALID_INTERFACES) | set(bus_kinds))
    if name not in can.interfaces.VALID_INTERFACES:
        close = difflib.get_close_matches(name, known, n=3, cutoff=0.5)
        hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
        raise ConfigError(f"unknown CAN interface {name!r}{hint}; known: {', '.join(known)}", path="can.interface")
    return _python_can(name, config.channel, bitrate=config.bitrate)
