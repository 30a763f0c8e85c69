"""The robot's routines on disk: ``<data_dir>/routines.yaml`` (edited on the Routines page or by hand) and the
runs they made, ``<data_dir>/routines-history.jsonl`` (one JSON object a line, newest last).

The YAML is checked whole (`atemr.domain.routines.RoutineBook.from_document`) before it is used, and written
atomically, so a half-written or broken file never replaces the routines in force: the robot keeps the ones
it had and reports why the file was refused.

    timezone: Europe/Berlin
    routines:
      - {name: check-on-resident, mission: kitchen-check, at: "09:00", days: [mon, tue, wed, thu, fri]}
      - {name: night patrol, mission: living-room-patrol, every_min: 30, from: "21:00", to: "23:00"}
"""

from __future__ import annotations

import json
from collections import deque
from pathlib import Path
from typing import Any

import yaml

from atemr.domain.routines import RoutineBook
from atemr.errors import ConfigError
from atemr.yamlsafe import load_yaml

#: History lines read back at most (the page shows the newest).
HISTORY_KEPT = 200


class RoutineStore:
    """``routines.yaml`` and ``routines-history.jsonl`` in ``data_dir``."""

    def __init__(self, data_dir: str | Path) -> None:
        self.dir = Path(data_dir)
        self.file = self.dir / "routines.yaml"
        self.history_file = self.dir / "routines-history.jsonl"

    def stamp(self) -> int:
        """Changes whenever the file does (-1: no file)."""
        try:
            return self.file.stat().st_mtime_ns
        except OSError:
            return -1

    def load(self) -> RoutineBook:
        """The routines (none without a file); `ConfigError` naming the file and the item at fault."""
        if not self.file.is_file():
            return RoutineBook()
        doc = load_yaml(self.file)
        try:
            return RoutineBook.from_document(doc)
        except ConfigError as exc:
            raise ConfigError(exc.reason, file=str(self.file), path=exc.path) from None

    def save(self, book: RoutineBook) -> None:
        """Write ``book`` atomically (a reader sees the old file or the new one)."""
        self.dir.mkdir(parents=True, exist_ok=True)
        text = "# The robot's care routines (atemr): edit here or on the dashboard's Routines page.\n"
        text += yaml.safe_dump(book.to_document(), sort_keys=False, allow_unicode=True)
        tmp = self.file.with_name(self.file.name + ".tmp")
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(self.file)

    def append_run(self, run: dict[str, Any]) -> None:
        """Add one run to the history (best effort: a full disk loses the line, not the robot)."""
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            with self.history_file.open("a", encoding="utf-8") as f:
                f.write(json.dumps(run, sort_keys=True) + "\n")
        except OSError:
            pass

    def history(self) -> list[dict[str, Any]]:
        """The newest `HISTORY_KEPT` runs, oldest first (unreadable lines skipped)."""
        try:
            with self.history_file.open(encoding="utf-8") as f:
                lines = deque(f, maxlen=HISTORY_KEPT)
        except OSError:
            return []
        out = []
        for line in lines:
            try:
                item = json.loads(line)
            except ValueError:
                continue
            if isinstance(item, dict):
                out.append(item)
        return out


__all__ = ["HISTORY_KEPT", "RoutineStore"]
