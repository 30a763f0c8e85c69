"""The Agent view (beyond the thesis): the lifecycle machine and the current state's behaviour tree drawn
live with each node's status and tick count, the blackboard (every key, its value, who wrote it and when),
the last transitions with their reasons and the mission progress; and the replay of a recording
(MCAP, or an older ``.atrace`` trace).

Live data comes over Socket.IO (``agent_view`` subscription, ``agent`` pushes). Replay is a small JSON API
over the traces in ``data_dir/traces`` (the Media store's ``traces`` kind: names checked with
``secure_filename``/``safe_join``): the list, a trace's summary, the frame at a time (`TraceTimeline.frame`,
the same shape as the live snapshot plus the pose), and an upload that is read before it is stored.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Any, cast

from flask import Blueprint, abort, current_app, jsonify, render_template, request
from werkzeug.exceptions import HTTPException
from werkzeug.wrappers import Response

from atemr.errors import ConfigError
from atemr.fsm.trace_timeline import TraceTimeline
from atemr.io.recording.agent_trace import read_agent_trace
from atemr.ui.media.files import MediaError, MediaStore
from atemr.ui.security import role_required

bp = Blueprint("agent", __name__, template_folder="templates", static_folder="static",
               static_url_path="/static/agent")

#: Traces listed on the page (newest first).
LISTED = 200
#: Parsed traces kept in memory (a replay reads frames from one trace at a time).
CACHED = 4


class TimelineCache:
    """Parsed traces by (path, size, modification time): a trace is read once per change, not per frame."""

    def __init__(self, size: int = CACHED) -> None:
        self.size = size
        self._lock = threading.Lock()
        self._items: OrderedDict[tuple[str, int, int], TraceTimeline] = OrderedDict()

    def get(self, path: Path) -> TraceTimeline:
        stat = path.stat()
        key = (str(path), stat.st_size, stat.st_mtime_ns)
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
        contents = read_agent_trace(path)
        timeline = TraceTimeline(contents.records, name=path.name, warnings=contents.warnings)
        with self._lock:
            self._items[key] = timeline
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return timeline


@bp.errorhandler(HTTPException)
def _json_error(exc: HTTPException) -> tuple[Response, int]:
    """The replay API answers in JSON, refusals included (the page shows ``reason``)."""
    return jsonify({"ok": False, "reason": exc.description or exc.name}), exc.code or 500


def _store() -> MediaStore:
    return cast(MediaStore, current_app.extensions["atemr.media"])


def _timeline(name: str) -> TraceTimeline:
    try:
        path = _store().path("traces", name)
    except MediaError as exc:
        abort(404, description=str(exc))
    cache = current_app.extensions.setdefault("atemr.traces", TimelineCache())
    try:
        return cast(TimelineCache, cache).get(path)
    except (ConfigError, OSError) as exc:
        abort(422, description=f"{name} cannot be replayed: {exc}")


@bp.route("/agent")
@role_required("user")
def page() -> str:
    return render_template("agent/agent.html")


@bp.route("/api/traces")
@role_required("user")
def traces() -> Any:
    """The recorded traces, newest first: ``{"traces": [{name, size_bytes, modified}], "total"}``."""
    files, total = _store().newest("traces", 0, LISTED)
    return jsonify({"traces": [f.to_json() for f in files], "total": total})


@bp.route("/api/traces/<name>")
@role_required("user")
def summary(name: str) -> Any:
    """A trace's span, meta, machine, transitions and read warnings."""
    return jsonify(_timeline(name).summary())


@bp.route("/api/traces/<name>/frame")
@role_required("user")
def frame(name: str) -> Any:
    """``?t=SECONDS``: the agent as recorded at that robot time (clamped to the trace)."""
    try:
        t = float(request.args.get("t", "nan"))
    except ValueError:
        t = math.nan
    if not math.isfinite(t):
        abort(400, description="t (robot time in seconds) must be a finite number")
    return jsonify(_timeline(name).frame(t))


@bp.route("/api/traces", methods=["POST"])
@role_required("user")
def upload() -> tuple[Response, int]:
    """A recording (``.mcap``, or an older ``.atrace``; form field ``file``), read before it is stored; the CSRF
    token is required."""
    file = request.files.get("file")
    if file is None or not file.filename:
        return jsonify({"ok": False, "reason": "choose a .mcap recording to upload"}), 400
    try:
        name, contents = _store().upload_trace(file.filename, file.read())
    except MediaError as exc:
        return jsonify({"ok": False, "reason": str(exc)}), 400
    return jsonify({"ok": True, "reason": "", "name": name, "records": len(contents.records),
                    "warnings": contents.warnings}), 201
