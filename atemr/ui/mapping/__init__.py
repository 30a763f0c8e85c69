"""The Mapping page (begin/end mapping, save/discard dialog, live map, map list and select) and the map
upload, which goes through the robot's map store (validated before anything is stored).

A refused upload answers with the page itself, the reason beside the upload form, cut to `MAX_FLASH_CHARS`
like the flash a successful upload leaves in the session cookie: what an upload may put on the page or in
the cookie is bounded whatever the upload was."""

from __future__ import annotations

from typing import Any, cast

from flask import Blueprint, current_app, flash, redirect, render_template, request, url_for

from atemr.errors import brief_text
from atemr.ui.gateway import RobotGateway
from atemr.ui.media.files import MapExistsError, MediaError, MediaStore
from atemr.ui.security import role_required

#: Longest flash message of an upload (it rides in the session cookie until shown).
MAX_FLASH_CHARS = 300

bp = Blueprint("mapping", __name__, template_folder="templates", static_folder="static",
               static_url_path="/static/mapping")


def _gateway() -> RobotGateway | None:
    return cast("RobotGateway | None", current_app.extensions["atemr.gateway"])


def _store() -> MediaStore:
    return cast(MediaStore, current_app.extensions["atemr.media"])


@bp.route("/mapping")
@role_required("user")
def page() -> str:
    return _render()


def _render(upload_error: str | None = None) -> str:
    maps, _ = _store().newest("maps", 0, 1000)
    return render_template("mapping/mapping.html", maps=maps, upload_error=upload_error)


def _refused(message: str, status: int) -> tuple[str, int]:
    """The Mapping page with the upload's refusal beside the upload form (a file input cannot be refilled)."""
    return _render(brief_text(message, MAX_FLASH_CHARS)), status


@bp.route("/mapping/upload", methods=["POST"])
@role_required("user")
def upload() -> Any:
    """A ROS map: ``yaml`` (name.yaml) and ``image`` (the PGM/PNG it names), stored through the robot's map
    store, which validates it first (nothing is stored when it is refused)."""
    yaml_file = request.files.get("yaml")
    image_file = request.files.get("image")
    if yaml_file is None or image_file is None or not yaml_file.filename or not image_file.filename:
        return _refused("Upload both the map's .yaml and the image it names.", 400)
    try:
        name = _store().upload_map(yaml_file.filename, yaml_file.read(), image_file.filename, image_file.read())
    except MapExistsError as exc:
        return _refused(f"Map upload refused: {exc}", 409)
    except MediaError as exc:
        return _refused(f"Map upload refused: {exc}", 400)
    robot = _gateway()
    if robot is not None:
        robot.maps_changed()
    flash(brief_text(f"Map {name} uploaded.", MAX_FLASH_CHARS), "ok")
    return redirect(url_for("mapping.page"))
