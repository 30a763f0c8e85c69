"""`ReloadWatcher`: notices edits of the agent document and the mission files and hands them to the agent.

A scheduler component (``reload_watcher``, 1 Hz) that polls the files' modification time and size; when
they change it reads the text, and only if the text changed validates it:

- invalid: a `ReloadReport` with status ``invalid`` and the error's line and column goes to the agent's
  reload log (`Agent.note_reload`); the running document or mission is untouched;
- valid: the unified diff against the running text, and the validated document goes to the agent
  (`Agent.request_reload`, applied in IDLE, deferred from any other state) or the mission to the agent
  (`Agent.request_mission_reload`, swapped into the running mission between steps).

`request` is the dashboard's explicit "reload" action: the next tick re-reads the agent document even
when its time stamp did not move. File I/O happens here, on the robot's thread; the agent only ever
receives validated documents.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path

from atemr.errors import ConfigError
from atemr.fsm.agent import Agent
from atemr.fsm.reload import ReloadKind, ReloadReport, unified_diff
from atemr.fsm.spec import parse_agent
from atemr.trees.missions import parse_mission
from atemr.yamlsafe import load_yaml

log = logging.getLogger(__name__)

#: How often the files are polled (robot time).
RATE_HZ = 1.0


class ReloadWatcher:
    """Polls ``agent_file`` and ``missions_dir/*.yaml`` and feeds validated edits to ``agent``."""

    name = "reload_watcher"

    def __init__(self, agent: Agent, agent_file: Path, missions_dir: Path | None = None) -> None:
        self.agent = agent
        self.agent_file = Path(agent_file)
        self.missions_dir = missions_dir if missions_dir is not None else self.agent_file.parent / "missions"
        self._lock = threading.Lock()
        self._forced = False
        #: The running (last valid) text of each file, and the stamp of what was last looked at.
        self._texts: dict[Path, str] = {}
        self._stamps: dict[Path, tuple[int, int]] = {}
        for path in self._files():
            stamp, text = self._stamp(path), self._read(path)
            if stamp is not None and text is not None:
                self._stamps[path], self._texts[path] = stamp, text

    def request(self) -> None:
        """Re-read the agent document at the next tick, changed or not (thread-safe)."""
        with self._lock:
            self._forced = True

    def tick(self, now: float) -> None:
        with self._lock:
            forced, self._forced = self._forced, False
        self.poll(now, forced=forced)

    def poll(self, now: float, *, forced: bool = False) -> list[ReloadReport]:
        """Look at every file once; returns the reports of what changed."""
        reports = []
        for path in self._files():
            stamp = self._stamp(path)
            force = forced and path == self.agent_file
            if stamp is None or (stamp == self._stamps.get(path) and not force):
                continue
            self._stamps[path] = stamp
            report = self._changed(path, now, force)
            if report is not None:
                reports.append(report)
        return reports

    # -- internals ---------------------------------------------------------------------------------
    def _files(self) -> list[Path]:
        missions = sorted(self.missions_dir.glob("*.yaml")) if self.missions_dir.is_dir() else []
        return [self.agent_file, *missions]

    @staticmethod
    def _stamp(path: Path) -> tuple[int, int] | None:
        try:
            st = path.stat()
        except OSError:
            return None
        return st.st_mtime_ns, st.st_size

    @staticmethod
    def _read(path: Path) -> str | None:
        try:
            return path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            return None

    def _changed(self, path: Path, now: float, forced: bool) -> ReloadReport | None:
        kind: ReloadKind = "agent" if path == self.agent_file else "mission"
        origin = "reload action" if forced else "file watcher"
        text = self._read(path)
        old = self._texts.get(path, "")
        if text is None:
            report = ReloadReport(kind, str(path), now, "invalid", f"{path} cannot be read as UTF-8 text", "",
                                  origin, {"message": "cannot be read as UTF-8 text", "line": None,
                                           "column": None, "path": "", "text": str(path)})
            self.agent.note_reload(report)
            return report
        if text == old:
            if not forced:
                return None
            report = ReloadReport(kind, str(path), now, "unchanged", "the file is the running version", "", origin)
            self.agent.note_reload(report)
            return report
        diff = unified_diff(old, text, path.name)
        try:
            document = load_yaml(str(path), text=text)
            if kind == "agent":
                spec = parse_agent(document, str(path))
            else:
                mission = parse_mission(document, str(path))
        except ConfigError as exc:
            report = ReloadReport.invalid(kind, str(path), now, exc, diff=diff, origin=origin)
            log.warning("%s not reloaded: %s", path, exc)
            self.agent.note_reload(report)
            return report
        self._texts[path] = text
        report = ReloadReport(kind, str(path), now, diff=diff, origin=origin)
        if kind == "agent":
            self.agent.request_reload(spec, report)
        else:
            self.agent.request_mission_reload(mission, report)
        return report


__all__ = ["RATE_HZ", "ReloadWatcher"]
