"""Named places: the domain type's rules, and places kept with their map through the store, an export and
an upload (issue 27)."""

from __future__ import annotations

import io
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from atemr.domain.places import Place, Places
from atemr.errors import ConfigError
from atemr.io.map_store import DEFAULT_MAP, MapStore
from atemr.msgs import Pose2D
from atemr.ui.media.files import MediaError, MediaStore

STUDIO_PLACES = ["home", "living room", "kitchen", "bedroom", "bathroom", "balcony door"]


def room_files() -> tuple[bytes, bytes]:
    pixels = np.full((40, 60), 254, dtype=np.uint8)
    pixels[0, :] = 0
    buf = io.BytesIO()
    Image.fromarray(pixels).save(buf, format="PPM")
    yaml = b"image: room.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n" \
           b"free_thresh: 0.196\n"
    return yaml, buf.getvalue()


def test_places_are_found_by_name_whatever_the_case_and_spacing() -> None:
    places = Places([Place("Mum's armchair", Pose2D(1, 2, 0)), Place("home", Pose2D(0, 0, 0), "dock")])
    assert places["mum's  ARMCHAIR"].name == "Mum's armchair"
    assert places.dock() == places["home"]
    with pytest.raises(ConfigError, match=r"no place named 'mums armchair' on this map \(closest: Mum's armchair\)"):
        places.find("mums armchair")
    with pytest.raises(ConfigError, match=r"places: Mum's armchair, home"):
        places.find("garage")


def test_a_refused_change_leaves_the_places_as_they_were() -> None:
    places = Places([Place("kitchen", Pose2D(1, 1, 0)), Place("hall", Pose2D(2, 2, 0))])
    with pytest.raises(ConfigError, match="exists already"):
        places.with_place(Place("Kitchen", Pose2D(5, 5, 0)))
    with pytest.raises(ConfigError, match="exists already"):
        places.renamed("hall", "KITCHEN")
    with pytest.raises(ConfigError, match="invalid place name"):
        places.renamed("hall", "  ")
    assert list(places) == ["kitchen", "hall"] and places["kitchen"].pose == Pose2D(1, 1, 0)
    moved = places.with_place(Place("kitchen", Pose2D(3, 3, 1)), replace=True).renamed("hall", "front door")
    assert list(moved) == ["kitchen", "front door"] and moved["kitchen"].pose == Pose2D(3, 3, 1)
    assert list(moved.without("front door")) == ["kitchen"]


@pytest.mark.parametrize(("items", "message"), [
    ([{"name": "a", "x_m": math.nan, "y_m": 0}], r"places\[0\]\.x_m.*finite"),
    ([{"name": "a", "y_m": 0}], r"places\[0\].*needs 'x_m'"),
    ([{"name": "a", "x_m": 0, "y_m": 0, "kind": "sofa"}], r"places\[0\]\.kind.*place, dock"),
    ([{"name": "a", "x_m": 0, "y_m": 0, "colour": 1}], r"places\[0\]\.colour.*unknown key"),
    ([{"name": "<script>", "x_m": 0, "y_m": 0}], r"places\[0\]\.name.*invalid place name"),
    ([{"name": "a", "x_m": 0, "y_m": 0}, {"name": "A", "x_m": 1, "y_m": 0}], "two places are named"),
    ({"name": "a"}, "a list"),
])
def test_bad_places_are_refused_saying_where(items: object, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        Places.from_json(items)


def test_the_studio_ships_a_place_for_each_room_and_its_dock(tmp_path: Path) -> None:
    store = MapStore(tmp_path)
    places = store.places(DEFAULT_MAP)
    assert list(places) == STUDIO_PLACES
    dock = places.dock()
    assert dock is not None and dock.name == "home" and dock.kind == "dock"
    grid = store.load(DEFAULT_MAP)
    for place in places.values():  # every place is on free floor of its map
        assert grid.value_at(place.pose.x_m, place.pose.y_m) == 0, place


def test_changes_to_a_builtin_maps_places_are_stored_in_the_data_directory(tmp_path: Path) -> None:
    store = MapStore(tmp_path)
    changed = store.places(DEFAULT_MAP).with_place(Place("front door", Pose2D(0.5, 6.5, 0.0)))
    store.save_places(DEFAULT_MAP, changed)
    assert (store.dir / "studio.places.yaml").is_file()
    assert store.names() == [DEFAULT_MAP]  # a places file is not a map
    assert MapStore(tmp_path).places(DEFAULT_MAP) == changed  # read back by a fresh store


def test_places_round_trip_through_the_store_an_export_and_an_upload(tmp_path: Path) -> None:
    robot = MediaStore(tmp_path / "robot")
    yaml, image = room_files()
    assert robot.upload_map("room.yaml", yaml, "room.pgm", image) == "room"
    assert robot.maps.places("room") == Places()
    places = Places([Place("Mum's armchair", Pose2D(1.25, 0.5, 1.571)),
                     Place("home", Pose2D(0.3, 0.4, -3.1), "dock")])
    robot.maps.save_places("room", places)
    assert MapStore(tmp_path / "robot").places("room") == places

    with zipfile.ZipFile(io.BytesIO(robot.map_zip("room.yaml"))) as zf:
        exported = {n: zf.read(n) for n in zf.namelist()}
    assert sorted(exported) == ["room.pgm", "room.places.yaml", "room.yaml"]

    other = MediaStore(tmp_path / "other")
    name = other.upload_map("room.yaml", exported["room.yaml"], "room.pgm", exported["room.pgm"],
                            exported["room.places.yaml"])
    assert name == "room" and other.maps.places("room") == places
    assert np.array_equal(other.maps.load("room").data, robot.maps.load("room").data)

    other.delete("maps", "room.yaml")  # the places go with their map
    assert sorted(p.name for p in other.maps.dir.iterdir()) == []


def test_an_upload_with_bad_places_stores_nothing(tmp_path: Path) -> None:
    media = MediaStore(tmp_path)
    yaml, image = room_files()
    bad = b"places:\n  - {name: kitchen, x_m: 1.0, y_m: .nan}\n"
    with pytest.raises(MediaError, match=r"room\.places\.yaml.*places\[0\]\.y_m.*finite"):
        media.upload_map("room.yaml", yaml, "room.pgm", image, bad)
    assert sorted(p.name for p in media.maps.dir.iterdir()) == []
    with pytest.raises(MediaError, match="one top-level key, 'places'"):
        media.upload_map("room.yaml", yaml, "room.pgm", image, b"kitchen: [1, 2]\n")
    assert sorted(p.name for p in media.maps.dir.iterdir()) == []
