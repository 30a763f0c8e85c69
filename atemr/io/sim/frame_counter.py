"""A frame number drawn into the simulated camera's image, so a viewer can tell which frame it shows.

Measuring video latency end to end (capture on the robot, display in a browser) needs to know, for the
picture on the screen, when it was captured. Timestamps in the stream do not survive every transport (an
MJPEG ``<img>`` has none the page can read), but the picture itself does: the frame number is drawn as a
row of black and white blocks in the top-left corner, big enough to survive JPEG and VP8/H.264 compression
and scaling, and read back by sampling the middle of each block (`read_counter` here; the benchmark's page
does the same on a canvas). A white block before the bits and a black one after them mark a picture that
carries a number at all, so a plain image reads as None rather than as a wrong number.

Layout, left to right on rows ``0 .. BLOCK_PX - 1``: white guard, `BITS` bits (most significant first, white
is 1), black guard; each block `BLOCK_PX` square. The number wraps at ``2 ** BITS`` (about 1.8 hours at
10 fps).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: Bits of the frame number.
BITS = 16
#: Side of one block in pixels (16 px survives a 640x480 frame scaled down to half and lossy coding).
BLOCK_PX = 16
#: Blocks in the row: the two guards and the bits.
BLOCKS = BITS + 2
WHITE = 255
BLACK = 0
#: A sampled block brighter than this reads as white, darker as black (the guards must be clearly so).
THRESHOLD = 128
GUARD_MARGIN = 64


def counter_width_px() -> int:
    """Width of the block row: the smallest image that can carry a number is this wide and `BLOCK_PX` high."""
    return BLOCKS * BLOCK_PX


def block_levels(number: int) -> NDArray[np.uint8]:
    """The grey level of each block (white guard, the bits of ``number`` modulo ``2 ** BITS``, black guard)."""
    n = number % (1 << BITS)
    bits = (n >> np.arange(BITS - 1, -1, -1)) & 1
    return np.concatenate(([WHITE], np.where(bits == 1, WHITE, BLACK), [BLACK])).astype(np.uint8)


def draw_counter(image: NDArray[np.uint8], number: int) -> None:
    """Draw ``number`` into the top-left corner of ``image`` (H x W x 3 uint8, changed in place)."""
    height, width = image.shape[:2]
    if height < BLOCK_PX or width < counter_width_px():
        raise ValueError(f"a {width}x{height} image is too small for the frame counter "
                         f"({counter_width_px()}x{BLOCK_PX} px)")
    row = np.repeat(block_levels(number), BLOCK_PX)
    image[:BLOCK_PX, :counter_width_px()] = row[None, :, None]


def read_counter(image: NDArray[np.uint8]) -> int | None:
    """The number drawn by `draw_counter` into ``image`` (H x W x 3 or H x W), or None when the guards are
    not there (no counter, or a picture too damaged to trust)."""
    height, width = image.shape[:2]
    if height < BLOCK_PX or width < counter_width_px():
        return None
    grey = image if image.ndim == 2 else image[..., :3].mean(axis=2)
    quarter = BLOCK_PX // 4
    middle = grey[quarter:BLOCK_PX - quarter, :counter_width_px()].astype(np.float64)
    levels = middle.reshape(middle.shape[0], BLOCKS, BLOCK_PX)[:, :, quarter:BLOCK_PX - quarter].mean(axis=(0, 2))
    if levels[0] < THRESHOLD + GUARD_MARGIN or levels[-1] > THRESHOLD - GUARD_MARGIN:
        return None
    bits = (levels[1:-1] >= THRESHOLD).astype(np.int64)
    return int((bits << np.arange(BITS - 1, -1, -1)).sum())


def read_counter_js() -> str:
    """`read_counter` as a JavaScript function ``(element) => number | null`` over an ``<img>`` or ``<video>``
    (drawn to a canvas), for a browser test or benchmark to pass to Playwright's ``evaluate``: the page
    shows the picture, and this reads which frame it is, with the same layout and thresholds."""
    q = BLOCK_PX // 4
    return f"""(el) => {{
  const B = {BLOCK_PX}, N = {BLOCKS}, Q = {q};
  const w = el.videoWidth || el.naturalWidth, h = el.videoHeight || el.naturalHeight;
  if (!w || !h || w < B * N || h < B) return null;
  const c = document.createElement("canvas");
  c.width = B * N; c.height = B;
  const g = c.getContext("2d", {{ willReadFrequently: true }});
  g.drawImage(el, 0, 0, B * N, B, 0, 0, B * N, B);
  const d = g.getImageData(0, 0, B * N, B).data;
  const level = (i) => {{
    let sum = 0, n = 0;
    for (let y = Q; y < B - Q; y++) for (let x = i * B + Q; x < (i + 1) * B - Q; x++) {{
      const p = (y * B * N + x) * 4; sum += (d[p] + d[p + 1] + d[p + 2]) / 3; n++;
    }}
    return sum / n;
  }};
  if (level(0) < {THRESHOLD + GUARD_MARGIN} || level(N - 1) > {THRESHOLD - GUARD_MARGIN}) return null;
  let v = 0;
  for (let i = 1; i < N - 1; i++) v = v * 2 + (level(i) >= {THRESHOLD} ? 1 : 0);
  return v;
}}"""
