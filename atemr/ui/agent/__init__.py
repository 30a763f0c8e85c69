"""The Agent view (beyond the thesis): the lifecycle machine and the current state's behaviour tree drawn
live with each node's status, the last transitions with their reasons, and the mission progress.
The data comes over Socket.IO (``agent_view`` subscription, ``agent`` pushes); this serves the page."""

from __future__ import annotations

from flask import Blueprint, render_template

from atemr.ui.security import role_required

bp = Blueprint("agent", __name__, template_folder="templates", static_folder="static",
               static_url_path="/static/agent")


@bp.route("/agent")
@role_required("user")
def page() -> str:
    return render_template("agent/agent.html")
