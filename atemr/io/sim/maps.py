"""Occupancy-grid maps in the ROS map_server format: ``name.yaml`` + an image (PGM, PNG, ...).

This is the one reader and writer of maps in the package: the simulator loads its worlds with it,
navigation and localization use the `OccupancyMap` it returns (the type itself is `atemr.domain.maps`, so
skills need not import this module), and the map store saves with `save_map` so maps made here open in ROS
tools and maps made by other robots load here unchanged.

The YAML keys are those of map_server: ``image`` (relative to the YAML), ``resolution`` (m/cell),
``origin`` ([x, y, yaw] of the lower-left pixel), ``occupied_thresh``, ``free_thresh``, ``negate`` and the
optional ``mode`` (``trinary`` by default, ``scale`` or ``raw``). Pixel values are turned into cell
values exactly as map_server does: 100 occupied, 0 free, -1 unknown (and 1..99 in ``scale`` mode).

Reading is bounded: an image's size is read from its header and refused above a number of cells
(``max_cells``: the map store passes ``ui.max_map_cells``, 4 M by default; never more than `MAX_CELLS`)
before a single pixel is decoded, so a small compressed file that claims 7000 x 7000 pixels costs a
header read, not gigabytes. Pillow's own guard (``Image.MAX_IMAGE_PIXELS``) stays on, and its
`DecompressionBombWarning` is an error in this process (see below), refused like any unreadable image.
"""

from __future__ import annotations

import difflib
import math
import warnings
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from numpy.typing import NDArray
from PIL import Image, UnidentifiedImageError

from atemr.domain.maps import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from atemr.errors import ConfigError, brief, brief_text
from atemr.msgs import Pose2D
from atemr.yamlsafe import load_yaml, mark_of

MapMode = Literal["trinary", "scale", "raw"]
#: Largest map ever accepted, in cells (a 100 m x 100 m map at 2 cm is 25 M cells): the ceiling of
#: ``ui.max_map_cells`` and the limit of maps read without one (worlds, `load_map` by default).
MAX_CELLS = 50_000_000
#: Largest map the robot's map store reads (uploads, stored maps): ``ui.max_map_cells``' default, 2000 x 2000
#: cells (100 m x 100 m at 5 cm).
DEFAULT_MAX_MAP_CELLS = 4_000_000

# Pillow decodes an image of between MAX_IMAGE_PIXELS and twice that many pixels with only a warning; a map
# reader has no use for one (`MAX_CELLS` is far below), so here the warning is an error, refused as such.
warnings.filterwarnings("error", category=Image.DecompressionBombWarning)

_REQUIRED = ("image", "resolution", "origin", "occupied_thresh", "free_thresh", "negate")
_KNOWN = (*_REQUIRED, "mode")


# -- loading ---------------------------------------------------------------------------------
def read_yaml(path: Path) -> Any:
    """`load_yaml`, plus the reader errors it lets through (control characters raise before parsing)."""
    try:
        return load_yaml(path)
    except yaml.YAMLError as exc:
        raise ConfigError(f"invalid YAML: {exc}", file=str(path)) from None


def _number(doc: Any, key: str, file: str) -> float:
    value = doc[key]
    line, col = mark_of(doc, key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"expected a finite number, got {brief(value)}", file=file, line=line, column=col,
                          path=key)
    return float(value)


def _fail(message: str, doc: Any, key: str, file: str) -> ConfigError:
    line, col = mark_of(doc, key)
    return ConfigError(message, file=file, line=line, column=col, path=key)


def load_map(path: str | Path, *, max_cells: int = MAX_CELLS) -> OccupancyMap:
    """Read a map_server YAML and its image into an `OccupancyMap`.

    Every problem (missing or unreadable image, thresholds out of order, an origin that is not three
    numbers, a file that is not an image, unknown keys, an image of more than ``max_cells`` pixels, or
    than `MAX_CELLS`) raises `ConfigError` naming the file, line and key. Values quoted in a message are
    cut short (`atemr.errors.brief`).
    """
    path = Path(path)
    file = str(path)
    doc = read_yaml(path)
    if not isinstance(doc, dict):
        raise ConfigError(f"expected a map_server mapping ({', '.join(_REQUIRED)}), got {type(doc).__name__}",
                          file=file)
    for key in doc:
        if key not in _KNOWN:
            name = str(key)
            close = difflib.get_close_matches(name, _KNOWN, n=1) if len(name) <= 64 else []
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            line, col = mark_of(doc, key)
            raise ConfigError(f"unknown key {brief(name)}{hint}; known keys: {', '.join(_KNOWN)}",
                              file=file, line=line, column=col, path=brief_text(name, 40))
    missing = [k for k in _REQUIRED if k not in doc]
    if missing:
        raise ConfigError(f"missing required key(s): {', '.join(missing)}", file=file)

    resolution = _number(doc, "resolution", file)
    if resolution <= 0:
        raise _fail(f"must be > 0 m per cell, got {resolution}", doc, "resolution", file)
    origin_raw = doc["origin"]
    if (
        not isinstance(origin_raw, list) or len(origin_raw) != 3
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in origin_raw)
    ):
        raise _fail(f"expected three numbers [x, y, yaw], got {brief(origin_raw)}", doc, "origin", file)
    occ = _number(doc, "occupied_thresh", file)
    free = _number(doc, "free_thresh", file)
    if not 0.0 <= occ <= 1.0:
        raise _fail(f"must be within [0, 1], got {occ}", doc, "occupied_thresh", file)
    if not 0.0 <= free <= 1.0:
        raise _fail(f"must be within [0, 1], got {free}", doc, "free_thresh", file)
    if free >= occ:
        raise _fail(f"must be below occupied_thresh ({occ}), got {free}", doc, "free_thresh", file)
    negate = doc["negate"]
    if negate not in (0, 1) or isinstance(negate, float):
        raise _fail(f"expected 0 or 1 (or true/false), got {brief(negate)}", doc, "negate", file)
    mode = doc.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        raise _fail(f"expected one of 'trinary', 'scale', 'raw', got {brief(mode)}", doc, "mode", file)
    image_name = doc["image"]
    if not isinstance(image_name, str) or not image_name:
        raise _fail(f"expected an image file name, got {brief(image_name)}", doc, "image", file)
    image_path = Path(image_name) if Path(image_name).is_absolute() else path.parent / image_name

    gray, alpha = _read_image(image_path, doc, file, min(max_cells, MAX_CELLS))
    data = pixels_to_occupancy(gray, alpha, occupied_thresh=occ, free_thresh=free, negate=bool(negate), mode=mode)
    return OccupancyMap(
        data, resolution, Pose2D(*(float(v) for v in origin_raw)), occ, free, name=path.stem,
    )


def header_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from the header of a PNG, PGM/PPM/PBM or BMP file, without decoding it; None for
    another format or a header that cannot be read (Pillow then reads it, lazily, and is asked again)."""
    try:
        with open(path, "rb") as f:
            head = f.read(512)
    except OSError:
        return None
    if head.startswith(b"\x89PNG\r\n\x1a\n") and head[12:16] == b"IHDR" and len(head) >= 24:
        return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    if head[:2] in (b"P1", b"P2", b"P3", b"P4", b"P5", b"P6"):
        numbers: list[int] = []
        for line in head[2:].split(b"\n"):
            for token in line.split(b"#", 1)[0].split():
                if not token.isdigit():
                    return None
                numbers.append(int(token))
                if len(numbers) == 2:
                    return numbers[0], numbers[1]
        return None
    if head.startswith(b"BM") and len(head) >= 26:
        if int.from_bytes(head[14:18], "little") == 12:  # OS/2 1.x: 16-bit sizes
            return int.from_bytes(head[18:20], "little"), int.from_bytes(head[20:22], "little")
        return (abs(int.from_bytes(head[18:22], "little", signed=True)),
                abs(int.from_bytes(head[22:26], "little", signed=True)))
    return None


def _shown(image_path: Path) -> str:
    return brief_text(str(image_path), 300)


def _too_large(image_path: Path, size: tuple[int, int], max_cells: int) -> str | None:
    width, height = size
    if width * height <= max_cells:
        return None
    setting = " (ui.max_map_cells)" if max_cells < MAX_CELLS else ""
    return (f"image {_shown(image_path)} is too large: {width} x {height} = {width * height:,} cells, more than the "
            f"limit of {max_cells:,}{setting}; refused without decoding it")


def _read_image(image_path: Path, doc: Any, file: str,
                max_cells: int = MAX_CELLS) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None]:
    """The image as grey levels 0..255 (float, mean of the colour channels as map_server) and transparency.

    Its size is checked against ``max_cells`` from the header, before Pillow is asked (PNG, PNM, BMP), and
    again once Pillow has opened it (lazily: nothing decoded yet), before it is decoded."""
    shown = _shown(image_path)
    size = header_size(image_path)
    if size is not None and (why := _too_large(image_path, size, max_cells)) is not None:
        raise _fail(why, doc, "image", file)
    try:
        with Image.open(image_path) as img:
            if (why := _too_large(image_path, img.size, max_cells)) is not None:
                raise _fail(why, doc, "image", file)
            img.load()
            if img.mode in ("I;16", "I;16B", "I;16L", "I"):
                arr = np.asarray(img, dtype=np.float64)
                peak = 65535.0 if arr.max(initial=0) > 255 else 255.0
                return arr * (255.0 / peak), None
            has_alpha = "A" in img.mode or "transparency" in img.info
            if img.mode == "L" and not has_alpha:  # the usual map: no RGBA copy needed
                return np.asarray(img, dtype=np.float64), None
            rgba = np.asarray(img.convert("RGBA"))
            gray = rgba[..., :3].sum(axis=2, dtype=np.uint16) / 3.0
            return gray, (rgba[..., 3] < 255) if has_alpha else None
    except FileNotFoundError:
        raise _fail(f"image file not found: {shown}", doc, "image", file) from None
    except IsADirectoryError:
        raise _fail(f"image path is a directory: {shown}", doc, "image", file) from None
    except UnidentifiedImageError:
        raise _fail(f"not an image file (PGM, PNG, ...): {shown}", doc, "image", file) from None
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:  # Pillow's own guard
        raise _fail(f"image {shown} is too large: {brief_text(str(exc), 160)}", doc, "image", file) from None
    except (OSError, SyntaxError, ValueError) as exc:
        raise _fail(f"cannot read image {shown}: {brief_text(str(exc), 160)}", doc, "image", file) from None


def pixels_to_occupancy(
    gray: NDArray[np.float64],
    alpha: NDArray[np.bool_] | None = None,
    *,
    occupied_thresh: float,
    free_thresh: float,
    negate: bool = False,
    mode: MapMode = "trinary",
) -> NDArray[np.int8]:
    """Convert image grey levels (row 0 = top of the image) to a ROS grid (row 0 = bottom), as map_server.

    ``p = (255 - v) / 255`` (or ``v / 255`` when negated) is the occupancy probability: above
    ``occupied_thresh`` → 100, below ``free_thresh`` → 0, else unknown (-1) in trinary mode or a scaled
    1..99 in scale mode; ``raw`` copies the value. Transparent pixels are unknown.
    """
    v = 255.0 - gray if negate else gray
    if mode == "raw":
        out = np.clip(np.rint(v), -1, 127).astype(np.int8)
    else:
        p = (255.0 - v) / 255.0
        out = np.full(p.shape, UNKNOWN, dtype=np.int8)
        if mode == "scale":
            ratio = (p - free_thresh) / (occupied_thresh - free_thresh)
            out = np.clip(np.rint(1 + 98 * ratio), 1, 99).astype(np.int8)
        out[p > occupied_thresh] = OCCUPIED
        out[p < free_thresh] = FREE
        if alpha is not None:
            out[alpha] = UNKNOWN
    return np.ascontiguousarray(out[::-1])


# -- saving ----------------------------------------------------------------------------------
def save_map(grid: OccupancyMap, path: str | Path, *, image_format: Literal["pgm", "png"] = "pgm") -> Path:
    """Write ``grid`` as ``path`` (the YAML) plus ``<stem>.pgm`` beside it, as ROS map_saver does.

    Trinary output: occupied 0 (black), free 254 (white), unknown 205 (grey), thresholds 0.65 / 0.196 (205
    reads as p = 0.19608, just above free_thresh: unknown, as map_saver intends).
    Returns the YAML path. Writes the image first and the YAML last, each to a temporary name renamed
    into place, so a reader never sees a YAML whose image is missing or half written.
    """
    path = Path(path)
    if path.suffix != ".yaml":
        path = path.with_suffix(".yaml")
    image_path = path.with_suffix(f".{image_format}")
    pixels = np.full(grid.data.shape, 205, dtype=np.uint8)
    pixels[grid.free] = 254
    pixels[grid.occupied] = 0
    tmp_image = image_path.with_name(image_path.name + ".tmp")
    pil_format = "PPM" if image_format == "pgm" else "PNG"  # Pillow writes PGM through its PPM plugin
    Image.fromarray(np.ascontiguousarray(pixels[::-1])).save(tmp_image, format=pil_format)
    tmp_image.replace(image_path)
    o = grid.origin
    text = (
        f"image: {image_path.name}\n"
        f"mode: trinary\n"
        f"resolution: {grid.resolution_m!r}\n"
        f"origin: [{o.x_m!r}, {o.y_m!r}, {o.yaw_rad!r}]\n"
        f"negate: 0\n"
        f"occupied_thresh: 0.65\n"
        f"free_thresh: 0.196\n"
    )
    tmp_yaml = path.with_name(path.name + ".tmp")
    tmp_yaml.write_text(text, encoding="utf-8")
    tmp_yaml.replace(path)
    return path


def is_map_document(doc: Any) -> bool:
    """Whether a loaded YAML document looks like a map_server map (rather than a world file)."""
    return isinstance(doc, dict) and "image" in doc and "resolution" in doc
