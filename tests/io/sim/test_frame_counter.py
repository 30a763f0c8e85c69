"""The frame number drawn into the simulated camera's image: it reads back exactly, survives JPEG, and a
picture without one reads as None."""

import io

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from PIL import Image

from atemr.errors import ConfigError
from atemr.io.sim.camera import CameraParams
from atemr.io.sim.frame_counter import BITS, BLOCK_PX, counter_width_px, draw_counter, read_counter
from atemr.io.sim.simulation import SimParams, build_simulation


def noise(seed: int, height: int = 480, width: int = 640) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (height, width, 3), dtype=np.uint8)


@given(st.integers(min_value=0, max_value=(1 << BITS) - 1), st.integers(min_value=0, max_value=1000))
def test_a_number_drawn_reads_back(number, seed):
    image = noise(seed)
    draw_counter(image, number)
    assert read_counter(image) == number


def test_the_number_wraps_and_only_the_corner_changes():
    image = noise(1)
    before = image.copy()
    draw_counter(image, (1 << BITS) + 7)
    assert read_counter(image) == 7
    assert np.array_equal(image[BLOCK_PX:], before[BLOCK_PX:])
    assert np.array_equal(image[:, counter_width_px():], before[:, counter_width_px():])


@pytest.mark.parametrize("quality", [30, 75])
def test_it_survives_jpeg_and_scaling(quality):
    image = noise(2)
    draw_counter(image, 40_321)
    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="JPEG", quality=quality)
    decoded = np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGB"))
    assert read_counter(decoded) == 40_321
    grey_half = np.asarray(Image.fromarray(decoded).resize((640, 480)).convert("L"))
    assert read_counter(grey_half) == 40_321


@given(st.integers(min_value=0, max_value=10_000))
def test_a_picture_without_a_counter_reads_none(seed):
    image = noise(seed)
    image[:BLOCK_PX, :BLOCK_PX] = 40  # no white guard where it belongs
    assert read_counter(image) is None
    assert read_counter(np.full((480, 640, 3), 255, np.uint8)) is None  # white everywhere: no black guard


def test_too_small_an_image_is_refused():
    with pytest.raises(ValueError, match="too small"):
        draw_counter(np.zeros((BLOCK_PX, counter_width_px() - 1, 3), np.uint8), 1)
    assert read_counter(np.zeros((8, 8, 3), np.uint8)) is None


def test_the_simulated_camera_numbers_its_frames(make_world, ideal_wheels):
    sim = build_simulation(make_world("start: [1.0, 2.0, 0.0]\n", width_m=6.0), 0,
                           params=SimParams(camera_hz=10, camera_counter=True), wheels=ideal_wheels)
    for expected in (1, 2, 3):
        sim.camera_source.tick(0.1 * expected)
        assert sim.camera_source.latest is not None
        assert read_counter(sim.camera_source.latest) == expected
    plain = build_simulation(make_world("start: [1.0, 2.0, 0.0]\n", width_m=6.0), 0,
                             params=SimParams(camera_hz=10), wheels=ideal_wheels)
    plain.camera_source.tick(0.1)
    assert read_counter(plain.camera_source.latest) is None


def test_the_counter_needs_a_wide_enough_camera():
    with pytest.raises(ConfigError, match="frame counter"):
        SimParams(camera=CameraParams(width=160, height=120), camera_hz=10, camera_counter=True)
