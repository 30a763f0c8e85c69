"""How the robot joins a WiFi network: NetworkManager's ``nmcli`` on the robot, a recording fake in simulation.

The secondary core's captive portal sends an SSID and a password over CAN (0x154/0x155); the primary's
`atemr.io.secondary_link.SecondaryLink` hands them to a `NetworkBackend`. Joining a network can take tens
of seconds, so the link calls `NetworkBackend.connect` off the control loop (see the link's ``executor``);
a backend may block, and reports failure by raising `HardwareError` with a message an operator can act on.
"""

from __future__ import annotations

import ipaddress
import logging
import shutil
import socket
import subprocess
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import psutil

from atemr.errors import HardwareError
from atemr.io.can.segmented import PASSWORD, SSID

log = logging.getLogger(__name__)

#: Bytes allowed in an SSID (IEEE 802.11) and in a WPA2 passphrase: the limits the CAN transfer enforces.
SSID_BYTES = (SSID.min_bytes, SSID.max_bytes)
PASSWORD_BYTES = (PASSWORD.min_bytes, PASSWORD.max_bytes)


def credential_problems(ssid: str, password: str) -> list[str]:
    """What is wrong with these credentials, in words for a person; empty when they can be sent.

    Lengths are counted in UTF-8 bytes because that is what travels on the bus and what WPA2 limits.
    """
    problems: list[str] = []
    ssid_len = len(ssid.encode("utf-8", errors="surrogatepass"))
    pass_len = len(password.encode("utf-8", errors="surrogatepass"))
    if not ssid.strip():
        problems.append("the network name (SSID) is empty")
    elif ssid_len > SSID_BYTES[1]:
        problems.append(f"the network name (SSID) is {ssid_len} bytes long; at most {SSID_BYTES[1]} are allowed")
    if pass_len < PASSWORD_BYTES[0]:
        problems.append(f"the password is {pass_len} bytes long; at least {PASSWORD_BYTES[0]} are needed")
    elif pass_len > PASSWORD_BYTES[1]:
        problems.append(f"the password is {pass_len} bytes long; at most {PASSWORD_BYTES[1]} are allowed")
    for what, text in (("network name (SSID)", ssid), ("password", password)):
        if any(ord(c) < 0x20 or ord(c) == 0x7F for c in text):
            problems.append(f"the {what} contains control characters")
        if any(0xD800 <= ord(c) <= 0xDFFF for c in text):
            problems.append(f"the {what} is not valid text")
    return problems


@runtime_checkable
class NetworkBackend(Protocol):
    """Joins WiFi networks and tells the robot's current IPv4 address."""

    #: The network last joined through this backend (from the dashboard or the captive portal), None before.
    ssid: str | None

    def connect(self, ssid: str, password: str) -> None:
        """Join ``ssid``; may block for as long as joining takes. Raises `HardwareError` on failure."""
        ...

    def ip_address(self) -> str | None:
        """The robot's current IPv4 address (dotted quad), or None when it has none. Must not block."""
        ...


@dataclass(frozen=True)
class AppliedNetwork:
    """One call to `RecordingNetworkBackend.connect`: what was asked and whether it worked."""

    ssid: str
    password: str
    ok: bool
    error: str | None = None


class RecordingNetworkBackend:
    """The simulation's network: records every request, answers a fixed address, fails when told to.

    ``fail_with`` makes the next `connect` calls raise `HardwareError` with that message (as a wrong
    password does on the robot) until it is set back to None.
    """

    def __init__(self, ip: str | None = "192.168.1.42", *, fail_with: str | None = None) -> None:
        if ip is not None:
            ipaddress.IPv4Address(ip)
        self.ip = ip
        self.fail_with = fail_with
        self.applied: list[AppliedNetwork] = []
        self.ssid: str | None = None

    def connect(self, ssid: str, password: str) -> None:
        if self.fail_with is not None:
            self.applied.append(AppliedNetwork(ssid, password, ok=False, error=self.fail_with))
            raise HardwareError(self.fail_with, component="network")
        self.applied.append(AppliedNetwork(ssid, password, ok=True))
        self.ssid = ssid

    def ip_address(self) -> str | None:
        return self.ip


Runner = Callable[..., "subprocess.CompletedProcess[str]"]


class NmcliBackend:
    """NetworkManager on the robot, through its command line client ``nmcli``.

    Every call has a timeout, and every failure (nmcli missing, timed out, refused) becomes a
    `HardwareError` naming what happened, with nmcli's own message. ``runner`` is `subprocess.run` unless a
    test replaces it; ``ifname`` pins the WiFi interface (default: NetworkManager chooses).
    """

    def __init__(
        self,
        *,
        nmcli: str = "nmcli",
        ifname: str | None = None,
        timeout_s: float = 45.0,
        runner: Runner | None = None,
    ) -> None:
        if timeout_s <= 0:
            raise HardwareError(f"timeout must be > 0 s, got {timeout_s}", component="network")
        self.nmcli = nmcli
        self.ifname = ifname
        self.timeout_s = timeout_s
        self._run: Runner = runner or subprocess.run
        self._addresses: Callable[[], dict[str, list[Any]]] = psutil.net_if_addrs
        self.ssid: str | None = None

    def _call(self, args: Sequence[str], *, what: str, timeout_s: float, secret: str | None = None) -> str:
        exe = shutil.which(self.nmcli) if "/" not in self.nmcli else self.nmcli
        if exe is None:
            raise HardwareError(
                f"cannot {what}: '{self.nmcli}' is not installed (install NetworkManager, or run in simulation)",
                component="network",
            )
        shown = " ".join("******" if secret is not None and a == secret else a for a in args)
        log.debug("running %s %s", exe, shown)
        try:
            done = self._run(
                [exe, *args], capture_output=True, text=True, timeout=timeout_s, check=False, stdin=subprocess.DEVNULL
            )
        except subprocess.TimeoutExpired as exc:
            raise HardwareError(
                f"cannot {what}: nmcli did not answer within {timeout_s:g} s", component="network"
            ) from exc
        except OSError as exc:
            raise HardwareError(f"cannot {what}: cannot run {exe}: {exc}", component="network") from exc
        if done.returncode != 0:
            message = (done.stderr or done.stdout or "").strip().replace(secret or "\0", "******")
            raise HardwareError(
                f"cannot {what}: nmcli exited with {done.returncode}: {message or 'no message'}", component="network"
            )
        return str(done.stdout)

    def connect(self, ssid: str, password: str) -> None:
        problems = credential_problems(ssid, password)
        if problems:
            raise HardwareError(f"cannot join '{ssid}': {'; '.join(problems)}", component="network")
        args = ["--wait", str(int(self.timeout_s)), "device", "wifi", "connect", ssid, "password", password]
        if self.ifname:
            args += ["ifname", self.ifname]
        self._call(args, what=f"join '{ssid}'", timeout_s=self.timeout_s + 5.0, secret=password)
        self.ssid = ssid
        log.info("joined WiFi network '%s'", ssid)

    def ip_address(self) -> str | None:
        """Read from the kernel's interface table (psutil), not from nmcli, so it never blocks the loop."""
        addrs = self._addresses()
        names = [self.ifname] if self.ifname else sorted(addrs)
        for name in names:
            for addr in addrs.get(name, []):
                if addr.family == socket.AF_INET and usable_ipv4(addr.address):
                    return str(addr.address)
        return None


def usable_ipv4(text: str) -> bool:
    """Whether ``text`` is an IPv4 address someone else could reach the robot at (not loopback, link-local)."""
    try:
        ip = ipaddress.IPv4Address(text)
    except ValueError:
        return False
    return not (ip.is_loopback or ip.is_link_local or ip.is_unspecified)
