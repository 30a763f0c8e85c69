"""Control and Mapping pages and the robot products fetched over HTTP (state, map image, screen)."""

from __future__ import annotations

from atemr.msgs import Pose2D
from atemr.ui.gateway import MapImage
from atemr.ui.state import state_problems


def test_pages_render_for_users(alice):
    for path in ("/control", "/mapping"):
        html = alice.get(path).get_data(as_text=True)
        assert 'id="joystick"' in html and 'id="map"' in html and 'id="mode-toggle"' in html, path
    assert 'id="sim-panel"' in alice.get("/control").get_data(as_text=True)  # simulation by default
    assert 'id="save-dialog"' in alice.get("/mapping").get_data(as_text=True)


def test_pages_name_their_own_robot_for_the_robot_selector(alice, ui, tmp_path):
    html = alice.get("/control").get_data(as_text=True)
    assert 'data-robot="KAY"' in html and 'id="robot"' in html  # secondary.robot_name
    from atemr.ui.app import create_app

    robotless = create_app(ui.make_config(tmp_path / "worker"), None, hash_method=ui.FAST_SCRYPT)
    robotless.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    client = robotless.test_client()
    ui.login(client, "admin", ui.ADMIN_PW)
    assert 'data-robot=""' in client.get("/control").get_data(as_text=True)  # a worker without a robot


def test_agent_page_renders(alice):
    html = alice.get("/agent").get_data(as_text=True)
    assert 'id="machine"' in html and 'id="agent-tree"' in html and 'id="agent-transitions"' in html


def test_index_goes_to_control(alice):
    assert alice.get("/").location.endswith("/control")


def test_state_json(alice, gateway):
    gateway.snapshot["agent_state"] = "MAPPING"
    body = alice.get("/api/state").get_json()
    assert body.pop("connected") is True and body["agent_state"] == "MAPPING"
    assert state_problems(body) == []  # the test robot keeps to the contract the pages read


def test_the_state_contract_names_what_is_wrong_and_where(gateway):
    state = gateway.state()
    assert state_problems(state) == []
    del state["pose"]
    state["mode"] = "TURBO"  # type: ignore[typeddict-item]
    state["limits"]["linear_mps"] = "fast"  # type: ignore[typeddict-item]
    state["events"] = [{"t": 1.0, "kind": "info"}]  # type: ignore[typeddict-item]
    state["level2"] = {"lidar": 1}
    state["extra"] = 1  # type: ignore[typeddict-unknown-key]
    assert state_problems(state) == [
        "state: missing key 'pose'",
        "state: unexpected key 'extra'",
        "state.mode: expected one of 'MANUAL', 'AUTO', got 'TURBO'",
        "state.level2.lidar: expected bool, got 1",
        "state.limits.linear_mps: expected float, got 'fast'",
        "state.events[0]: missing key 'text'",
        "state.events[0]: missing key 'unix_s'",
    ]


def test_the_state_contract_holds_localization_to_its_words(gateway):
    """Issue 21: the dashboard's localization is the robot's LocalizationStatus; a state it does not name, or a
    candidate without its agreement, breaks the contract."""
    state = gateway.state()
    state["localization"]["state"] = "confused"  # type: ignore[typeddict-item]
    state["localization"]["candidates"] = [{"x_m": 1.0, "y_m": 2.0, "yaw_rad": 0.0}]  # type: ignore[typeddict-item]
    problems = state_problems(state)
    assert problems[0].startswith("state.localization.state: expected one of 'localized', 'lost', ")
    assert problems[1:] == ["state.localization.candidates[0]: missing key 'agreement'"]


def test_map_meta_and_png(alice, gateway):
    assert alice.get("/api/map").get_json() is None
    assert alice.get("/api/map.png").status_code == 404
    gateway.map = MapImage(b"\x89PNG fake", 40, 20, 0.05, Pose2D(-1.0, -0.5, 0.0), 7)
    meta = alice.get("/api/map").get_json()
    assert meta == {"width_px": 40, "height_px": 20, "resolution_m": 0.05,
                    "origin": {"x_m": -1.0, "y_m": -0.5, "yaw_rad": 0.0}, "version": 7}
    png = alice.get("/api/map.png")
    assert png.mimetype == "image/png" and png.data == b"\x89PNG fake"
    assert png.headers["Cache-Control"] == "no-store"


def test_secondary_screen(alice, gateway):
    assert alice.get("/api/secondary-screen.png").status_code == 404
    gateway.screen = b"\x89PNG screen"
    assert alice.get("/api/secondary-screen.png").data == b"\x89PNG screen"


def test_static_assets_are_served(alice):
    for path in ("/static/css/dashboard.css", "/static/js/socket.js", "/static/js/statusbar.js",
                 "/static/js/mapview.js", "/static/js/panel.js", "/static/js/media.js",
                 "/static/control/control.js", "/static/mapping/mapping.js", "/static/agent/agent.js"):
        response = alice.get(path)
        assert response.status_code == 200, path
        response.close()


def test_mapping_page_lists_maps(alice, app):
    maps = app.config["ATEMR_CONFIG"].data_dir / "maps"
    maps.mkdir(parents=True, exist_ok=True)  # the map store made it
    (maps / "kitchen.yaml").write_text("image: kitchen.pgm\n")
    html = alice.get("/mapping").get_data(as_text=True)
    assert '<option value="kitchen">kitchen.yaml</option>' in html
    assert '<option value="studio">studio.yaml</option>' in html  # the built-in map is listed too
