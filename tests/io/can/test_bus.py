"""The bus factory: virtual by default, socketcan and any python-can interface by name, clear errors."""

from __future__ import annotations

import can
import pytest

from atemr.config import CanConfig
from atemr.errors import BusError, ConfigError
from atemr.io.can.bus import bus_kinds, open_bus, unique_channel


def test_virtual_buses_on_one_channel_see_each_other() -> None:
    config = CanConfig(channel=unique_channel("test-bus"))
    with open_bus(config) as a, open_bus(config) as b, open_bus(CanConfig(channel=unique_channel("other"))) as c:
        a.send(can.Message(arbitration_id=0x157, data=b"\x01", is_extended_id=False))
        got = b.recv(timeout=0)
        assert got is not None and got.arbitration_id == 0x157
        assert c.recv(timeout=0) is None
        assert a.recv(timeout=0) is None  # no echo of own frames


def test_unique_channels_differ() -> None:
    assert unique_channel() != unique_channel()


def test_unknown_interface_names_the_closest() -> None:
    with pytest.raises(ConfigError, match=r"unknown CAN interface 'socketcann' \(did you mean 'socketcan'"):
        open_bus(CanConfig(interface="socketcann"))


def test_a_bus_that_cannot_open_is_a_critical_bus_error() -> None:
    with pytest.raises(BusError) as info:
        open_bus(CanConfig(interface="socketcan", channel="atemr-no-such-can-device"))
    assert info.value.critical and "atemr-no-such-can-device" in str(info.value)


def test_other_python_can_interfaces_by_name() -> None:
    # udp_multicast would open sockets; 'serial' with a missing port fails cleanly as a BusError
    with pytest.raises(BusError, match="serial"):
        open_bus(CanConfig(interface="serial", channel="/dev/atemr-no-such-port"))


@pytest.mark.parametrize("kind", list(bus_kinds))
def test_every_registered_kind_is_callable(kind: str) -> None:
    assert callable(bus_kinds.get(kind))
