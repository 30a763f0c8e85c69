"""The board's 128×64 monochrome OLED: a screen's content, drawn as pixels (PNG) or as text.

The real display is a two-colour SSD1306: rows 0–15 are yellow (the title, black text on a lit band),
rows 16–63 cyan (the body, lit text on black). A `Screen` is only content; `render_image` draws it with
Pillow's built-in 6×11 bitmap font (21 characters per line, four body lines), so what the dashboard
shows is what fits on the board. `render_text` draws the same content as a boxed block of text for
terminals and for tests that compare screens.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from functools import lru_cache

from PIL import Image, ImageDraw, ImageFont

WIDTH = 128
HEIGHT = 64
#: Rows of the yellow title band.
TITLE_ROWS = 16
#: Characters per line with the 6-pixel-wide font.
COLUMNS = WIDTH // 6
#: Body lines below the title band (12 pixels each).
BODY_LINES = 4
LINE_PX = 12
#: Width taken by the steering-wheel logo on the left of the body (pixels and characters).
LOGO_PX = 42
LOGO_COLUMNS = LOGO_PX // 6
#: The two colours of the real panel, for the colour rendering.
YELLOW = (255, 214, 0)
CYAN = (0, 230, 255)


@dataclass(frozen=True)
class Screen:
    """What the display shows: a title, up to four body lines, an optional progress bar and logo.

    Lines longer than the display are cut (the board cuts them too); ``progress`` in [0, 1] replaces
    the last body line with a bar; ``logo`` draws the steering wheel of the BOOT/READY screen on the
    left of the body, and the body text moves right to leave it room.
    """

    title: str
    lines: tuple[str, ...] = field(default_factory=tuple)
    progress: float | None = None
    logo: bool = False

    def __post_init__(self) -> None:
        width = COLUMNS - (LOGO_COLUMNS if self.logo else 0)
        object.__setattr__(self, "title", self.title[:COLUMNS])
        object.__setattr__(self, "lines", tuple(line[:width] for line in self.lines[:BODY_LINES]))
        if self.progress is not None:
            object.__setattr__(self, "progress", min(1.0, max(0.0, float(self.progress))))


@lru_cache(maxsize=1)
def _font() -> ImageFont.ImageFont:
    # The bitmap font shipped inside Pillow: the same pixels on every machine, no font files needed.
    return ImageFont.load_default_imagefont()


def _body_rows(screen: Screen) -> list[str | None]:
    """The four body rows: text, or None for the row the progress bar takes."""
    rows: list[str | None] = [*screen.lines, *([""] * (BODY_LINES - len(screen.lines)))]
    if screen.progress is not None:
        rows[BODY_LINES - 1] = None
    return rows


def render_image(screen: Screen) -> Image.Image:
    """The screen as the panel's pixels: a 128×64 1-bit image (lit pixels are 1)."""
    img = Image.new("1", (WIDTH, HEIGHT), 0)
    draw = ImageDraw.Draw(img)
    font = _font()
    draw.rectangle((0, 0, WIDTH - 1, TITLE_ROWS - 2), fill=1)
    title_w = int(draw.textlength(screen.title, font=font))
    draw.text(((WIDTH - title_w) // 2, 2), screen.title, font=font, fill=0)
    left = LOGO_PX if screen.logo else 0
    if screen.logo:
        _draw_wheel(draw, cx=LOGO_PX // 2 - 1, cy=TITLE_ROWS + (HEIGHT - TITLE_ROWS) // 2, r=20)
    for i, row in enumerate(_body_rows(screen)):
        y = TITLE_ROWS + 1 + i * LINE_PX
        if row is None:
            _draw_progress(draw, left, y + 2, screen.progress or 0.0)
        elif row:
            draw.text((left, y), row, font=font, fill=1)
    return img


def _draw_wheel(draw: ImageDraw.ImageDraw, *, cx: int, cy: int, r: int) -> None:
    """The steering wheel of the BOOT screen (the two cores steering the robot together)."""
    draw.ellipse((cx - r, cy - r, cx + r, cy + r), outline=1, width=3)
    hub = r // 4
    draw.ellipse((cx - hub, cy - hub, cx + hub, cy + hub), fill=1)
    draw.line((cx - r, cy, cx + r, cy), fill=1, width=2)
    draw.line((cx, cy, cx, cy + r), fill=1, width=2)


def _draw_progress(draw: ImageDraw.ImageDraw, left: int, y: int, progress: float) -> None:
    draw.rectangle((left + 2, y, WIDTH - 3, y + 7), outline=1)
    inner = round((WIDTH - 5 - (left + 3)) * progress)
    if inner > 0:
        draw.rectangle((left + 3, y + 1, left + 3 + inner - 1, y + 6), fill=1)


def render_color(screen: Screen, *, scale: int = 1) -> Image.Image:
    """The screen as it looks on the two-colour panel (yellow title rows, cyan body), scaled up by ``scale``."""
    mono = render_image(screen)
    rgb = Image.new("RGB", (WIDTH, HEIGHT), (0, 0, 0))
    yellow = Image.new("RGB", (WIDTH, HEIGHT), YELLOW)
    cyan = Image.new("RGB", (WIDTH, HEIGHT), CYAN)
    band = Image.new("1", (WIDTH, HEIGHT), 0)
    ImageDraw.Draw(band).rectangle((0, 0, WIDTH - 1, TITLE_ROWS - 1), fill=1)
    rgb.paste(cyan, mask=mono)
    rgb.paste(yellow, mask=Image.composite(mono, Image.new("1", (WIDTH, HEIGHT), 0), band))
    if scale > 1:
        rgb = rgb.resize((WIDTH * scale, HEIGHT * scale), Image.Resampling.NEAREST)
    return rgb


def render_png(screen: Screen, *, scale: int = 1, color: bool = False) -> bytes:
    """PNG bytes of the screen: monochrome at the panel's 128×64 by default, or coloured and scaled."""
    if scale < 1:
        raise ValueError(f"scale must be >= 1, got {scale}")
    img = render_color(screen, scale=scale) if color else render_image(screen)
    if not color and scale > 1:
        img = img.resize((WIDTH * scale, HEIGHT * scale), Image.Resampling.NEAREST)
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def render_text(screen: Screen) -> str:
    """The screen as a boxed text block of 21 columns: the title centred, then the four body rows.

    The logo is shown as ``(@)`` in its column band; the progress bar as ``[####....]``.
    """
    border = "+" + "-" * COLUMNS + "+"
    out = [border, "|" + screen.title.center(COLUMNS) + "|", border]
    for i, row in enumerate(_body_rows(screen)):
        prefix = ""
        if screen.logo:
            prefix = (" (@) " if i == 1 else "").ljust(LOGO_COLUMNS)
        width = COLUMNS - len(prefix)
        if row is None:
            filled = round((width - 2) * (screen.progress or 0.0))
            text = "[" + "#" * filled + "." * (width - 2 - filled) + "]"
        else:
            text = row.ljust(width)
        out.append("|" + prefix + text + "|")
    out.append(border)
    return "\n".join(out)


def render_pixels(screen: Screen) -> str:
    """The screen's pixels as text (two pixel rows per character with half blocks), for a terminal view."""
    img = render_image(screen)
    px = img.load()
    assert px is not None
    chars = {(0, 0): " ", (1, 0): "▀", (0, 1): "▄", (1, 1): "█"}
    rows = []
    for y in range(0, HEIGHT, 2):
        rows.append("".join(chars[(1 if px[x, y] else 0, 1 if px[x, y + 1] else 0)] for x in range(WIDTH)))
    return "\n".join(rows)
