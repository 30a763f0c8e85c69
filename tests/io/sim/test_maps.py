"""Map loading and saving in the ROS map_server format."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from atemr.domain.maps import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from atemr.errors import ConfigError
from atemr.io.sim.maps import load_map, pixels_to_occupancy, save_map
from atemr.msgs import Pose2D

STUDIO = Path(__file__).resolve().parents[3] / "atemr" / "worlds" / "studio" / "studio.yaml"

EXTERNAL = {
    # name: (width, height, resolution, origin)
    "nav2_depot": (604, 307, 0.05, (0.0, 0.0, 0.0)),
    "nav2_tb3_sandbox": (None, None, 0.05, (-10.0, -10.0, 0.0)),
    "nav2_warehouse": (None, None, 0.03, (-15.1, -25.0, 0.0)),
    "turtlebot3_world": (None, None, 0.05, (-10.0, -10.0, 0.0)),
}


def write_map(tmp_path: Path, yaml_text: str, pixels: np.ndarray | None = None, name: str = "m") -> Path:
    if pixels is not None:
        Image.fromarray(pixels.astype(np.uint8)).save(tmp_path / f"{name}.pgm", format="PPM")
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml_text)
    return path


GOOD = "image: m.pgm\nresolution: 0.1\norigin: [1.0, 2.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"


def test_studio_map_loads_at_5_cm():
    m = load_map(STUDIO)
    assert m.resolution_m == 0.05
    assert m.data.shape == (190, 200)
    assert m.occupied.any() and m.free.any() and m.unknown.any()
    # the living room centre is free, the west wall (x in [-0.15, 0]) occupied
    assert m.value_at(2.6, 2.6) == FREE
    assert m.value_at(-0.07, 2.6) == OCCUPIED


@pytest.mark.parametrize("name", sorted(EXTERNAL))
def test_external_maps_load_as_they_are(shared_dir, name):
    path = shared_dir / "worlds" / "external" / f"{name}.yaml"
    if not path.is_file():
        pytest.skip(f"{path} is not there")
    width, height, resolution, origin = EXTERNAL[name]
    m = load_map(path)
    with Image.open(path.with_suffix(".pgm")) as img:
        assert (m.width, m.height) == img.size
        top_left = np.asarray(img.convert("L"))[0, 0]
    if width is not None:
        assert (m.width, m.height) == (width, height)
    assert m.resolution_m == resolution
    assert (m.origin.x_m, m.origin.y_m, m.origin.yaw_rad) == origin
    # a real map has walls and free space, and the image's top row is the grid's last row
    assert 0.001 < m.occupied.mean() < 0.5
    assert m.free.mean() > 0.05
    expected = FREE if top_left >= 254 else (OCCUPIED if top_left <= 89 else m.data[-1, 0])
    assert m.data[-1, 0] == expected


def test_pixels_follow_map_server_rules():
    gray = np.array([[0, 100, 205, 254]], dtype=np.float64)
    out = pixels_to_occupancy(gray, occupied_thresh=0.65, free_thresh=0.196)
    assert out.tolist() == [[OCCUPIED, UNKNOWN, UNKNOWN, FREE]]
    neg = pixels_to_occupancy(gray, occupied_thresh=0.65, free_thresh=0.196, negate=True)
    assert neg.tolist() == [[FREE, UNKNOWN, OCCUPIED, OCCUPIED]]
    scale = pixels_to_occupancy(np.array([[128.0]]), occupied_thresh=0.65, free_thresh=0.196, mode="scale")
    assert 1 <= scale[0, 0] <= 99
    alpha = pixels_to_occupancy(np.array([[254.0]]), np.array([[True]]), occupied_thresh=0.65, free_thresh=0.2)
    assert alpha[0, 0] == UNKNOWN


def test_image_rows_are_flipped_so_row_0_is_the_bottom(tmp_path):
    pixels = np.full((4, 5), 254)
    pixels[0, 0] = 0  # top-left pixel of the image
    m = load_map(write_map(tmp_path, GOOD, pixels))
    assert m.data[3, 0] == OCCUPIED and m.data[0, 0] == FREE
    # that cell's centre in world coordinates: origin + (0.5, 3.5) cells
    assert m.world_to_cell(1.05, 2.35) == (3, 0)
    x, y = m.cell_to_world(3, 0)
    assert (float(x), float(y)) == pytest.approx((1.05, 2.35))


def test_save_then_load_gives_the_same_grid(tmp_path):
    rng = np.random.default_rng(0)
    data = rng.choice(np.array([FREE, OCCUPIED, UNKNOWN], dtype=np.int8), size=(30, 40))
    original = OccupancyMap(data, 0.05, Pose2D(-1.5, 2.25, 0.0), name="rt")
    path = save_map(original, tmp_path / "saved.yaml")
    assert (tmp_path / "saved.pgm").is_file()
    loaded = load_map(path)
    np.testing.assert_array_equal(loaded.data, original.data)
    assert loaded.resolution_m == 0.05
    assert loaded.origin == original.origin


@settings(max_examples=50, deadline=None)
@given(
    x=st.floats(-50, 50), y=st.floats(-50, 50), yaw=st.floats(-3.1, 3.1),
)
def test_world_cell_round_trip(x, y, yaw):
    m = OccupancyMap(np.zeros((10, 10), dtype=np.int8), 0.05, Pose2D(1.0, -2.0, yaw))
    row, col = m.world_to_cell(x, y)
    cx, cy = m.cell_to_world(row, col)
    # the cell centre is within half a cell diagonal of the point
    assert np.hypot(cx - x, cy - y) <= 0.05 * np.sqrt(2) / 2 + 1e-9


BAD = [
    ("image: nope.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.2\n",
     False, "image", "image file not found"),
    (GOOD.replace("free_thresh: 0.196", "free_thresh: 0.7"), True, "free_thresh", "below occupied_thresh"),
    (GOOD.replace("occupied_thresh: 0.65", "occupied_thresh: 1.5"), True, "occupied_thresh", "within [0, 1]"),
    (GOOD.replace("origin: [1.0, 2.0, 0.0]", "origin: [1.0, 2.0]"), True, "origin", "three numbers"),
    (GOOD.replace("origin: [1.0, 2.0, 0.0]", "origin: [a, 2.0, 0]"), True, "origin", "three numbers"),
    (GOOD.replace("resolution: 0.1", "resolution: -1"), True, "resolution", "> 0"),
    (GOOD.replace("negate: 0", "negate: 3"), True, "negate", "0 or 1"),
    (GOOD + "mode: fancy\n", True, "mode", "'trinary'"),
    (GOOD + "ocupied_thresh: 0.6\n", True, "ocupied_thresh", "did you mean 'occupied_thresh'"),
    (GOOD.replace("negate: 0\n", ""), True, None, "missing required key(s): negate"),
]


@pytest.mark.parametrize(("text", "with_image", "field", "message"), BAD)
def test_bad_maps_name_the_file_and_the_field(tmp_path, text, with_image, field, message):
    path = write_map(tmp_path, text, np.full((4, 4), 254) if with_image else None)
    with pytest.raises(ConfigError) as err:
        load_map(path)
    assert err.value.file == str(path)
    assert message in str(err.value)
    if field is not None:
        assert err.value.path == field
        assert err.value.line is not None


def test_a_non_image_file_is_refused(tmp_path):
    (tmp_path / "m.pgm").write_text("this is not an image")
    path = write_map(tmp_path, GOOD)
    with pytest.raises(ConfigError, match="not an image file") as err:
        load_map(path)
    assert err.value.path == "image" and err.value.line == 1


def test_a_missing_yaml_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="file not found"):
        load_map(tmp_path / "absent.yaml")


@settings(max_examples=60, deadline=None)
@given(blob=st.binary(max_size=300))
def test_random_image_bytes_only_ever_raise_config_error(tmp_path_factory, blob):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "m.pgm").write_bytes(b"P5\n4 4\n255\n" + blob if blob[:1] == b"\x00" else blob)
    path = d / "m.yaml"
    path.write_text(GOOD)
    try:
        m = load_map(path)
    except ConfigError as err:
        assert err.file == str(path)
    else:
        assert m.data.ndim == 2


@settings(max_examples=60, deadline=None)
@given(text=st.text(max_size=200))
def test_random_yaml_only_ever_raises_config_error(tmp_path_factory, text):
    d = tmp_path_factory.mktemp("fuzzy")
    path = d / "m.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError):
        load_map(path)
