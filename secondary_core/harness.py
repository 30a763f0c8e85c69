"""A bench with both ends of the inter-core link on one virtual CAN bus and a simulated clock.

`LinkBench` wires a `SecondaryCore` (the emulated board) and the primary's `SecondaryLink` on a fresh
virtual channel, ticked at 50 Hz by one `Scheduler` on a `SimClock`, plus a ``spy`` bus that sees every
frame. Tests, the CLI's self-check and other parts' integration tests use it to drive whole handshakes
in simulated time.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable
from types import TracebackType
from typing import Any

import can

from atemr.clock import SimClock
from atemr.domain.status import PowerState
from atemr.io.network import RecordingNetworkBackend
from atemr.io.secondary_emulator.board import BoardConfig, SecondaryCore
from atemr.io.secondary_link import SecondaryLink
from atemr.msgs import CliffReadings
from atemr.scheduler import Scheduler

_counter = itertools.count()

#: Tick rate of both ends in the bench (Hz).
RATE_HZ = 50.0


def unique_channel(prefix: str = "atemr-bench") -> str:
    """A virtual channel name no other bench or test in this process uses."""
    return f"{prefix}-{os.getpid()}-{next(_counter)}"


class _Gate:
    """Ticks a component unless paused: a hung process, or a core unplugged from the bus."""

    def __init__(self, component: SecondaryCore | SecondaryLink) -> None:
        self.component = component
        self.name = component.name
        self.paused = False

    def tick(self, now: float) -> None:
        if not self.paused:
            self.component.tick(now)


class _Spy:
    """Drains the spy bus each tick, stamping frames with the simulated time they were seen."""

    name = "bench_spy"

    def __init__(self, bus: can.BusABC, frames: list[tuple[float, can.Message]]) -> None:
        self.bus = bus
        self.frames = frames

    def tick(self, now: float) -> None:
        while (msg := self.bus.recv(timeout=0)) is not None:
            self.frames.append((now, msg))


class LinkBench:
    """Board + primary link + spy on one virtual bus; ``board_bus``/``link_bus`` may wrap the raw buses.

    ``wrap_board_bus(bus, clock)`` lets a test put a fault-injecting wrapper between the board and the bus.
    """

    def __init__(
        self,
        *,
        channel: str | None = None,
        config: BoardConfig | None = None,
        cliff: CliffReadings | None = None,
        network: RecordingNetworkBackend | None = None,
        wrap_board_bus: Callable[[can.BusABC, SimClock], Any] | None = None,
        link_kwargs: dict[str, Any] | None = None,
    ) -> None:
        self.channel = channel or unique_channel()
        self.clock = SimClock()
        self._buses = [can.Bus(interface="virtual", channel=self.channel) for _ in range(3)]
        raw_board, self.link_bus, self.spy = self._buses
        self.board_bus = wrap_board_bus(raw_board, self.clock) if wrap_board_bus else raw_board
        self.cliff = cliff
        self.network = network or RecordingNetworkBackend()
        self.core = SecondaryCore(self.board_bus, cliff_source=lambda: self.cliff, config=config)
        self.link = SecondaryLink(self.link_bus, self.network, **(link_kwargs or {}))
        self.scheduler = Scheduler(self.clock)
        self.gates = {"core": _Gate(self.core), "link": _Gate(self.link)}
        self.scheduler.add(self.gates["core"], RATE_HZ)
        self.scheduler.add(self.gates["link"], RATE_HZ)
        self.frames: list[tuple[float, can.Message]] = []
        self.scheduler.add(_Spy(self.spy, self.frames), RATE_HZ)  # added last: sees each tick's frames

    @property
    def now(self) -> float:
        return self.clock.now()

    def run(self, seconds: float) -> None:
        """Advance both ends by ``seconds`` of simulated time, recording what the spy saw (with sim time)."""
        self.scheduler.run(duration=seconds)

    def run_until(self, condition: Callable[[], bool], *, timeout_s: float, step_s: float = 0.02) -> float:
        """Run until ``condition()`` holds; returns the simulated time it took. Raises TimeoutError after
        ``timeout_s`` of simulated time."""
        start = self.now
        while not condition():
            if self.now - start > timeout_s:
                raise TimeoutError(f"condition not met within {timeout_s} s of simulated time")
            self.run(step_s)
        return self.now - start

    def pause(self, which: str) -> None:
        """Stop ticking ``"core"`` (the board) or ``"link"`` (the primary) until `resume`."""
        self.gates[which].paused = True

    def resume(self, which: str) -> None:
        self.gates[which].paused = False

    def frames_with_id(self, arbitration_id: int, *, since: float = float("-inf")) -> list[tuple[float, can.Message]]:
        return [(t, m) for t, m in self.frames if m.arbitration_id == arbitration_id and t >= since]

    def bring_up(self) -> None:
        """Boot the board, power the primary on with a 1 s hold and report it running: the board is in OPS."""
        self.run(self.core.config.boot_s + 0.1)
        self.core.button.hold(1.0)
        self.run(1.1)
        self.link.set_power_state(PowerState.RUNNING)
        self.run(0.5)

    def close(self) -> None:
        if self.board_bus is not self._buses[0] and hasattr(self.board_bus, "shutdown"):
            self.board_bus.shutdown()  # a wrapper (fault injection) closes its inner bus too
        for bus in self._buses:
            bus.shutdown()

    def __enter__(self) -> LinkBench:
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.close()
