"""Thumbnails of captured images and recorded videos, for the media page: made once, kept in a bounded cache.

A thumbnail is a small JPEG (at most `THUMB_SIZE`, twice the size shown so it is sharp on phones), made on
the first request for it, on the web request's thread (never the robot's): Pillow for images and for the
first JPEG of an old ``.mjpeg``, PyAV for the first frame of other videos. At most `MAX_MAKING` are made at
once, so a page of twenty previews cannot take every core of the robot.

The cache is ``data_dir/cache/thumbnails/``; a thumbnail's file name is made of a hash of the media's kind and
name and a hash of its size and modification time, so a file replaced under the same name gets a new one,
and deleting a medium finds its thumbnail. At most `MAX_THUMBNAILS` files are kept (the oldest made go first):
about 10 MB.

A file that cannot be previewed (damaged, cut short, not what its name says) gets a plain "no preview"
thumbnail, also cached, so the page shows a tile instead of a broken image and the file is not tried again
until it changes.
"""

from __future__ import annotations

import hashlib
import logging
import os
import secrets
import threading
from pathlib import Path

from PIL import Image, ImageDraw, ImageOps

from atemr.io.video_file import MAX_PREVIEW_PIXELS, VideoFileError, first_frame

log = logging.getLogger(__name__)

#: Largest thumbnail (width, height); the page shows them at half this size.
THUMB_SIZE = (320, 240)
#: Thumbnails kept at most.
MAX_THUMBNAILS = 500
#: Thumbnails made at the same time at most (the others wait).
MAX_MAKING = 2
JPEG_QUALITY = 80
#: Files read with Pillow (images, and the first frame of a Motion-JPEG video).
PILLOW_SUFFIXES = frozenset({".jpg", ".jpeg", ".png", ".mjpeg"})


def _digest(text: str, length: int) -> str:
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()[:length]


def preview(source: Path) -> Image.Image:
    """The picture a thumbnail is made from; `VideoFileError` saying why there is none."""
    if source.suffix.lower() not in PILLOW_SUFFIXES:
        return first_frame(source)
    try:
        with Image.open(source) as image:
            if image.width * image.height > MAX_PREVIEW_PIXELS:  # from the header, before decoding
                raise VideoFileError(f"{source.name} is {image.width}×{image.height}, too large to preview")
            image.draft("RGB", THUMB_SIZE)  # JPEG: decode at a reduced size, much cheaper
            return ImageOps.exif_transpose(image).convert("RGB")
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise VideoFileError(f"cannot read {source.name}: {exc}") from None


def no_preview() -> Image.Image:
    """The tile shown for a file that cannot be previewed."""
    width, height = THUMB_SIZE
    image = Image.new("RGB", (width, height), (60, 60, 60))
    draw = ImageDraw.Draw(image)
    left, top, right, bottom = draw.textbbox((0, 0), "no preview")
    draw.text(((width - right + left) // 2, (height - bottom + top) // 2), "no preview", fill=(220, 220, 220))
    return image


class Thumbnails:
    """The thumbnail cache in ``folder`` (see the module docstring)."""

    def __init__(self, folder: Path, max_files: int = MAX_THUMBNAILS) -> None:
        self.folder = folder
        self.max_files = max_files
        self._making = threading.BoundedSemaphore(MAX_MAKING)

    def _prefix(self, kind: str, name: str) -> str:
        return _digest(f"{kind}/{name}", 24)

    def path(self, kind: str, name: str, source: Path) -> Path:
        """Where the thumbnail of ``source`` (as it is now) is kept."""
        st = source.stat()
        return self.folder / f"{self._prefix(kind, name)}-{_digest(f'{st.st_size}/{st.st_mtime_ns}', 12)}.jpg"

    def get(self, kind: str, name: str, source: Path) -> Path:
        """The thumbnail of ``source`` (the medium ``name`` of ``kind``), made now if it is not cached."""
        target = self.path(kind, name, source)
        if target.is_file():
            return target
        with self._making:
            if target.is_file():  # made meanwhile by another request
                return target
            try:
                image = preview(source)
            except VideoFileError as exc:
                log.warning("no thumbnail for %s %s: %s", kind, name, exc)
                image = no_preview()
            image.thumbnail(THUMB_SIZE)
            self.folder.mkdir(parents=True, exist_ok=True)
            self._forget_other(target)
            part = target.with_name(f".{secrets.token_hex(8)}.part")
            try:
                image.save(part, format="JPEG", quality=JPEG_QUALITY)
                os.replace(part, target)
            finally:
                part.unlink(missing_ok=True)
            self._bound()
        return target

    def forget(self, kind: str, name: str) -> None:
        """Delete the thumbnails of a medium (it was deleted)."""
        if self.folder.is_dir():
            for old in self.folder.glob(f"{self._prefix(kind, name)}-*.jpg"):
                old.unlink(missing_ok=True)

    def _forget_other(self, target: Path) -> None:
        """Delete thumbnails of an earlier version of the same medium."""
        prefix = target.name.split("-", 1)[0]
        for old in self.folder.glob(f"{prefix}-*.jpg"):
            if old != target:
                old.unlink(missing_ok=True)

    def _bound(self) -> None:
        """Keep at most `max_files` thumbnails: the oldest made go."""
        entries = []
        for path in self.folder.glob("*.jpg"):
            try:
                entries.append((path.stat().st_mtime_ns, path))
            except OSError:  # deleted meanwhile
                continue
        if len(entries) <= self.max_files:
            return
        entries.sort()
        for _, path in entries[: len(entries) - self.max_files]:
            path.unlink(missing_ok=True)
