"""Host health for the dashboard's 1 Hz CPU/memory/disk graph, sampled with psutil."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from pathlib import Path

import psutil


@dataclass(frozen=True)
class SystemSample:
    """One sample of the host's load, in percent."""

    t: float
    cpu_percent: float
    memory_percent: float
    disk_percent: float


class SystemMonitor:
    """A scheduler component that samples the host at its tick rate and keeps a short history."""

    name = "system_monitor"

    def __init__(self, disk_path: Path, history: int = 300) -> None:
        self.disk_path = disk_path
        self.history: deque[SystemSample] = deque(maxlen=history)

    def start(self) -> None:
        psutil.cpu_percent(interval=None)  # primes the counter: the first real call then has a baseline

    def tick(self, now: float) -> None:
        path = self.disk_path if self.disk_path.exists() else Path(self.disk_path.anchor or "/")
        self.history.append(
            SystemSample(
                t=now,
                cpu_percent=psutil.cpu_percent(interval=None),
                memory_percent=psutil.virtual_memory().percent,
                disk_percent=psutil.disk_usage(str(path)).percent,
            )
        )

    @property
    def latest(self) -> SystemSample | None:
        """The newest sample, or None before the first tick."""
        return self.history[-1] if self.history else None
