"""The Control page (camera, map, joystick, mode, states, graph, missions, simulation panel) and the
robot products it fetches over HTTP: the map image, the secondary core's screen, the camera as MJPEG
(`atemr.ui.control.mjpeg`) and whether to try it over WebRTC first (`atemr.ui.drive_video`)."""

from __future__ import annotations

from typing import Any, cast

from flask import Blueprint, abort, current_app, jsonify, render_template
from werkzeug.wrappers import Response

from atemr.ui.control.mjpeg import MIMETYPE, StreamCount, mjpeg_parts
from atemr.ui.gateway import RobotGateway
from atemr.ui.security import role_required

bp = Blueprint("control", __name__, template_folder="templates", static_folder="static",
               static_url_path="/static/control")


@bp.record_once
def _init(state: Any) -> None:
    state.app.extensions["atemr.camera_streams"] = StreamCount()


def _gateway() -> RobotGateway | None:
    return cast("RobotGateway | None", current_app.extensions["atemr.gateway"])


@bp.route("/control")
@role_required("user")
def page() -> str:
    return render_template("control/control.html")


@bp.route("/api/state")
@role_required("user")
def state() -> Any:
    """The snapshot once, for a page's first paint before the socket delivers."""
    robot = _gateway()
    return jsonify({"connected": robot is not None, **(robot.state() if robot else {})})


@bp.route("/api/map")
@role_required("user")
def map_meta() -> Any:
    """Size, resolution, origin and version of the map to draw (``null`` when there is none)."""
    robot = _gateway()
    image = robot.map_image() if robot else None
    return jsonify(image.meta() if image else None)


@bp.route("/api/map.png")
@role_required("user")
def map_png() -> Response:
    robot = _gateway()
    image = robot.map_image() if robot else None
    if image is None:
        abort(404, description="no map")
    return Response(image.png, mimetype="image/png", headers={"Cache-Control": "no-store"})


@bp.route("/api/secondary-screen.png")
@role_required("user")
def secondary_screen() -> Response:
    robot = _gateway()
    png = robot.secondary_screen_png() if robot else None
    if png is None:
        abort(404, description="no secondary-core screen")
    return Response(png, mimetype="image/png", headers={"Cache-Control": "no-store"})


@bp.route("/api/drive-video")
@role_required("user")
def drive_video() -> Any:
    """Whether the page should try the camera over WebRTC first (``webrtc``), why not (``reason``: the page
    says MJPEG and shows it), and the ICE servers for its peer connection."""
    from atemr.ui.drive_video.events import drive_video_of

    return jsonify(drive_video_of(current_app).availability().to_json())


@bp.route("/api/camera.mjpeg")
@role_required("user")
def camera_stream() -> Response:
    """The camera as an endless ``multipart/x-mixed-replace`` of JPEG frames (an ``<img>`` source), for as
    long as the client stays; parts start with the camera's first frame. 404 when no robot is connected."""
    robot = _gateway()
    if robot is None:
        abort(404, description="no robot is connected: no camera")
    app = current_app._get_current_object()  # type: ignore[attr-defined]
    parts = mjpeg_parts(robot.camera_jpeg, app.extensions["atemr.stopping"], app.extensions["atemr.camera_streams"])
    return Response(parts, mimetype=MIMETYPE, headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"})
