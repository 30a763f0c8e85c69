"""Issue 19, finding 1: a user-role account could stall the robot's control loop with a map.

* A 55 KB PNG of 7000 x 7000 pixels (or a PGM whose header claims 20000 x 20000) was decoded in full:
  gigabytes and seconds. Now the size is read from the header and refused above ``ui.max_map_cells``
  before a pixel is decoded.
* A few hundred bytes of nested YAML aliases stood for billions of values, and the error message quoted
  them (``repr``), then the flash carried them into a 2.67 MB session cookie. Now the aliases' expansion
  is bounded while parsing, values quoted in errors are cut short, and upload flashes are bounded.
* Selecting a map ran its loading on the robot's thread (``overrun: dashboard_gateway took 13230.1 ms``:
  motion, the heartbeat and the secondary core stood still). Now the gateway reads and prepares the map in
  its own worker and the robot's thread only swaps the finished map in; the whole simulated robot, on the
  wall clock, keeps its periods while a 1900 x 1900 map loads (the scheduler's own overrun accounting).
"""

from __future__ import annotations

import html
import io
import re
import threading
import time
import tracemalloc
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from flask import Flask
from flask.testing import FlaskClient
from PIL import Image, ImageFile

from atemr.clock import SimClock, WallClock
from atemr.config import Config, UiConfig, load_config
from atemr.domain.maps import OccupancyMap
from atemr.errors import ConfigError, brief
from atemr.io.can.bus import unique_channel
from atemr.io.map_store import MapStore
from atemr.io.sim.maps import DEFAULT_MAX_MAP_CELLS, load_map
from atemr.robot import Robot, build_robot
from atemr.robot import gateway as gateway_module
from atemr.robot.gateway import RobotGatewayImpl
from atemr.ui.app import create_app
from atemr.ui.mapping import MAX_FLASH_CHARS
from atemr.yamlsafe import MAX_ALIAS_NODES, load_yaml

FAST_SCRYPT = "scrypt:1024:8:1"
ADMIN_PW = "root-secret-1"
USER_PW = "user-secret-1"
MAP_YAML = ("image: {image}\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\noccupied_thresh: 0.65\n"
            "free_thresh: 0.196\nnegate: 0\n")


# -- helpers -------------------------------------------------------------------------------------------
def png_bytes(width: int, height: int, value: int = 255) -> bytes:
    """A plain white (or ``value``) PNG: 7000 x 7000 compresses to a few tens of KB."""
    buf = io.BytesIO()
    Image.new("L", (width, height), value).save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def pgm_header_bomb(width: int = 20_000, height: int = 20_000) -> bytes:
    """A binary PGM whose header claims ``width`` x ``height`` pixels, followed by a few bytes."""
    return f"P5\n{width} {height}\n255\n".encode() + bytes(64)


def alias_bomb(levels: int = 9, fan: int = 9) -> str:
    """The issue's map YAML: ``resolution: [&l0 lol, &l1 [*l0, ... x9], ... &l8 [...]]`` (about 500 bytes)."""
    items = ["&l0 lol"] + [f"&l{i} [" + ",".join([f"*l{i - 1}"] * fan) + "]" for i in range(1, levels)]
    return MAP_YAML.format(image="room.pgm").replace("resolution: 0.05", f"resolution: [{', '.join(items)}]")


class DecodeSpy:
    """Counts Pillow decodes (``ImageFile.load``) and opens, calling through."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.loads: list[tuple[int, int]] = []
        self.opens = 0
        real_load, real_open = ImageFile.ImageFile.load, Image.open
        spy = self

        def load(img: ImageFile.ImageFile) -> Any:
            spy.loads.append(img.size)
            return real_load(img)

        def open_(*args: Any, **kwargs: Any) -> Any:
            spy.opens += 1
            return real_open(*args, **kwargs)

        monkeypatch.setattr(ImageFile.ImageFile, "load", load)
        monkeypatch.setattr(Image, "open", open_)


@pytest.fixture
def app(tmp_path: Path) -> Flask:
    """A dashboard without a robot (its own map store, default limits) with a user-role account."""
    config = Config(data_dir=tmp_path / "data", ui=UiConfig())
    app = create_app(config, None, clock=SimClock(), hash_method=FAST_SCRYPT)
    users = app.extensions["atemr.users"]
    users.set_password("admin", ADMIN_PW)
    users.create("carol", USER_PW, "user")
    return app


def token_of(client: FlaskClient, path: str) -> str:
    match = re.search(r'name="csrf_token" value="([^"]+)"', client.get(path).get_data(as_text=True))
    assert match, f"no CSRF token on {path}"
    return match.group(1)


@pytest.fixture
def carol(app: Flask) -> FlaskClient:
    client = app.test_client()
    response = client.post("/auth/login", data={"username": "carol", "password": USER_PW,
                                                "csrf_token": token_of(client, "/auth/login")})
    assert response.status_code == 302
    return client


def upload(client: FlaskClient, yaml_text: str, image: bytes, *, yaml_name: str = "room.yaml",
           image_name: str = "room.pgm") -> Any:
    data = {"yaml": (io.BytesIO(yaml_text.encode()), yaml_name), "image": (io.BytesIO(image), image_name),
            "csrf_token": token_of(client, "/mapping")}
    return client.post("/mapping/upload", data=data, content_type="multipart/form-data")


def refusals(client: FlaskClient, response: Any) -> list[str]:
    """What the upload's answer says beside its form, plus any flash left in the session (there must be none:
    a refusal shown in place never rides in the cookie)."""
    with client.session_transaction() as session:
        assert not session.get("_flashes"), session.get("_flashes")
    found = re.findall(r'<p class="error inline-error" id="map-upload-error" role="alert">(.*?)</p>',
                       response.get_data(as_text=True), re.S)
    return [html.unescape(text) for text in found]


def stored(app: Flask) -> list[str]:
    return sorted(p.name for p in (app.config["ATEMR_CONFIG"].data_dir / "maps").iterdir())


# -- image bombs -----------------------------------------------------------------------------------------
def test_a_7000_by_7000_png_upload_is_refused_from_its_header_without_decoding(app, carol, monkeypatch):
    bomb = png_bytes(7000, 7000)
    assert len(bomb) < 100_000  # a small file: ui.max_upload_mb (which bounds the compressed size) lets it in
    spy = DecodeSpy(monkeypatch)
    response = upload(carol, MAP_YAML.format(image="bomb.png"), bomb, yaml_name="bomb.yaml", image_name="bomb.png")
    assert response.status_code == 400
    [message] = refusals(carol, response)
    assert "7000 x 7000 = 49,000,000 cells" in message, message  # names the size ...
    assert "more than the limit of 4,000,000 (ui.max_map_cells)" in message  # ... and the cap
    assert spy.loads == [] and spy.opens == 0  # refused from the PNG header: Pillow never even opened it
    assert stored(app) == []  # nothing stored, no staging directory left
    assert app.extensions["atemr.maps"].names() == ["studio"]


def test_an_all_black_7000_by_7000_png_is_refused_the_same_way(tmp_path, monkeypatch):
    store = MapStore(tmp_path)
    spy = DecodeSpy(monkeypatch)
    with pytest.raises(ConfigError, match=r"7000 x 7000 = 49,000,000 cells, more than the limit of 4,000,000"):
        store.upload({"black.yaml": MAP_YAML.format(image="black.png").encode(), "black.png": png_bytes(7000, 7000, 0)})
    assert spy.loads == [] and store.names() == ["studio"]


@pytest.mark.parametrize("size", [(20_000, 20_000), (7000, 7000), (2001, 2000)])
def test_a_pgm_whose_header_claims_too_many_pixels_is_refused_from_the_header(tmp_path, monkeypatch, size):
    store = MapStore(tmp_path)
    spy = DecodeSpy(monkeypatch)
    width, height = size
    with pytest.raises(ConfigError) as info:
        store.upload({"room.yaml": MAP_YAML.format(image="room.pgm").encode(), "room.pgm": pgm_header_bomb(*size)})
    assert f"{width} x {height} = {width * height:,} cells, more than the limit of 4,000,000" in str(info.value)
    assert spy.opens == 0 and spy.loads == []  # PGM: the header is read first, Pillow is not asked
    assert store.names() == ["studio"] and sorted(p.name for p in store.dir.iterdir()) == []


def test_formats_without_a_header_check_are_refused_before_pillow_decodes(tmp_path, monkeypatch):
    """TIFF: Pillow opens it lazily; the size is checked before ``load`` decodes it."""
    buf = io.BytesIO()
    Image.new("L", (2100, 2000), 255).save(buf, format="TIFF", compression="tiff_deflate")
    store = MapStore(tmp_path)
    spy = DecodeSpy(monkeypatch)
    with pytest.raises(ConfigError, match=r"2100 x 2000 = 4,200,000 cells, more than the limit of 4,000,000"):
        store.upload({"room.yaml": MAP_YAML.format(image="room.tif").encode(), "room.tif": buf.getvalue()})
    assert spy.opens == 1 and spy.loads == []


@pytest.mark.parametrize("side", [20_000, 10_000])
def test_pillows_own_decompression_bomb_guard_is_a_clean_refusal(tmp_path, side):
    """A GIF (no header check of ours) claiming more pixels than Pillow's ``MAX_IMAGE_PIXELS``: its error (above
    twice the limit) and its warning (above the limit) are both a refusal naming the image."""
    buf = io.BytesIO()
    Image.new("L", (1, 1)).save(buf, format="GIF")
    data = bytearray(buf.getvalue())
    data[6:10] = side.to_bytes(2, "little") * 2  # the logical screen's width and height
    (tmp_path / "room.gif").write_bytes(bytes(data))
    (tmp_path / "room.yaml").write_text(MAP_YAML.format(image="room.gif"))
    assert Image.MAX_IMAGE_PIXELS is not None and side * side > Image.MAX_IMAGE_PIXELS  # Pillow's guard is on
    with pytest.raises(ConfigError, match=r"image: image .*room.gif is too large: Image size"):
        load_map(tmp_path / "room.yaml")


def test_the_cap_is_ui_max_map_cells(tmp_path):
    assert UiConfig().max_map_cells == DEFAULT_MAX_MAP_CELLS == 4_000_000
    with pytest.raises(ConfigError, match="max_map_cells"):
        load_config(environ={}, overrides={"ui.max_map_cells": 100_000_000})  # above MAX_CELLS
    small = MapStore(tmp_path, max_cells=10_000)
    with pytest.raises(ConfigError, match=r"200 x 100 = 20,000 cells, more than the limit of 10,000 "
                                          r"\(ui.max_map_cells\)"):
        small.upload({"room.yaml": MAP_YAML.format(image="room.png").encode(), "room.png": png_bytes(200, 100)})
    assert MapStore(tmp_path).upload({"room.yaml": MAP_YAML.format(image="room.png").encode(),
                                      "room.png": png_bytes(200, 100)}) == "room"
    with pytest.raises(ConfigError, match="more than the limit of 10,000"):  # stored maps too, not just uploads
        small.load("room")


# -- YAML alias bombs -------------------------------------------------------------------------------------
def test_the_nested_alias_map_yaml_is_refused_while_parsing(tmp_path):
    document = alias_bomb()
    assert len(document) < 600
    tracemalloc.start()
    try:
        with pytest.raises(ConfigError) as info:
            load_yaml("bomb.yaml", text=document)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert f"aliases expand to more than {MAX_ALIAS_NODES} nodes" in str(info.value)
    assert peak < 5_000_000  # not 1.7 GB
    assert len(str(info.value)) < 300 and "lol" not in str(info.value)


def test_the_alias_bomb_upload_gets_a_short_refusal(app, carol):
    response = upload(carol, alias_bomb(), png_bytes(20, 10), image_name="room.png")
    assert response.status_code == 400
    [message] = refusals(carol, response)
    assert "aliases expand to more than" in message
    assert len(message) < 300 and message.count("lol") == 0
    assert stored(app) == []


def test_aliases_within_the_limits_still_load_and_self_reference_is_refused():
    doc = load_yaml("ok.yaml", text="base: &b {x: 1, y: 2}\nother:\n  <<: *b\n  z: 3\nboth: [*b, *b]\n")
    assert doc["other"] == {"x": 1, "y": 2, "z": 3} and doc["both"] == [{"x": 1, "y": 2}] * 2
    with pytest.raises(ConfigError, match="contains it"):
        load_yaml("loop.yaml", text="a: &a [1, *a]\n")


def test_errors_quote_values_briefly():
    nested: Any = "lol"
    for _ in range(9):
        nested = [nested] * 9  # 387 M leaves: a full repr would never finish
    assert len(brief(nested)) <= 80
    assert len(brief("x" * 1_000_000)) <= 80 and brief("ok") == "'ok'"



def test_map_errors_quote_values_briefly(tmp_path):
    """The map reader quotes what it refuses through `brief`: a long value is cut."""
    for key, value in [("negate", '"' + "9" * 100_000 + '"'), ("origin", "[" + ", ".join(["1.5"] * 20_000) + "]"),
                       ("mode", "x" * 100_000), ("image", "[" + "[" * 30 + "]" * 31)]:
        lines = [line for line in MAP_YAML.format(image="room.pgm").splitlines() if not line.startswith(key)]
        (tmp_path / "room.yaml").write_text("\n".join([*lines, f"{key}: {value}"]) + "\n")
        with pytest.raises(ConfigError) as info:
            load_map(tmp_path / "room.yaml")
        assert len(str(info.value)) < 300, (key, len(str(info.value)))


# -- flashes and the session cookie ----------------------------------------------------------------------
@pytest.mark.parametrize("case", ["long name", "long value", "long key", "long image name"])
def test_upload_flashes_are_bounded_whatever_the_upload(app, carol, case):
    yaml_text, yaml_name, image_name = MAP_YAML.format(image="room.pgm"), "room.yaml", "room.pgm"
    if case == "long name":
        yaml_name = "m" * 3000 + ".yaml"
    elif case == "long value":
        yaml_text = yaml_text.replace("origin: [0.0, 0.0, 0.0]", "origin: " + "[" * 40 + "7" * 200_000 + "]" * 40)
    elif case == "long key":
        yaml_text += "k" * 1000 + ": 1\n"
    else:
        image_name = "i" * 3000 + ".pgm"
        yaml_text = MAP_YAML.format(image=image_name)
    response = upload(carol, yaml_text, small_pgm(), yaml_name=yaml_name, image_name=image_name)
    assert response.status_code == 400
    [message] = refusals(carol, response)
    assert message.startswith("Map upload refused: ") and len(message) <= MAX_FLASH_CHARS
    assert len(carol.get_cookie("atemr_session").value) < 4000  # a browser keeps cookies up to 4 KB
    assert stored(app) == []


def small_pgm() -> bytes:
    buf = io.BytesIO()
    Image.new("L", (20, 10), 254).save(buf, format="PPM")
    return buf.getvalue()


# -- the control loop keeps its period while a map loads ----------------------------------------------
def grid_map(n: int) -> OccupancyMap:
    """An ``n`` x ``n`` map of 2.5 m rooms (walls every 50 cells, a door in each)."""
    data = np.zeros((n, n), np.int8)
    data[::50, :] = 100
    data[:, ::50] = 100
    data[::50, 20::50] = 0
    data[20::50, ::50] = 0
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    return OccupancyMap(data, 0.05, name="big")


def make_robot(data_dir: Path, **kwargs: Any) -> tuple[Robot, RobotGatewayImpl]:
    overrides = {"data_dir": str(data_dir), "can.channel": unique_channel("bombs"), "sim.seed": 3,
                 "secondary.portal_serve": False, "ui.enabled": False, "ui.port": 0, "sim.camera_hz": 0.0,
                 "secondary.boot_s": 0.5, **kwargs.pop("overrides", {})}
    robot = build_robot(load_config(environ={}, overrides=overrides), **kwargs)
    return robot, RobotGatewayImpl(robot)


def boot(robot: Robot) -> None:
    for _ in range(100):
        robot.run(until=robot.clock.now() + 0.2)
        if str(robot.components["agent"].state).startswith("IDLE"):  # type: ignore[attr-defined]
            return
    agent = robot.parts.agent
    raise AssertionError(f"the robot did not reach IDLE: {agent.state}, {agent.snapshot().get('error')}, "
                         f"{[(k, h.detail) for k, h in robot.parts.health.collect().items() if not h.ok]}")


@pytest.fixture
def sim_robot(tmp_path: Path) -> Iterator[tuple[Robot, RobotGatewayImpl]]:
    robot, gateway = make_robot(tmp_path / "data", overrides={"ui.max_map_cells": 1_000_000},
                                realtime=False, clock=SimClock())
    with robot:
        boot(robot)
        yield robot, gateway
    gateway.close()


def test_a_stored_map_above_the_cap_is_refused_at_selection_and_nothing_changes(sim_robot):
    robot, gateway = sim_robot
    store = robot.parts.map_store
    assert store.max_cells == 1_000_000  # the robot's store takes ui.max_map_cells
    MapStore(store.dir.parent).save("huge", grid_map(1100))  # put there by another store (a larger cap)
    version = robot.parts.maps.version
    result = gateway.select_map("huge")
    assert not result.ok
    assert "1100 x 1100 = 1,210,000 cells, more than the limit of 1,000,000 (ui.max_map_cells)" in result.reason
    robot.run(until=robot.clock.now() + 0.3)
    assert robot.parts.maps.active_name == "studio" and robot.parts.maps.version == version
    assert gateway.select_map("studio").ok  # the loading slot was freed


def test_a_slow_load_answers_still_loading_refuses_a_second_and_reports_when_ready(sim_robot, monkeypatch):
    robot, gateway = sim_robot
    MapStore(robot.parts.map_store.dir.parent).save("rooms", grid_map(300))
    maps = robot.parts.maps
    release, real = threading.Event(), maps.prepare

    def slow_prepare(name: str, grid: OccupancyMap | None = None) -> Any:
        assert release.wait(30)
        return real(name, grid)

    monkeypatch.setattr(maps, "prepare", slow_prepare)  # the gateway's worker blocks until released
    monkeypatch.setattr(gateway_module, "MAP_WAIT_S", 0.05)
    try:
        first = gateway.select_map("rooms")
        assert first.ok and "still loading map rooms" in first.reason
        assert "map rooms is still loading" in gateway.select_map("studio").reason  # one map at a time
        robot.run(until=robot.clock.now() + 0.5)
        assert maps.active_name == "studio"  # the robot went on meanwhile
    finally:
        release.set()
    for _ in range(200):
        robot.run(until=robot.clock.now() + 0.1)
        if maps.active_name == "rooms":
            break
    assert maps.active_name == "rooms" and robot.parts.map_store.active_name() == "rooms"
    assert any(e["text"] == "active map: rooms" for e in robot.recent_events(10))


@pytest.mark.exclusive  # the real-time robot's own overrun accounting
def test_selecting_a_large_map_does_not_stall_the_control_loop(tmp_path):
    """The whole simulated robot on the wall clock (so a tick that blocks shows as an overrun of every
    component due meanwhile) selects a 1900 x 1900 map through the gateway, as the dashboard does.

    The map is read, decoded and prepared (likelihood field, costmap) in the gateway's worker, the swap is
    a cheap action of ``dashboard_gateway`` on the robot's thread. Checked with the scheduler's overrun
    accounting over the whole load: ``dashboard_gateway`` never takes longer than its period, and
    ``motion``, ``secondary_link`` (the heartbeat) and ``dashboard_gateway`` are never stalled by it.
    Loading on the robot's thread stalls all three for the whole load (the load's time, 1.5-2 s here).

    A shared machine delays ticks now and then with no map loading at all (the other processes' CPU time:
    on a 2-core machine running other test suites, starts up to a few hundred ms late were measured
    without any load): a component starting late by less than half the load's time is that, not a stall.
    """
    robot, gateway = make_robot(tmp_path / "data", realtime=True, clock=WallClock())
    MapStore(tmp_path / "data").save("big", grid_map(1900))
    maps, scheduler = robot.parts.maps, robot.scheduler
    threads: dict[str, set[str]] = {"prepare": set(), "swap": set()}
    real_prepare, real_swap = maps.prepare, maps.swap

    def prepare(name: str, grid: OccupancyMap | None = None) -> Any:
        threads["prepare"].add(threading.current_thread().name)
        return real_prepare(name, grid)

    def swap(prepared: Any, *, persist: bool = True) -> Any:
        threads["swap"].add(threading.current_thread().name)
        return real_swap(prepared, persist=persist)

    maps.prepare, maps.swap = prepare, swap  # type: ignore[method-assign]  # spies on this robot only
    with robot:
        boot(robot)
        scheduler.overruns.clear()
        run_thread = threading.Thread(target=robot.run, kwargs={"duration": 120.0}, name="robot-scheduler")
        run_thread.start()
        try:
            time.sleep(0.5)
            start = robot.clock.now()
            result = gateway.select_map("big")
            for _ in range(6000):
                if maps.active_name == "big":
                    break
                time.sleep(0.01)
            ready = robot.clock.now()
            time.sleep(0.5)  # the ticks after the swap count too
        finally:
            robot.stop()
            run_thread.join(30)
        end = robot.clock.now()
    gateway.close()
    assert result.ok, result.reason
    assert maps.active_name == "big" and maps.active is not None and maps.active.width == 1900
    assert threads["swap"] == {"robot-scheduler"}
    assert threads["prepare"] and "robot-scheduler" not in threads["prepare"]
    assert len(scheduler.overruns) < scheduler.max_overruns_kept  # every overrun of the window was kept
    watched = [o for o in scheduler.overruns if start <= o.due <= end
               and o.component in ("motion", "secondary_link", "dashboard_gateway")]
    load_s = ready - start
    summary = [(o.component, round(o.late_s * 1e3), round(o.cost_s * 1e3)) for o in watched]
    assert not [o for o in watched if o.component == "dashboard_gateway" and o.cost_s > o.period_s], (
        f"the pump took longer than its period while a {load_s:.2f} s load ran: {summary}")
    stalls = [o for o in watched if max(o.late_s, o.cost_s) >= 0.5 * load_s]
    assert not stalls, f"stalled while the map loaded for {load_s:.2f} s (component, late ms, cost ms): {summary}"
