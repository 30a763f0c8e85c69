"""Settings an operator changes at run time (speed limits, awareness), kept across restarts.

They live in ``<data_dir>/settings.yaml``, written atomically (temporary file + rename) so a crash
never leaves half a file, and read back at start-up on top of the configuration. A corrupt file is
reported and ignored: the robot starts on its configured values rather than not at all.
"""

from __future__ import annotations

import logging
import os
import tempfile
from pathlib import Path
from typing import Any

import yaml

from atemr.errors import ConfigError
from atemr.yamlsafe import load_yaml

log = logging.getLogger(__name__)


class SettingsStore:
    """A small YAML mapping of run-time settings under ``data_dir``."""

    def __init__(self, data_dir: Path) -> None:
        self.path = data_dir / "settings.yaml"

    def load(self) -> dict[str, Any]:
        """The stored settings, or {} when there are none or the file is unreadable (logged)."""
        if not self.path.exists():
            return {}
        try:
            document = load_yaml(self.path)
        except ConfigError as exc:
            log.error("ignoring stored settings: %s", exc)
            return {}
        if not isinstance(document, dict):
            log.error("ignoring stored settings: %s is not a mapping", self.path)
            return {}
        return {str(k): _plain(v) for k, v in document.items()}

    def update(self, section: str, values: dict[str, Any]) -> None:
        """Merge ``values`` into ``section`` and write the file atomically."""
        current = self.load()
        merged = dict(current.get(section) or {})
        merged.update(values)
        current[section] = merged
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".settings-", suffix=".yaml", dir=self.path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                yaml.safe_dump(current, fh, sort_keys=True)
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value
