"""`LinkPort` over the real `atemr.io.secondary_link.SecondaryLink` (the primary's end of the CAN link).

The link itself sends the 0x157 heartbeat every 0.5 s, and re-sends 0x153 and 0x150 at 2 Hz and at once
on change; the agent only sets what they carry and reads what came back. Wire it as
``Agent(spec, robot_port, SecondaryLinkPort(link))``.
"""

from __future__ import annotations

from atemr.domain.status import PowerState
from atemr.io.can import PrimaryStatus
from atemr.io.secondary_link import SecondaryLink


class SecondaryLinkPort:
    """The agent's `LinkPort` backed by a `SecondaryLink` ticked by the same scheduler."""

    def __init__(self, link: SecondaryLink) -> None:
        self.link = link

    def publish_status(self, status: PrimaryStatus) -> None:
        self.link.set_status(status.agent, status.hardware, status.state)

    def set_power_state(self, state: PowerState) -> None:
        self.link.set_power_state(state)

    def power_off_requested(self) -> bool:
        return bool(self.link.power_off_requested)

    def heartbeat_ok(self) -> bool:
        return bool(self.link.heartbeat_ok)
