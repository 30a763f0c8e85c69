"""The files the dashboard lists, serves and deletes: captured images, recorded videos and maps.

Layout under ``data_dir``: ``media/images/``, ``media/videos/`` and ``maps/`` (ROS map_server pairs,
``name.yaml`` + its image). Names coming from a browser go through `secure_filename` and every path
through `safe_join`, so nothing outside these directories can be read, written or deleted.
"""

from __future__ import annotations

import io
import shutil
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from werkzeug.security import safe_join
from werkzeug.utils import secure_filename

from atemr.errors import AtemrError, ConfigError
from atemr.yamlsafe import load_yaml

Kind = Literal["images", "videos", "maps"]
KINDS: tuple[Kind, ...] = ("images", "videos", "maps")
#: File types listed per kind (maps are listed by their YAML).
EXTENSIONS: dict[Kind, frozenset[str]] = {
    "images": frozenset({".jpg", ".jpeg", ".png"}),
    "videos": frozenset({".mp4", ".webm", ".avi", ".mjpeg", ".mkv"}),
    "maps": frozenset({".yaml", ".yml"}),
}
MAP_IMAGE_EXTENSIONS = frozenset({".pgm", ".png", ".bmp", ".jpg", ".jpeg", ".tif", ".tiff"})
PAGE_SIZE = 10


class MediaError(AtemrError):
    """A media request was refused: unknown kind, bad or unknown file name, invalid upload."""


@dataclass(frozen=True)
class MediaFile:
    """One listed file (for maps: the map's name, its YAML's size and time)."""

    kind: Kind
    name: str
    size_bytes: int
    modified: float

    def to_json(self) -> dict[str, object]:
        return {"kind": self.kind, "name": self.name, "size_bytes": self.size_bytes, "modified": self.modified}


def check_kind(kind: str) -> Kind:
    if kind not in KINDS:
        raise MediaError(f"unknown media kind {kind!r}: one of {', '.join(KINDS)}")
    return kind


class MediaStore:
    """Images, videos and maps under ``data_dir``."""

    def __init__(self, data_dir: Path) -> None:
        self.data_dir = Path(data_dir)
        self.dirs: dict[Kind, Path] = {
            "images": self.data_dir / "media" / "images",
            "videos": self.data_dir / "media" / "videos",
            "maps": self.data_dir / "maps",
        }

    def dir(self, kind: str) -> Path:
        path = self.dirs[check_kind(kind)]
        path.mkdir(parents=True, exist_ok=True)
        return path

    def path(self, kind: str, name: str) -> Path:
        """The file ``name`` of ``kind``; `MediaError` if the name is not a plain, listed file name."""
        folder = self.dir(kind)
        if not name or secure_filename(name) != name or Path(name).suffix.lower() not in EXTENSIONS[check_kind(kind)]:
            raise MediaError(f"not a valid {kind} file name: {name!r}")
        joined = safe_join(str(folder), name)
        if joined is None:
            raise MediaError(f"not a valid {kind} file name: {name!r}")
        path = Path(joined)
        if not path.is_file():
            raise MediaError(f"no such {kind[:-1]}: {name!r}")
        return path

    def newest(self, kind: str, offset: int = 0, limit: int = PAGE_SIZE) -> tuple[list[MediaFile], int]:
        """The files of ``kind``, newest first, ``limit`` of them from ``offset``; and the total count."""
        k = check_kind(kind)
        folder = self.dir(k)
        files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in EXTENSIONS[k]]
        stats = sorted(((p, p.stat()) for p in files), key=lambda ps: (ps[1].st_mtime, ps[0].name), reverse=True)
        page = stats[max(0, offset): max(0, offset) + max(0, limit)]
        return [MediaFile(k, p.name, st.st_size, st.st_mtime) for p, st in page], len(stats)

    # -- maps are pairs -------------------------------------------------------------------------------
    def map_files(self, yaml_path: Path) -> list[Path]:
        """The YAML and the image it names, when that image is a plain file beside it."""
        files = [yaml_path]
        try:
            doc = load_yaml(yaml_path)
        except ConfigError:
            return files
        image = doc.get("image") if isinstance(doc, dict) else None
        if isinstance(image, str) and image and secure_filename(image) == image:
            joined = safe_join(str(yaml_path.parent), image)
            if joined is not None and Path(joined).is_file():
                files.append(Path(joined))
        return files

    def map_zip(self, name: str) -> bytes:
        """A map's YAML and image as one zip, for download."""
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
            for path in self.map_files(self.path("maps", name)):
                zf.write(path, path.name)
        return buf.getvalue()

    # -- deleting -------------------------------------------------------------------------------------
    def delete(self, kind: str, name: str) -> list[str]:
        """Delete one file (a map with its image); returns the names deleted."""
        path = self.path(kind, name)
        targets = self.map_files(path) if kind == "maps" else [path]
        for target in targets:
            target.unlink(missing_ok=True)
        return [t.name for t in targets]

    def delete_all(self, kind: str) -> int:
        """Delete every listed file of ``kind``; returns how many were listed."""
        files, total = self.newest(kind, 0, 1_000_000)
        for f in files:
            self.delete(kind, f.name)
        return total

    # -- uploading maps -------------------------------------------------------------------------------
    def stage_map_upload(self, yaml_name: str, yaml_bytes: bytes, image_name: str, image_bytes: bytes) -> Path:
        """Write an uploaded map pair into a fresh staging directory (not yet listed) and return the
        staged YAML's path; the caller validates it, then `commit_map` or `discard_staged`."""
        yaml_safe = secure_filename(yaml_name)
        image_safe = secure_filename(image_name)
        if Path(yaml_safe).suffix.lower() not in EXTENSIONS["maps"]:
            raise MediaError(f"the map description must be a .yaml file, got {yaml_name!r}")
        if Path(image_safe).suffix.lower() not in MAP_IMAGE_EXTENSIONS:
            raise MediaError(
                f"the map image must be one of {', '.join(sorted(MAP_IMAGE_EXTENSIONS))}, got {image_name!r}"
            )
        if not yaml_bytes or not image_bytes:
            raise MediaError("both the map's YAML and its image are needed, and neither may be empty")
        stage = self.dir("maps") / f".upload-{uuid.uuid4().hex}"
        stage.mkdir()
        yaml_path = stage / yaml_safe
        yaml_path.write_bytes(yaml_bytes)
        (stage / image_safe).write_bytes(image_bytes)
        try:
            doc = load_yaml(yaml_path)
        except ConfigError as exc:
            self.discard_staged(yaml_path)
            raise MediaError(f"the map YAML is not valid: {exc.reason}") from None
        image = doc.get("image") if isinstance(doc, dict) else None
        if image != image_safe:
            self.discard_staged(yaml_path)
            raise MediaError(
                f"the map YAML names the image {image!r}; upload that file (a plain name beside the YAML), "
                f"not {image_safe!r}"
            )
        return yaml_path

    def commit_map(self, staged_yaml: Path) -> str:
        """Move a validated staged map into the maps directory; refuses to overwrite an existing map."""
        maps = self.dir("maps")
        files = [p for p in staged_yaml.parent.iterdir() if p.is_file()]
        clash = [p.name for p in files if (maps / p.name).exists()]
        if clash:
            self.discard_staged(staged_yaml)
            raise MediaError(f"a map file called {', '.join(clash)} exists already; delete it first or rename")
        for p in files:
            p.replace(maps / p.name)
        self.discard_staged(staged_yaml)
        return staged_yaml.name

    def discard_staged(self, staged_yaml: Path) -> None:
        if staged_yaml.parent.name.startswith(".upload-"):
            shutil.rmtree(staged_yaml.parent, ignore_errors=True)
