"""Missions by place names (issue 27): ``atemr mission validate`` checks the places on the mission's map, and
``atemr mission run --headless`` drives the whole simulated robot to each place, or refuses a mission that
names a place the map lacks before it starts."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from atemr.cli.main import main
from atemr.io.map_store import MapStore

ROOT = Path(__file__).resolve().parents[2]
ROUND = ROOT / "trees" / "missions" / "round-of-the-rooms.yaml"

MISSING = """
mission:
  name: to-the-kitchen
  world: studio
  steps:
    - go_to: {place: kichen}
"""


def test_validate_checks_places_on_the_missions_map(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["mission", "validate", str(ROUND), "--data-dir", str(tmp_path)]) == 0
    assert "OK, mission 'round-of-the-rooms'" in capsys.readouterr().out
    bad = tmp_path / "bad.yaml"
    bad.write_text(MISSING)
    assert main(["mission", "validate", str(bad), "--data-dir", str(tmp_path), "--json"]) == 2
    report = json.loads(capsys.readouterr().out)
    assert report["valid"] is False and report["line"] == 6
    assert "no place named 'kichen' on map studio (closest: kitchen)" in report["error"]
    # the operator adds the place on the dashboard: the same file is valid against that map now
    store = MapStore(tmp_path)
    store.save_places("studio", store.places("studio").renamed("kitchen", "kichen"))
    assert main(["mission", "validate", str(bad), "--data-dir", str(tmp_path)]) == 0
    assert main(["mission", "validate", str(ROUND), "--data-dir", str(tmp_path), "--map", "studio"]) == 2
    assert "no place named 'kitchen' on map studio (closest: kichen)" in capsys.readouterr().err


def test_a_mission_naming_a_missing_place_is_refused_before_it_starts(capsys: pytest.CaptureFixture[str],
                                                                       tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(MISSING)
    code = main(["--log-level", "ERROR", "mission", "run", str(bad), "--headless", "--json", "--seed", "1",
                 "--data-dir", str(tmp_path)])
    result = json.loads(capsys.readouterr().out)
    assert code == 1 and result["outcome"] == "not started"
    assert "no place named 'kichen' on the active map (closest: kitchen)" in result["reason"]
    assert all(s["status"] == "pending" for s in result["steps"]) or not result["steps"]


@pytest.mark.slow
def test_a_mission_by_place_names_reaches_each_place(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code = main(["--log-level", "ERROR", "mission", "run", str(ROUND), "--headless", "--json", "--seed", "3",
                 "--data-dir", str(tmp_path)])
    result = json.loads(capsys.readouterr().out)
    assert code == 0 and result["outcome"] == "reached", result.get("reason")
    places = MapStore(tmp_path).places("studio")
    driven = [s for s in result["steps"] if s["kind"] != "capture_image"]
    assert len(driven) == 5 and all(s["status"] == "reached" for s in result["steps"])
    for step in driven:  # each step ends at its place (the last of a visit's), within the navigator's tolerance
        assert step["position_error_m"] is not None and step["position_error_m"] <= 0.25, step
        assert step["heading_error_rad"] <= 0.2, step
    ends = [(s["final_pose"]["x_m"], s["final_pose"]["y_m"]) for s in driven]
    for (x, y), name in zip(ends, ["kitchen", "bedroom", "balcony door", "living room", "home"], strict=True):
        pose = places[name].pose
        assert math.hypot(x - pose.x_m, y - pose.y_m) <= 0.25, (name, x, y)
    assert result["collisions"] == 0
