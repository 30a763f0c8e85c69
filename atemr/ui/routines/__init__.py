"""The Routines page (admins): the care routines with their schedules, next runs and the last runs with their
outcome, and forms to add, change or delete a routine and set the time zone. Every change goes through the
robot's gateway, which checks the whole routines file before it stores it; a refused form answers with the
page itself, the reason beside the form and what was typed kept in it."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, cast

from flask import Blueprint, current_app, flash, make_response, redirect, render_template, request, url_for
from werkzeug.wrappers import Response

from atemr.domain.routines import DAYS
from atemr.ui.gateway import NO_ROBOT, CommandResult, RobotGateway
from atemr.ui.security import role_required

bp = Blueprint("routines", __name__, url_prefix="/routines", template_folder="templates", static_folder="static")


def _gateway() -> RobotGateway | None:
    return cast("RobotGateway | None", current_app.extensions["atemr.gateway"])


#: A run's outcome (`atemr.robot.routines`, the history file's word, on hover) as the carer reads it.
OUTCOME_WORDS = {"reached": "done", "skipped": "skipped", "missed": "missed", "failed": "failed",
                 "cancelled": "cancelled", "refused": "refused", "running": "running"}


def _page(status: int = 200, error: str | None = None, form: str | None = None, edit: str | None = None) -> Response:
    """The page; ``error`` beside ``form`` (what the carer typed in it kept), or the routine ``edit`` in the form."""
    robot = _gateway()
    data = robot.routines() if robot is not None else None
    missions = robot.state()["missions"] if robot is not None else []
    typed: dict[str, Any] = {}
    if error and form == "routine":
        typed = {k: request.form.getlist(k) if k == "days" else v for k, v in request.form.items() if k != "csrf_token"}
    elif edit is not None and data is not None:
        routine = next((r for r in data["routines"] if r["name"] == edit), None)
        if routine is None:
            error, form, status = f"no routine named {edit!r} to change (it may have been deleted)", "routine", 404
        else:
            typed = form_from_routine(routine)
    zone_typed = request.form.get("timezone", "") if error and form == "timezone" else None
    html = render_template("routines/routines.html", data=data, missions=missions, days=DAYS, error=error,
                           error_form=form, typed=typed, zone_typed=zone_typed, OUTCOME_WORDS=OUTCOME_WORDS)
    return make_response(html, status)


def _change(ask: Callable[[RobotGateway], CommandResult], done: str, form: str) -> Response:
    """Ask the robot for a change: the page again with a flash (``done``), or with the refusal beside ``form``."""
    robot = _gateway()
    if robot is None:
        return _page(503, NO_ROBOT.reason, form)
    result = ask(robot)
    if not result.ok:
        return _page(400, result.reason, form)
    flash(done, "ok")
    return redirect(url_for("routines.page"))


@bp.route("")
@role_required("admin")
def page() -> Response:
    """The routines; ``?edit=NAME`` puts that routine in the form to change it."""
    return _page(edit=request.args.get("edit"))


def form_from_routine(routine: dict[str, Any]) -> dict[str, Any]:
    """A routine of the routines file as the form's fields (the inverse of `routine_from_form`), to change it."""
    fields: dict[str, Any] = {"name": routine["name"], "previous": routine["name"], "mission": routine["mission"],
                              "days": list(routine.get("days") or DAYS)}
    if "every_min" in routine:
        fields.update({"kind": "every", "every_min": str(routine["every_min"]), "from": routine.get("from", ""),
                       "to": routine.get("to", "")})
    else:
        fields.update({"kind": "at", "at": routine.get("at", "")})
    if routine.get("enabled", True):
        fields["enabled"] = "on"
    return fields


def routine_from_form(form: Any) -> dict[str, Any]:
    """The form's fields as a routine of the routines file (the robot checks it)."""
    routine: dict[str, Any] = {"name": form.get("name", "").strip(), "mission": form.get("mission", "")}
    if form.get("kind") == "every":
        every = form.get("every_min", "")
        routine.update({"every_min": int(every) if every.strip().isdigit() else every,
                        "from": form.get("from", ""), "to": form.get("to", "")})
    else:
        routine["at"] = form.get("at", "")
    days = form.getlist("days")
    if days and len(days) < len(DAYS):
        routine["days"] = days
    elif not days:
        routine["days"] = []  # refused by the robot: a routine that never runs is a mistake
    if form.get("enabled") != "on":
        routine["enabled"] = False
    return routine


@bp.route("/save", methods=["POST"])
@role_required("admin")
def save() -> Response:
    routine = routine_from_form(request.form)
    previous = request.form.get("previous") or None
    return _change(lambda robot: robot.save_routine(routine, previous), f"Routine {routine['name']} saved.", "routine")


@bp.route("/delete", methods=["POST"])
@role_required("admin")
def delete() -> Response:
    name = request.form.get("name", "")
    return _change(lambda robot: robot.delete_routine(name), f"Routine {name} deleted.", "delete")


@bp.route("/timezone", methods=["POST"])
@role_required("admin")
def timezone() -> Response:
    zone = request.form.get("timezone", "").strip()
    return _change(lambda robot: robot.set_routines_timezone(zone), f"Routines time zone {zone}.", "timezone")
