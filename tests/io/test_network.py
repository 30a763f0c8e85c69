"""NetworkBackend: credential rules, the recording fake, and NmcliBackend against a fake nmcli program."""

from __future__ import annotations

import socket
import stat
import subprocess
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from atemr.errors import HardwareError
from atemr.io.network import (
    NetworkBackend,
    NmcliBackend,
    RecordingNetworkBackend,
    credential_problems,
    usable_ipv4,
)


def fake_nmcli(tmp_path: Path, body: str) -> Path:
    """An executable shell script standing in for nmcli; it logs its arguments to args.txt."""
    script = tmp_path / "nmcli"
    script.write_text(f'#!/bin/sh\nprintf "%s\\n" "$@" > "{tmp_path}/args.txt"\n{body}\n')
    script.chmod(script.stat().st_mode | stat.S_IXUSR)
    return script


def test_both_backends_satisfy_the_protocol() -> None:
    assert isinstance(RecordingNetworkBackend(), NetworkBackend)
    assert isinstance(NmcliBackend(), NetworkBackend)


@pytest.mark.parametrize(
    ("ssid", "password", "ok"),
    [("Home", "12345678", True), ("H" * 32, "p" * 63, True), ("", "12345678", False), ("Home", "1234567", False),
     ("Home", "p" * 64, False), ("H" * 33, "12345678", False), ("Home\n", "12345678", False),
     ("Home", "pass\x7fword", False), ("\ud800", "12345678", False)],
)
def test_credential_rules(ssid: str, password: str, ok: bool) -> None:
    assert (credential_problems(ssid, password) == []) is ok


def test_nmcli_connect_runs_the_right_command(tmp_path: Path) -> None:
    nmcli = fake_nmcli(tmp_path, "echo 'Device wlan0 successfully activated'")
    NmcliBackend(nmcli=str(nmcli), ifname="wlan0", timeout_s=20).connect("Home net", "s3cret-pass")
    args = (tmp_path / "args.txt").read_text().splitlines()
    assert args == ["--wait", "20", "device", "wifi", "connect", "Home net", "password", "s3cret-pass",
                    "ifname", "wlan0"]


def test_nmcli_failure_is_a_hardware_error_without_the_password(tmp_path: Path) -> None:
    nmcli = fake_nmcli(tmp_path, "echo 'Error: Connection activation failed: s3cret-pass rejected' >&2; exit 4")
    with pytest.raises(HardwareError, match="exited with 4") as info:
        NmcliBackend(nmcli=str(nmcli)).connect("Home", "s3cret-pass")
    assert "s3cret-pass" not in str(info.value) and "activation failed" in str(info.value)
    assert info.value.component == "network"


def test_nmcli_missing(tmp_path: Path) -> None:
    with pytest.raises(HardwareError, match="not installed"):
        NmcliBackend(nmcli="definitely-not-nmcli-xyz").connect("Home", "s3cret-pass")


def test_nmcli_timeout() -> None:
    def runner(args: list[str], **kwargs: Any) -> subprocess.CompletedProcess[str]:
        raise subprocess.TimeoutExpired(args, kwargs["timeout"])

    backend = NmcliBackend(nmcli="/bin/true", timeout_s=3, runner=runner)
    with pytest.raises(HardwareError, match="did not answer within 8 s"):
        backend.connect("Home", "s3cret-pass")


def test_nmcli_refuses_invalid_credentials_before_running(tmp_path: Path) -> None:
    nmcli = fake_nmcli(tmp_path, "exit 0")
    with pytest.raises(HardwareError, match="at least 8"):
        NmcliBackend(nmcli=str(nmcli)).connect("Home", "short")
    assert not (tmp_path / "args.txt").exists()


def test_nmcli_bad_timeout() -> None:
    with pytest.raises(HardwareError, match="timeout"):
        NmcliBackend(timeout_s=0)


def test_ip_address_from_interfaces() -> None:
    def addr(family: int, address: str) -> SimpleNamespace:
        return SimpleNamespace(family=family, address=address)

    table = {
        "lo": [addr(socket.AF_INET, "127.0.0.1")],
        "wlan0": [addr(socket.AF_INET6, "fe80::1"), addr(socket.AF_INET, "192.168.1.20")],
        "eth0": [addr(socket.AF_INET, "169.254.3.3")],
    }
    backend = NmcliBackend()
    backend._addresses = lambda: table
    assert backend.ip_address() == "192.168.1.20"
    backend.ifname = "eth0"
    assert backend.ip_address() is None


def test_usable_ipv4() -> None:
    assert usable_ipv4("10.0.0.1") and not usable_ipv4("127.0.0.1") and not usable_ipv4("0.0.0.0")
    assert not usable_ipv4("nonsense") and not usable_ipv4("169.254.1.1")


def test_recording_backend_records_and_fails_on_demand() -> None:
    net = RecordingNetworkBackend(ip=None)
    net.connect("A", "12345678")
    net.fail_with = "Secrets were required"
    with pytest.raises(HardwareError, match="Secrets"):
        net.connect("B", "12345678")
    assert [(a.ssid, a.ok) for a in net.applied] == [("A", True), ("B", False)]
    assert net.ssid == "A" and net.ip_address() is None
