"""Map store: list, save, select (persisted), delete, built-in default map, validated uploads."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from atemr.domain.maps import OccupancyMap
from atemr.errors import ConfigError
from atemr.io.map_store import DEFAULT_MAP, MapStore, clean_name
from atemr.msgs import Pose2D


def small_map(value: int = 0) -> OccupancyMap:
    data = np.full((10, 12), value, dtype=np.int8)
    data[0, :] = 100
    data[5, 3] = -1
    return OccupancyMap(data, 0.1, Pose2D(-1.0, -0.5, 0.0), name="small")


def pgm_bytes(pixels: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(pixels.astype(np.uint8)).save(buf, format="PPM")
    return buf.getvalue()


GOOD_YAML = b"image: room.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n" \
            b"free_thresh: 0.196\n"


def stored_files(store: MapStore) -> list[str]:
    return sorted(p.name for p in store.dir.iterdir())


def test_default_map_is_builtin_and_active(tmp_path: Path) -> None:
    store = MapStore(tmp_path)
    assert store.dir == tmp_path / "maps" and store.dir.is_dir()
    assert store.names() == [DEFAULT_MAP]
    assert store.active_name() == DEFAULT_MAP
    grid = store.active_map()
    assert grid is not None and grid.occupied.any()
    with pytest.raises(ConfigError, match="built-in"):
        store.delete(DEFAULT_MAP)
    with pytest.raises(ConfigError, match="built-in"):
        store.save(DEFAULT_MAP, small_map())


def test_save_list_select_persist_delete(tmp_path: Path) -> None:
    store = MapStore(tmp_path)
    assert store.save("Kitchen map", small_map()) == "Kitchen_map"
    assert (store.dir / "Kitchen_map.yaml").is_file() and (store.dir / "Kitchen_map.pgm").is_file()
    loaded = store.load("Kitchen_map")
    assert np.array_equal(loaded.data, small_map().data) and loaded.origin == Pose2D(-1.0, -0.5, 0.0)
    with pytest.raises(ConfigError, match="already exists"):
        store.save("Kitchen_map", small_map())
    store.save("Kitchen_map", small_map(), overwrite=True)
    store.select("Kitchen_map")
    again = MapStore(tmp_path)  # a restart
    assert again.active_name() == "Kitchen_map"
    listed = [(i.name, i.builtin, i.active) for i in again.list()]
    assert listed == [("studio", True, False), ("Kitchen_map", False, True)]
    again.delete("Kitchen_map")
    assert stored_files(again) == ["active"]
    assert again.active_name() == DEFAULT_MAP  # the deleted active map falls back to the default
    with pytest.raises(ConfigError, match="no map named"):
        again.select("Kitchen_map")
    with pytest.raises(ConfigError, match="no map named"):
        again.load("../maps/Kitchen_map")


@pytest.mark.parametrize("bad", ["", "../", "...", "/", "a" * 65])
def test_bad_names_are_refused(bad: str) -> None:
    with pytest.raises(ConfigError, match="invalid map name"):
        clean_name(bad)


def test_names_are_made_safe() -> None:
    assert clean_name("../../etc/passwd") == "etc_passwd"
    assert clean_name("my map.yaml") == "my_map"


def test_upload_valid_map(tmp_path: Path) -> None:
    store = MapStore(tmp_path)
    pixels = np.full((20, 30), 254)
    pixels[0, :] = 0
    name = store.upload({"room.yaml": GOOD_YAML, "room.pgm": pgm_bytes(pixels)})
    assert name == "room" and store.names() == ["studio", "room"]
    grid = store.load("room")
    assert grid.data.shape == (20, 30) and grid.occupied[-1].all()  # image row 0 is the top of the map
    assert stored_files(store) == ["room.pgm", "room.yaml"]  # nothing left of the staging directory


PGM = pgm_bytes(np.full((4, 4), 254))


@pytest.mark.parametrize(("files", "message"), [
    ({"room.yaml": GOOD_YAML}, "must be one of the uploaded files"),
    ({"room.yaml": GOOD_YAML, "room.pgm": b"not an image"}, "not an image"),
    ({"room.pgm": b"P5"}, "exactly one .yaml"),
    ({"a.yaml": GOOD_YAML, "b.yaml": GOOD_YAML}, "exactly one .yaml"),
    ({"room.yaml": GOOD_YAML.replace(b"room.pgm", b"/etc/hostname")}, "must be one of the uploaded files"),
    ({"room.yaml": GOOD_YAML.replace(b"room.pgm", b"../maps/x.pgm")}, "must be one of the uploaded files"),
    ({"room.yaml": GOOD_YAML.replace(b"0.196", b"0.9"), "room.pgm": PGM}, "free_thresh"),
    ({"room.yaml": b"image: room.pgm\nresolution: 0.05\n", "room.pgm": PGM}, "missing required key"),
    ({"room.yaml": b"!!python/object:os.system {}\n", "room.pgm": PGM}, "python"),
    ({"room.yaml": GOOD_YAML + b"colour: red\n", "room.pgm": PGM}, "unknown key"),
])
def test_bad_upload_is_refused_and_nothing_stored(tmp_path: Path, files: dict[str, bytes], message: str) -> None:
    store = MapStore(tmp_path)
    store.select(DEFAULT_MAP)
    before = stored_files(store)
    with pytest.raises(ConfigError, match=message) as err:
        store.upload(files)
    assert ".upload-" not in str(err.value)  # the message names the uploaded file, not the staging path
    assert stored_files(store) == before and store.names() == [DEFAULT_MAP]


def test_upload_limits(tmp_path: Path) -> None:
    store = MapStore(tmp_path, max_upload_bytes=100)
    with pytest.raises(ConfigError, match="larger than the limit"):
        store.upload({"room.yaml": GOOD_YAML, "room.pgm": b"x" * 200})
    store = MapStore(tmp_path)
    with pytest.raises(ConfigError, match="built-in"):
        store.upload({"studio.yaml": GOOD_YAML, "room.pgm": pgm_bytes(np.zeros((3, 3)))})


def test_upload_of_a_map_from_another_robot(tmp_path: Path, shared_dir: Path) -> None:
    """A Nav2 map (its own YAML and PGM, as published) uploads as it is and saves back in map_server format."""
    src = shared_dir / "worlds" / "external"
    yaml_path = src / "nav2_depot.yaml"
    if not yaml_path.is_file():
        pytest.skip(f"{yaml_path} is not there")
    from atemr.yamlsafe import load_yaml

    image = load_yaml(yaml_path)["image"]
    store = MapStore(tmp_path)
    name = store.upload({yaml_path.name: yaml_path.read_bytes(), image: (src / image).read_bytes()}, name="depot")
    grid = store.load(name)
    assert (grid.width, grid.height, grid.resolution_m) == (604, 307, 0.05)
