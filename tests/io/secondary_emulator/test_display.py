"""The 128×64 display: PNG and text renderings of a screen's content."""

from __future__ import annotations

import io

import pytest
from PIL import Image

from atemr.io.secondary_emulator.display import (
    COLUMNS,
    HEIGHT,
    WIDTH,
    Screen,
    render_image,
    render_pixels,
    render_png,
    render_text,
)


def png_size(data: bytes) -> tuple[int, int]:
    with Image.open(io.BytesIO(data)) as img:
        assert img.format == "PNG"
        return img.size


def test_png_is_128_by_64() -> None:
    screen = Screen("SC CORE", ("", "Ready !!"), logo=True)
    assert png_size(render_png(screen)) == (WIDTH, HEIGHT) == (128, 64)
    assert png_size(render_png(screen, scale=4, color=True)) == (512, 256)
    assert png_size(render_png(screen, scale=2)) == (256, 128)
    with pytest.raises(ValueError):
        render_png(screen, scale=0)


def test_title_band_is_lit_and_body_dark_where_empty() -> None:
    img = render_image(Screen("X"))
    assert img.mode == "1" and img.size == (128, 64)
    assert img.getpixel((0, 0)) and img.getpixel((127, 10))
    assert not any(img.getpixel((x, y)) for x in range(128) for y in range(20, 64))


def test_text_appears_in_the_pixels() -> None:
    blank = render_image(Screen("T"))
    text = render_image(Screen("T", ("HELLO",)))
    diff = [(x, y) for x in range(128) for y in range(16, 64) if blank.getpixel((x, y)) != text.getpixel((x, y))]
    assert diff and min(y for _, y in diff) >= 16 and max(x for x, _ in diff) < 6 * 5


def test_text_rendering() -> None:
    screen = Screen("POWER ON", ("Input received.", "Powering on the", "primary core..."), progress=0.5)
    assert render_text(screen) == "\n".join([
        "+---------------------+",
        "|       POWER ON      |",
        "+---------------------+",
        "|Input received.      |",
        "|Powering on the      |",
        "|primary core...      |",
        "|[##########.........]|",
        "+---------------------+",
    ])


def test_long_lines_are_cut_to_the_display() -> None:
    screen = Screen("T" * 40, ("x" * 40,) * 6)
    assert len(screen.title) == COLUMNS and len(screen.lines) == 4 and all(len(ln) == COLUMNS for ln in screen.lines)
    assert all(len(line) == COLUMNS + 2 for line in render_text(screen).splitlines())


def test_progress_clamped_and_logo_narrows_lines() -> None:
    assert Screen("T", progress=3.0).progress == 1.0 and Screen("T", progress=-1).progress == 0.0
    assert len(Screen("T", ("y" * 30,), logo=True).lines[0]) == COLUMNS - 7


def test_pixel_text_has_one_char_per_column_and_two_rows_per_line() -> None:
    rows = render_pixels(Screen("SC CORE", logo=True)).splitlines()
    assert len(rows) == 32 and all(len(r) == 128 for r in rows)
    assert rows[0] == "█" * 128
