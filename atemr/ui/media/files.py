"""The files the dashboard lists, serves and deletes: captured images, recorded videos, maps and agent traces.

Layout under ``data_dir``: ``media/images/``, ``media/videos/`` (MP4 since the recorder writes it; older
``.mjpeg`` files are still listed and downloaded), ``traces/`` (the recorder's ``.mcap`` recordings, and older
``.atrace`` traces, which the Agent page replays; uploads are read before they are stored) and
``cache/thumbnails/`` (previews of images and videos, `atemr.ui.media.thumbnails`); maps belong to the robot's
`atemr.io.map_store.MapStore` (``maps/``, ROS map_server pairs, plus read-only built-ins), and every map
listing, download, upload and delete goes through it, so the dashboard and the robot have one set of
rules (built-ins protected, uploaded images only, size limit). Names coming from a browser go through
`secure_filename` and every path through `safe_join`, so nothing outside these directories can be read,
written or deleted.
"""

from __future__ import annotations

import io
import secrets
import zipfile
from collections.abc import Callable, Collection
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from werkzeug.security import safe_join
from werkzeug.utils import secure_filename

from atemr.errors import AtemrError, ConfigError
from atemr.io.map_store import PLACES_SUFFIX, MapStore, clean_name, places_text
from atemr.io.recording.agent_trace import RECORDING_SUFFIXES, decode_agent_trace
from atemr.io.trace_file import TraceContents
from atemr.ui.media.thumbnails import Thumbnails
from atemr.yamlsafe import load_yaml

Kind = Literal["images", "videos", "maps", "traces"]
KINDS: tuple[Kind, ...] = ("images", "videos", "maps", "traces")
#: File types listed per kind (maps are listed by their YAML).
EXTENSIONS: dict[Kind, frozenset[str]] = {
    "images": frozenset({".jpg", ".jpeg", ".png"}),
    "videos": frozenset({".mp4", ".webm", ".avi", ".mjpeg", ".mkv"}),
    "maps": frozenset({".yaml", ".yml"}),
    "traces": frozenset(RECORDING_SUFFIXES),
}
#: What each listed file is served as. A Motion-JPEG video (``.mjpeg``, what the recorder wrote before it
#: wrote MP4) has no registered type; VLC and ffplay open it, browsers do not.
MIME_TYPES: dict[str, str] = {
    ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".png": "image/png",
    ".mp4": "video/mp4", ".webm": "video/webm", ".mkv": "video/x-matroska", ".avi": "video/x-msvideo",
    ".mjpeg": "video/x-motion-jpeg",
    **dict.fromkeys(RECORDING_SUFFIXES, "application/octet-stream"),
}
#: Files a browser shows in place (an ``<img>`` or a ``<video>``); the rest are downloaded.
VIEWABLE = frozenset({".jpg", ".jpeg", ".png", ".mp4", ".webm"})
#: Kinds that have thumbnails.
THUMBNAIL_KINDS = frozenset({"images", "videos"})
MAP_IMAGE_EXTENSIONS = frozenset({".pgm", ".png", ".bmp", ".jpg", ".jpeg", ".tif", ".tiff"})
PAGE_SIZE = 10
#: Longest file name asked for (a name the file system cannot hold is simply not there).
MAX_NAME_BYTES = 255


def _plain_name(name: str) -> bool:
    """A plain file name (what `secure_filename` leaves as it is) the file system can hold."""
    return bool(name) and len(name.encode("utf-8", "surrogatepass")) <= MAX_NAME_BYTES and secure_filename(name) == name


def _shown(name: str, limit: int = 80) -> str:
    """``name`` quoted for a message, cut to ``limit`` characters."""
    return repr(name) if len(name) <= limit else repr(name[:limit]) + f"... ({len(name)} characters)"


def human_size(size_bytes: int) -> str:
    """A file's size as a phone or a file manager says it (decimal units, three figures at most): "640 bytes",
    "12.3 kB", "58.9 MB", "1.20 GB". "57512.0 KiB" for an hour's recording read as a puzzle."""
    if size_bytes < 1000:
        return f"{size_bytes} bytes"
    value = float(size_bytes)
    for unit in ("kB", "MB", "GB", "TB"):
        value = float(f"{value / 1000:.3g}")  # three figures, rounded once: 999,500 bytes is 1.00 MB
        if value < 1000 or unit == "TB":
            break
    decimals = 0 if value >= 100 else 1 if value >= 10 else 2
    return f"{value:.{decimals}f} {unit}"


class MediaError(AtemrError):
    """A media request was refused: unknown kind, bad or unknown file name, invalid upload."""


class MediaInUseError(MediaError):
    """A file the robot is writing now (the recording's current part) cannot be deleted: the writer keeps it open,
    so what it writes next would go to a file nobody can reach, and its disk space would stay taken until the part
    ends."""


@dataclass(frozen=True)
class MediaFile:
    """One listed file (for maps: ``name.yaml``, its YAML's size and time, and whether it is a built-in)."""

    kind: Kind
    name: str
    size_bytes: int
    modified: float
    builtin: bool = False
    #: The robot is writing it now (the recording's current part): listed, not deletable.
    in_use: bool = False

    @property
    def viewable(self) -> bool:
        """Shown in place by a browser (an image, or a video a ``<video>`` plays)."""
        return self.kind in THUMBNAIL_KINDS and Path(self.name).suffix.lower() in VIEWABLE

    @property
    def has_thumbnail(self) -> bool:
        return self.kind in THUMBNAIL_KINDS

    def to_json(self) -> dict[str, object]:
        return {"kind": self.kind, "name": self.name, "size_bytes": self.size_bytes, "modified": self.modified,
                "builtin": self.builtin, "viewable": self.viewable, "thumbnail": self.has_thumbnail,
                "in_use": self.in_use}


def mimetype(name: str) -> str:
    """What a listed file is served as (by its suffix)."""
    return MIME_TYPES.get(Path(name).suffix.lower(), "application/octet-stream")


def check_kind(kind: str) -> Kind:
    if kind not in KINDS:
        raise MediaError(f"unknown media kind {kind!r}: one of {', '.join(KINDS)}")
    return kind


class MediaStore:
    """Images and videos under ``data_dir``, and the maps of ``maps`` (default: a store over ``data_dir``)."""

    def __init__(self, data_dir: Path, maps: MapStore | None = None,
                 in_use: Callable[[], Collection[Path]] = tuple) -> None:
        """``in_use``: the files the robot is writing now (`atemr.ui.gateway.RobotGateway.files_in_use`)."""
        self.data_dir = Path(data_dir)
        self.in_use = in_use
        self.maps = maps or MapStore(self.data_dir)
        self.thumbnails = Thumbnails(self.data_dir / "cache" / "thumbnails")
        self.dirs: dict[Kind, Path] = {
            "images": self.data_dir / "media" / "images",
            "videos": self.data_dir / "media" / "videos",
            "maps": self.maps.dir,
            "traces": self.data_dir / "traces",
        }

    def dir(self, kind: str) -> Path:
        path = self.dirs[check_kind(kind)]
        path.mkdir(parents=True, exist_ok=True)
        return path

    def path(self, kind: str, name: str) -> Path:
        """The file ``name`` of ``kind``; `MediaError` if the name is not a plain, listed file name (or one
        the file system cannot hold: too long, odd bytes)."""
        if check_kind(kind) == "maps":
            return self.maps.path(self.map_name(name)) if self._is_map(name) else self._no_map(name)
        folder = self.dir(kind)
        if not _plain_name(name) or Path(name).suffix.lower() not in EXTENSIONS[check_kind(kind)]:
            raise MediaError(f"not a valid {kind} file name: {_shown(name)}")
        joined = safe_join(str(folder), name)
        if joined is None:
            raise MediaError(f"not a valid {kind} file name: {_shown(name)}")
        path = Path(joined)
        try:
            found = path.is_file()
        except (OSError, ValueError):  # ENAMETOOLONG and kin: no such file
            found = False
        if not found:
            raise MediaError(f"no such {kind[:-1]}: {_shown(name)}")
        return path

    def viewable(self, kind: str, name: str) -> Path:
        """An image or video that a browser shows in place (`VIEWABLE`); `MediaError` for any other file."""
        path = self.path(kind, name)
        if kind not in THUMBNAIL_KINDS or path.suffix.lower() not in VIEWABLE:
            raise MediaError(f"{_shown(name)} is not shown in a browser; download it")
        return path

    def thumbnail(self, kind: str, name: str) -> Path:
        """The thumbnail JPEG of an image or a video (made now on first request: see `Thumbnails`)."""
        if check_kind(kind) not in THUMBNAIL_KINDS:
            raise MediaError(f"{kind} have no thumbnails")
        source = self.path(kind, name)
        try:
            return self.thumbnails.get(kind, name, source)
        except FileNotFoundError:  # deleted meanwhile
            raise MediaError(f"no such {kind[:-1]}: {_shown(name)}") from None

    def newest(self, kind: str, offset: int = 0, limit: int = PAGE_SIZE) -> tuple[list[MediaFile], int]:
        """The files of ``kind``, newest first, ``limit`` of them from ``offset``; and the total count."""
        k = check_kind(kind)
        if k == "maps":
            return self._maps_listing(offset, limit)
        folder = self.dir(k)
        files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in EXTENSIONS[k]]
        stats = sorted(((p, p.stat()) for p in files), key=lambda ps: (ps[1].st_mtime, ps[0].name), reverse=True)
        page = stats[max(0, offset): max(0, offset) + max(0, limit)]
        busy = self._busy(k)
        return [MediaFile(k, p.name, st.st_size, st.st_mtime, in_use=p.name in busy) for p, st in page], len(stats)

    def _busy(self, kind: Kind) -> set[str]:
        """The names of the files of ``kind`` the robot is writing now."""
        folder = self.dirs[kind].resolve()
        return {p.name for p in map(Path, self.in_use()) if p.resolve().parent == folder}

    # -- maps: through the map store -------------------------------------------------------------------
    @staticmethod
    def map_name(name: str) -> str:
        """``room.yaml`` (as listed) → the map store's name ``room``."""
        return name[: -len(Path(name).suffix)] if Path(name).suffix.lower() in EXTENSIONS["maps"] else name

    def _is_map(self, name: str) -> bool:
        if not _plain_name(name) or Path(name).suffix.lower() not in EXTENSIONS["maps"]:
            return False
        stem = self.map_name(name)
        try:
            return (stem in self.maps.builtins or clean_name(stem) == stem) and self.maps.exists(stem)
        except (ConfigError, OSError, ValueError):
            return False

    @staticmethod
    def _no_map(name: str) -> Path:
        raise MediaError(f"no such map: {_shown(name)}")

    def _maps_listing(self, offset: int, limit: int) -> tuple[list[MediaFile], int]:
        """Stored maps newest first, then the built-ins."""
        stored: list[MediaFile] = []
        builtin: list[MediaFile] = []
        for info in self.maps.list():
            try:
                st = self.maps.path(info.name).stat()
            except (ConfigError, OSError):
                continue
            entry = MediaFile("maps", f"{info.name}.yaml", st.st_size, st.st_mtime, builtin=info.builtin)
            (builtin if info.builtin else stored).append(entry)
        stored.sort(key=lambda f: (f.modified, f.name), reverse=True)
        files = stored + builtin
        return files[max(0, offset): max(0, offset) + max(0, limit)], len(files)

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
        """A map's YAML, image and places (``name.places.yaml``, when it has any) as one zip, for download:
        what `upload_map` takes back."""
        buf = io.BytesIO()
        yaml_path = self.path("maps", name)
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
            for path in self.map_files(yaml_path):
                zf.write(path, path.name)
            try:
                places = self.maps.places(self.map_name(name))
            except ConfigError as exc:
                raise MediaError(f"the map's places cannot be read: {exc}") from None
            if len(places):
                zf.writestr(yaml_path.stem + PLACES_SUFFIX, places_text(places))
        return buf.getvalue()

    # -- deleting -------------------------------------------------------------------------------------
    def delete(self, kind: str, name: str) -> list[str]:
        """Delete one file (a map with its image; built-in maps are refused); returns the names deleted."""
        path = self.path(kind, name)
        if kind == "maps":
            targets = self.map_files(path)
            try:
                self.maps.delete(self.map_name(name))
            except ConfigError as exc:
                raise MediaError(exc.reason) from None
            return [t.name for t in targets]
        if path.name in self._busy(check_kind(kind)):
            raise MediaInUseError(f"{path.name} is still being recorded: it can be deleted once it is finished")
        path.unlink(missing_ok=True)
        if kind in THUMBNAIL_KINDS:
            self.thumbnails.forget(kind, name)
        return [path.name]

    def delete_all(self, kind: str) -> tuple[int, int]:
        """Delete every listed file of ``kind`` (maps: every stored map, never a built-in; never a file being
        recorded); returns how many were deleted and how many are being recorded (kept)."""
        files, _ = self.newest(kind, 0, 1_000_000)
        deletable = [f for f in files if not f.builtin and not f.in_use]
        for f in deletable:
            self.delete(kind, f.name)
        return len(deletable), sum(1 for f in files if f.in_use)

    # -- uploading maps -------------------------------------------------------------------------------
    def upload_map(self, yaml_name: str, yaml_bytes: bytes, image_name: str, image_bytes: bytes,
                   places_bytes: bytes | None = None) -> str:
        """Store an uploaded map pair through the map store (which validates it with the package's map
        reader: keys, thresholds, an image that is one of the uploaded files, size), with its places file
        (``places_bytes``, the ``.places.yaml`` of an export) when given; returns its name.

        `MediaError` says why an upload was refused (nothing is stored then); `MapExistsError` when a map of that
        name exists already.
        """
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
        try:
            name = clean_name(yaml_safe)
        except ConfigError as exc:
            raise MediaError(exc.reason) from None
        if name not in self.maps.builtins and self.maps.exists(name):
            raise MapExistsError(f"a map named '{name}' exists already; delete it first or rename the upload")
        files = {yaml_safe: yaml_bytes, image_safe: image_bytes}
        if places_bytes:
            files[Path(yaml_safe).stem + PLACES_SUFFIX] = places_bytes
        try:
            return self.maps.upload(files, name=name)
        except ConfigError as exc:
            raise MediaError(f"not a valid ROS map: {exc}") from None


    # -- uploading traces -----------------------------------------------------------------------------
    def upload_trace(self, name: str, data: bytes) -> tuple[str, TraceContents]:
        """Store an uploaded agent trace under ``traces/`` after reading it as the replay will (a trace
        from another robot, or one copied off this one); returns its stored name (through ``secure_filename``)
        and what was read.

        Refused with `MediaError` (nothing stored): a name that is not a ``.mcap`` (or older ``.atrace``) file
        name, a file
        that is not a trace or has no agent ``head`` record, a name already taken. A trace damaged after
        some good records is stored; its warnings say where the damage is.
        """
        from atemr.fsm.trace_timeline import TraceTimeline

        safe = secure_filename(name or "")
        suffix = Path(safe).suffix.lower()
        if not _plain_name(safe) or suffix not in RECORDING_SUFFIXES:
            raise MediaError(f"a trace upload is a file name of at most {MAX_NAME_BYTES} bytes ending in "
                             f"{' or '.join(RECORDING_SUFFIXES)}, "
                             f"got {_shown(name or '')}")
        folder = self.dir("traces")
        try:
            contents = decode_agent_trace(data, Path(safe))
            TraceTimeline(contents.records, name=safe)
        except ConfigError as exc:
            raise MediaError(f"not a valid trace: {exc}") from None
        target = folder / safe
        if target.exists():
            raise MediaError(f"a trace named '{safe}' exists already; delete it first or rename the upload")
        tmp = folder / f".upload-{secrets.token_hex(8)}{suffix}.part"
        try:
            tmp.write_bytes(data)
            tmp.replace(target)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise MediaError(f"cannot store the trace: {exc.strerror}") from None
        return safe, contents


class MapExistsError(MediaError):
    """An upload would replace a stored map."""
