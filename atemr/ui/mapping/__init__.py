"""The Mapping page (begin/end mapping, save/discard dialog, live map, map list and select) and the map
upload, which is validated before anything is stored."""

from __future__ import annotations

from typing import Any, cast

from flask import Blueprint, current_app, flash, redirect, render_template, request, url_for

from atemr.errors import ConfigError
from atemr.ui.gateway import CommandResult, RobotGateway
from atemr.ui.media.files import MediaError, MediaStore
from atemr.ui.security import role_required

bp = Blueprint("mapping", __name__, template_folder="templates", static_folder="static",
               static_url_path="/static/mapping")


def _gateway() -> RobotGateway | None:
    return cast("RobotGateway | None", current_app.extensions["atemr.gateway"])


def _store() -> MediaStore:
    return cast(MediaStore, current_app.extensions["atemr.media"])


@bp.route("/mapping")
@role_required("user")
def page() -> str:
    maps, _ = _store().newest("maps", 0, 1000)
    return render_template("mapping/mapping.html", maps=maps)


def validate_map(yaml_path: Any) -> CommandResult:
    """Validate a staged upload: through the robot when there is one, else with the package's map reader."""
    robot = _gateway()
    if robot is not None:
        return robot.validate_map(yaml_path)
    from atemr.io.sim.maps import load_map  # the one map reader in the package (ROS map_server format)

    try:
        load_map(yaml_path)
    except ConfigError as exc:
        return CommandResult.refused(f"not a valid ROS map: {exc.reason}")
    return CommandResult.accepted()


@bp.route("/mapping/upload", methods=["POST"])
@role_required("user")
def upload() -> Any:
    """A ROS map: ``yaml`` (name.yaml) and ``image`` (the PGM/PNG it names), validated, then stored."""
    yaml_file = request.files.get("yaml")
    image_file = request.files.get("image")
    if yaml_file is None or image_file is None or not yaml_file.filename or not image_file.filename:
        flash("Upload both the map's .yaml and the image it names.", "error")
        return redirect(url_for("mapping.page")), 400
    store = _store()
    try:
        staged = store.stage_map_upload(yaml_file.filename, yaml_file.read(), image_file.filename, image_file.read())
    except MediaError as exc:
        flash(f"Map upload refused: {exc}", "error")
        return redirect(url_for("mapping.page")), 400
    verdict = validate_map(staged)
    if not verdict.ok:
        store.discard_staged(staged)
        flash(f"Map upload refused: {verdict.reason}", "error")
        return redirect(url_for("mapping.page")), 400
    try:
        name = store.commit_map(staged)
    except MediaError as exc:
        flash(f"Map upload refused: {exc}", "error")
        return redirect(url_for("mapping.page")), 409
    robot = _gateway()
    if robot is not None:
        robot.maps_changed()
    flash(f"Map {name} uploaded.", "ok")
    return redirect(url_for("mapping.page"))
