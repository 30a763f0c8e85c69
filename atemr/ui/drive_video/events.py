"""The drive video's Socket.IO events and its place in the app.

``drive_video_offer`` ``{description: {type: "offer", sdp}}`` is answered in its acknowledgement,
``{ok, reason, description: {type: "answer", sdp}}``; ``drive_video_stop`` (no payload) closes the page's
connection (CAM off). Both are operator events of the ``user`` role like the camera itself: the screen's
device token and a session without access are refused by the group's checks, and a socket that goes (or
is closed because its session ended) closes its connection. What a page may try is ``GET
/api/drive-video`` (`atemr.ui.control`).
"""

from __future__ import annotations

from typing import Any, cast

from flask import Flask, current_app, request

from atemr.errors import ProtocolError
from atemr.ui.call.events import check_signal, ice_servers
from atemr.ui.drive_video.sender import DriveVideo
from atemr.ui.gateway import RobotGateway
from atemr.ui.sockets import EventGroup, disconnect_hooks

events = EventGroup("drive_video")


def drive_video_of(app: Flask) -> DriveVideo:
    return cast(DriveVideo, app.extensions["atemr.drive_video"])


def init_app(app: Flask, robot: RobotGateway | None) -> None:
    """Give ``app`` its drive video over ``robot``'s camera (None: no robot, no WebRTC); a socket that goes
    closes its connection."""
    ui = app.config["ATEMR_CONFIG"].ui
    video = DriveVideo(None if robot is None else robot.camera_frame, enabled=ui.drive_video == "webrtc",
                       max_peers=ui.drive_video_max_peers, ice_servers=lambda: ice_servers(app))
    app.extensions["atemr.drive_video"] = video
    disconnect_hooks(app).append(video.close)


def _sid() -> str:
    return cast(str, request.sid)  # type: ignore[attr-defined]


@events.on("drive_video_offer")
def drive_video_offer(robot: RobotGateway, data: Any) -> dict[str, Any]:
    """Answer the page's offer of one receive-only video track (refused with the reason: the page uses MJPEG)."""
    signal = check_signal("drive_video_offer", data)
    offer = signal.get("description")
    if offer is None or offer["type"] != "offer":
        raise ProtocolError("drive_video_offer: expected {description: {type: offer, sdp: text}}")
    answer = drive_video_of(current_app).answer(_sid(), offer)
    return {"ok": True, "reason": "", "description": answer}


@events.on("drive_video_stop")
def drive_video_stop(robot: RobotGateway, data: Any) -> dict[str, Any]:
    """Close this page's drive video connection (the camera is off, or the page falls back to MJPEG)."""
    if data not in (None, {}):
        raise ProtocolError("drive_video_stop: takes no payload")
    drive_video_of(current_app).close(_sid())
    return {"ok": True, "reason": ""}
