"""Media: captured images, recorded videos and maps — list (ten newest, more on request), download,
delete one or all. HTML page plus a small JSON API the page uses for "more"."""

from __future__ import annotations

from typing import Any, cast

from flask import Blueprint, abort, current_app, flash, jsonify, redirect, render_template, request, send_file, url_for
from werkzeug.wrappers import Response

from atemr.ui.gateway import RobotGateway
from atemr.ui.media.files import KINDS, PAGE_SIZE, MediaError, MediaStore
from atemr.ui.security import permission_required, role_required

bp = Blueprint("media", __name__, template_folder="templates")


def _store() -> MediaStore:
    return cast(MediaStore, current_app.extensions["atemr.media"])


def _maps_changed(kind: str) -> None:
    robot = cast("RobotGateway | None", current_app.extensions["atemr.gateway"])
    if kind == "maps" and robot is not None:
        robot.maps_changed()


@bp.route("/media")
@role_required("user")
def page() -> str:
    lists = {kind: _store().newest(kind) for kind in KINDS}
    return render_template("media/media.html", lists=lists, page_size=PAGE_SIZE)


@bp.route("/api/media/<kind>")
@role_required("user")
def listing(kind: str) -> Any:
    """``?offset=N&limit=M`` (limit at most 100): newest first, with the total count."""
    try:
        offset = max(0, int(request.args.get("offset", 0)))
        limit = min(100, max(1, int(request.args.get("limit", PAGE_SIZE))))
        files, total = _store().newest(kind, offset, limit)
    except ValueError:
        abort(400, description="offset and limit are integers")
    except MediaError as exc:
        abort(404, description=str(exc))
    return jsonify({"kind": kind, "offset": offset, "total": total, "files": [f.to_json() for f in files]})


@bp.route("/media/<kind>/<name>")
@role_required("user")
def download(kind: str, name: str) -> Response:
    store = _store()
    try:
        if kind == "maps":
            import io

            data = store.map_zip(name)
            stem = name.rsplit(".", 1)[0]
            return send_file(io.BytesIO(data), mimetype="application/zip", as_attachment=True,
                             download_name=f"{stem}.zip")
        return send_file(store.path(kind, name), as_attachment=True, download_name=name)
    except MediaError as exc:
        abort(404, description=str(exc))


@bp.route("/media/<kind>/<name>/delete", methods=["POST"])
@role_required("user")
def delete(kind: str, name: str) -> Response:
    try:
        deleted = _store().delete(kind, name)
    except MediaError as exc:
        abort(404, description=str(exc))
    _maps_changed(kind)
    flash(f"Deleted {', '.join(deleted)}.", "ok")
    return redirect(url_for("media.page"))


@bp.route("/media/<kind>/delete-all", methods=["POST"])
@permission_required("delete_all", back="media.page")
def delete_all(kind: str) -> Response:
    try:
        count = _store().delete_all(kind)
    except MediaError as exc:
        abort(404, description=str(exc))
    _maps_changed(kind)
    flash(f"Deleted all {count} {kind}.", "ok")
    return redirect(url_for("media.page"))
