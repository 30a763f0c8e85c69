"""Media: captured images, recorded videos and maps — list (ten newest, more on request), preview, download,
delete one or all.

Images and videos show a thumbnail (`atemr.ui.media.thumbnails`, made on first request, on the request's
thread); an image opens full size in place, and an MP4/WebM video plays in the page's ``<video>`` (served
inline with its type and byte ranges, so the browser can seek). Downloads carry the file's real type
(``video/mp4``, ...), so a player opens them; an old ``.mjpeg`` video downloads as ``video/x-motion-jpeg``.
Deleting one file asks first (the form's ``data-confirm``, handled by statusbar.js). "MORE" fetches the
next items as HTML rendered by the same template as the page (``/media/<kind>/more``); ``/api/media/<kind>``
gives the same listing as JSON.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

from flask import Blueprint, abort, current_app, flash, jsonify, redirect, render_template, request, send_file, url_for
from werkzeug.wrappers import Response

from atemr.ui.gateway import RobotGateway
from atemr.ui.media.files import KINDS, PAGE_SIZE, MediaError, MediaInUseError, MediaStore, human_size, mimetype
from atemr.ui.security import permission_required, role_required

bp = Blueprint("media", __name__, template_folder="templates")
#: How long a browser keeps a thumbnail without asking again (a medium's name is never reused for other content
#: by the robot: names carry the time).
THUMBNAIL_MAX_AGE_S = 3600


bp.add_app_template_filter(human_size, "size")


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


@bp.route("/media/<kind>/more")
@role_required("user")
def more(kind: str) -> Response:
    """The list items after ``?offset=N`` (`PAGE_SIZE` of them) as HTML, and the total in ``X-Total-Count``."""
    try:
        offset = max(0, int(request.args.get("offset", 0)))
        files, total = _store().newest(kind, offset, PAGE_SIZE)
    except ValueError:
        abort(400, description="offset is an integer")
    except MediaError as exc:
        abort(404, description=str(exc))
    response = current_app.make_response(render_template("media/items.html", kind=kind, files=files))
    response.headers["X-Total-Count"] = str(total)
    return response


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
        return send_file(store.path(kind, name), mimetype=mimetype(name), as_attachment=True, download_name=name)
    except MediaError as exc:
        abort(404, description=str(exc))


def _found(find: Callable[[str, str], Path], kind: str, name: str) -> Path:
    """``find(kind, name)``, or 404 with the store's reason."""
    try:
        return find(kind, name)
    except MediaError as exc:
        abort(404, description=str(exc))


@bp.route("/media/<kind>/<name>/view")
@role_required("user")
def view(kind: str, name: str) -> Response:
    """An image or a video a browser shows in place, inline, with byte ranges for seeking."""
    return send_file(_found(_store().viewable, kind, name), mimetype=mimetype(name), conditional=True)


@bp.route("/media/<kind>/<name>/thumbnail.jpg")
@role_required("user")
def thumbnail(kind: str, name: str) -> Response:
    return send_file(_found(_store().thumbnail, kind, name), mimetype="image/jpeg", max_age=THUMBNAIL_MAX_AGE_S)


@bp.route("/media/<kind>/<name>/delete", methods=["POST"])
@role_required("user")
def delete(kind: str, name: str) -> Response:
    try:
        deleted = _store().delete(kind, name)
    except MediaInUseError as exc:
        flash(str(exc), "error")
        return redirect(url_for("media.page"))
    except MediaError as exc:
        abort(404, description=str(exc))
    _maps_changed(kind)
    flash(f"Deleted {', '.join(deleted)}.", "ok")
    return redirect(url_for("media.page"))


@bp.route("/media/<kind>/delete-all", methods=["POST"])
@permission_required("delete_all", back="media.page")
def delete_all(kind: str) -> Response:
    try:
        count, kept = _store().delete_all(kind)
    except MediaError as exc:
        abort(404, description=str(exc))
    _maps_changed(kind)
    flash(f"Deleted {count} of the {kind}; kept the one still being recorded." if kept
          else f"Deleted all {count} {kind}.", "ok")
    return redirect(url_for("media.page"))
