"""The robot's screen: the page the tablet on the robot's mast shows full screen (the caller's video, what
the robot does in plain words, ANSWER / DECLINE / HANG UP). It opens with a screen device token
(`atemr.ui.screens`) and with nothing else: an operator's login cannot pose as the screen, and a screen's
session opens no operator page (`atemr.ui.security.role_required`) or event (`atemr.ui.sockets`)."""

from __future__ import annotations

from flask import Blueprint, abort, redirect, render_template, request, url_for
from werkzeug.wrappers import Response

from atemr.ui.security import current_screen, current_user, login_screen

bp = Blueprint("screen", __name__, template_folder="templates", static_folder="static",
               static_url_path="/static/screen")

NO_TOKEN = ("The robot's screen opens only with its device token: open /screen?token=... with the token "
            "that 'atemr screen add NAME' printed.")
BAD_TOKEN = "This screen token is unknown or was revoked: make a new one with 'atemr screen add NAME'."
NOT_AN_OPERATOR = ("The robot's screen opens only with a screen device token; an operator's login cannot "
                   "pose as the screen.")


@bp.route("/screen")
def page() -> Response | str:
    """With ``?token=``: start the screen's session and come back without the token in the address (it
    would stay in the history); without: the page for a screen's session, 403 with the reason for anyone
    else."""
    token = request.args.get("token")
    if token is not None:
        if login_screen(token) is None:
            abort(403, description=BAD_TOKEN)
        return redirect(url_for("screen.page"))
    if current_screen() is None:
        abort(403, description=NOT_AN_OPERATOR if current_user() is not None else NO_TOKEN)
    return render_template("screen/screen.html", screen=current_screen())
