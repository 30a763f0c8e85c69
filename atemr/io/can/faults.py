"""A fault-injection bus: wraps any python-can bus and damages traffic on a seeded schedule.

For reliability tests: the robot must stop safely when frames are dropped, late, doubled, swapped or
corrupted, or the link is down for a while, and recover when the link recovers. Every decision comes
from ``random.Random(seed)``, one draw sequence per direction, and delays and outages are measured on
an injected clock, so a run is exactly repeatable.

Faults apply to frames this wrapper sends (``direction="send"``), receives (``"recv"``) or both. A
delayed or reordered frame is held and released by a later `send`/`recv` call once it is due.
"""

from __future__ import annotations

import math
import random
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import can

from atemr.clock import Clock
from atemr.errors import ConfigError

Direction = Literal["send", "recv", "both"]


@dataclass(frozen=True)
class FaultPlan:
    """Probabilities per frame (0–1) of each fault, and the windows ``[start, end)`` the link is down."""

    drop: float = 0.0
    duplicate: float = 0.0
    delay: float = 0.0
    delay_s: float = 0.05
    reorder: float = 0.0
    corrupt: float = 0.0
    outages: Sequence[tuple[float, float]] = field(default_factory=tuple)
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("drop", "duplicate", "delay", "reorder", "corrupt"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0.0 <= value <= 1.0):
                raise ConfigError(f"fault probability {name} must be within 0..1, got {value!r}", path=f"faults.{name}")
        if not (math.isfinite(self.delay_s) and self.delay_s >= 0):
            raise ConfigError(f"delay_s must be >= 0, got {self.delay_s!r}", path="faults.delay_s")
        for start, end in self.outages:
            if not end > start:
                raise ConfigError(f"outage window ({start}, {end}) must end after it starts", path="faults.outages")


@dataclass
class FaultStats:
    """How many frames each fault hit."""

    passed: int = 0
    dropped: int = 0
    duplicated: int = 0
    delayed: int = 0
    reordered: int = 0
    corrupted: int = 0
    outage_dropped: int = 0


class _Pipe:
    """One direction's fault machinery: decides, holds delayed/reordered frames, releases them."""

    def __init__(self, plan: FaultPlan, rng: random.Random, stats: FaultStats) -> None:
        self.plan = plan
        self.rng = rng
        self.stats = stats
        self.delayed: list[tuple[float, int, can.Message]] = []
        self.held: can.Message | None = None
        self.held_until = 0.0
        self._order = 0

    def push(self, msg: can.Message, now: float, link_up: bool) -> list[can.Message]:
        """Frames to deliver now because ``msg`` was offered at ``now`` (maybe none, maybe several)."""
        plan, rng = self.plan, self.rng
        if not link_up or any(start <= now < end for start, end in plan.outages):
            self.stats.outage_dropped += 1
            return self.release(now)
        # draw every decision each time so the schedule does not depend on earlier outcomes
        r_drop, r_dup, r_delay, r_reorder, r_corrupt = (rng.random() for _ in range(5))
        if r_drop < plan.drop:
            self.stats.dropped += 1
            return self.release(now)
        if r_corrupt < plan.corrupt:
            msg = self._corrupt(msg)
            self.stats.corrupted += 1
        out = [msg]
        if r_dup < plan.duplicate:
            self.stats.duplicated += 1
            out.append(_copy(msg))
        if r_delay < plan.delay:
            self.stats.delayed += 1
            for m in out:
                self._order += 1
                self.delayed.append((now + plan.delay_s, self._order, m))
            return self.release(now)
        if r_reorder < plan.reorder and self.held is None:
            self.stats.reordered += 1
            self.held, out = out[0], out[1:]
            self.held_until = now + plan.delay_s  # released by then even if no frame follows
            return self.release(now) + out
        self.stats.passed += 1
        ready = self.release(now)
        if self.held is not None:  # the held frame goes after this one: the pair is swapped
            out.append(self.held)
            self.held = None
        return ready + out

    def release(self, now: float) -> list[can.Message]:
        """Delayed frames that are due at ``now``, in the order they were delayed."""
        if self.held is not None and now >= self.held_until:
            self.delayed.append((self.held_until, -1, self.held))
            self.held = None
        if not self.delayed:
            return []
        self.delayed.sort(key=lambda item: (item[0], item[1]))
        due = [m for t, _, m in self.delayed if t <= now]
        self.delayed = [item for item in self.delayed if item[0] > now]
        return due

    def _corrupt(self, msg: can.Message) -> can.Message:
        data = bytearray(msg.data or b"")
        if data:
            bit = self.rng.randrange(len(data) * 8)
            data[bit // 8] ^= 1 << (bit % 8)
        else:
            data.append(self.rng.randrange(256))
        out = _copy(msg)
        out.data = data
        out.dlc = len(data)
        return out


def _copy(msg: can.Message) -> can.Message:
    return can.Message(timestamp=msg.timestamp, arbitration_id=msg.arbitration_id, is_extended_id=msg.is_extended_id,
                       is_remote_frame=msg.is_remote_frame, is_error_frame=msg.is_error_frame, channel=msg.channel,
                       dlc=msg.dlc, data=bytes(msg.data or b""), is_fd=msg.is_fd, check=False)


class FaultInjectionBus(can.BusABC):
    """``inner`` with faults from ``plan``; ``clock`` times delays and outages. Closing it closes ``inner``.

    ``link_up`` can be switched off and on by a test to cut the link by hand.
    """

    def __init__(self, inner: can.BusABC, plan: FaultPlan, clock: Clock, *, direction: Direction = "both") -> None:
        if direction not in ("send", "recv", "both"):
            raise ConfigError(f"direction must be send, recv or both, got {direction!r}", path="faults.direction")
        self.inner = inner
        self.plan = plan
        self.clock = clock
        self.direction = direction
        self.link_up = True
        self.stats = {"send": FaultStats(), "recv": FaultStats()}
        self._pipes: dict[str, _Pipe] = {
            "send": _Pipe(plan, random.Random(f"{plan.seed}:send"), self.stats["send"]),
            "recv": _Pipe(plan, random.Random(f"{plan.seed}:recv"), self.stats["recv"]),
        }
        self._inbox: deque[can.Message] = deque()
        self.channel_info = f"faults({inner.channel_info})"
        super().__init__(channel=self.channel_info)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        now = self.clock.now()
        faulty = self.direction in ("send", "both")
        for frame in self._pipes["send"].push(msg, now, self.link_up) if faulty else [msg]:
            self.inner.send(frame, timeout)

    def flush_due(self) -> None:
        """Send delayed frames that are due now (also done by every `send` and `recv`)."""
        for frame in self._pipes["send"].release(self.clock.now()):
            self.inner.send(frame)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        now = self.clock.now()
        self.flush_due()
        if self.direction in ("recv", "both"):
            self._inbox.extend(self._pipes["recv"].release(now))
            while not self._inbox:
                msg = self.inner.recv(timeout=0 if self._inbox or timeout == 0 else timeout)
                if msg is None:
                    break
                self._inbox.extend(self._pipes["recv"].push(msg, now, self.link_up))
        elif not self._inbox:
            msg = self.inner.recv(timeout=timeout)
            if msg is not None:
                self._inbox.append(msg)
        return (self._inbox.popleft() if self._inbox else None), False

    @property
    def state(self) -> can.BusState:
        return self.inner.state

    @state.setter
    def state(self, new_state: can.BusState) -> None:
        self.inner.state = new_state

    def shutdown(self) -> None:
        super().shutdown()
        self.inner.shutdown()
