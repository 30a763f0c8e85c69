"""The map store: named maps under ``<data_dir>/maps/`` in the ROS map_server format, and which one is active.

Each map is ``name.yaml`` + ``name.pgm`` written by `save_map` and read by `load_map` (the package's one
map reader/writer), so a map saved here opens in ROS tools and a map from another robot uploads as it
is. The default world's map (``studio``) is always available as a read-only built-in; it is the active
map until the operator selects another. The choice is persisted in ``maps/active`` (written atomically),
so it survives a restart; an active map that was deleted falls back to the default.

Uploads are validated before anything is stored: the files land in a private temporary directory
inside ``maps/``, names pass through `werkzeug.utils.secure_filename`, the YAML's ``image`` must name
one of the uploaded files (never a path elsewhere on the robot), the map must load with `load_map`,
and only then is it written under its name. A refused upload raises `ConfigError` saying why and
leaves the store exactly as it was.

Every map the store reads (an upload, a stored map, a built-in) is refused above ``max_cells`` cells
(``ui.max_map_cells``, 4 M by default) from its image's header, before anything is decoded.

Each map's named places (`atemr.domain.places`) live beside it in ``name.places.yaml`` (a file ROS tools
ignore, so the pair stays a map_server map): saved atomically, deleted with the map, carried in its export
and accepted in an upload (checked like the map, before anything is stored). A built-in map's places ship
beside it; the operator's changes to them are stored in ``maps/``, since the built-in is read-only.
"""

from __future__ import annotations

import json
import re
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from werkzeug.utils import secure_filename

from atemr.domain.maps import OccupancyMap
from atemr.domain.places import NO_PLACES, Places
from atemr.errors import ConfigError, brief, brief_text
from atemr.io.sim.maps import DEFAULT_MAX_MAP_CELLS, load_map, save_map
from atemr.yamlsafe import load_yaml

#: The shipped default world's map: a built-in every store offers.
DEFAULT_MAP = "studio"
BUILTIN_MAPS: dict[str, Path] = {
    DEFAULT_MAP: Path(__file__).resolve().parents[1] / "worlds" / "studio" / "studio.yaml",
}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")
#: Largest upload accepted (all files together), bytes.
MAX_UPLOAD_BYTES = 50 * 1024 * 1024
#: Longest uploaded file name (what a file system holds).
MAX_NAME_BYTES = 255
#: A map's places file: ``<map>.places.yaml`` beside ``<map>.yaml``.
PLACES_SUFFIX = ".places.yaml"


def places_file_of(yaml_path: Path) -> Path:
    """Where the places of the map described by ``yaml_path`` are kept."""
    return yaml_path.with_name(yaml_path.stem + PLACES_SUFFIX)


def parse_places(text: str, file: str) -> Places:
    """A places file's text (``places: [{name, x_m, y_m, yaw_rad, kind}, ...]``) as `Places`; `ConfigError`
    naming the file and the item at fault."""
    doc = load_yaml(file, text=text)
    if doc is None:
        return NO_PLACES
    if not isinstance(doc, dict) or set(doc) - {"places"}:
        raise ConfigError("a places file has one top-level key, 'places'", file=file)
    try:
        return Places.from_json(doc.get("places"))
    except ConfigError as exc:
        raise ConfigError(exc.reason, file=file, path=exc.path) from None


def places_text(places: Places) -> str:
    """The file form of ``places`` (YAML, one place a line)."""
    lines = ["# Named places of this map (atemr): map-frame poses, metres and radians.", "places:"]
    lines += [f"  - {json.dumps(item, ensure_ascii=False)}" for item in places.to_json()]
    if not len(places):
        lines[-1] = "places: []"
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class MapInfo:
    """One entry of the list the dashboard shows."""

    name: str
    builtin: bool
    active: bool


def clean_name(name: str) -> str:
    """A map name as stored: through ``secure_filename``, without a ``.yaml``/``.pgm`` suffix, 1–64 characters.

    Raises `ConfigError` when nothing usable is left (``"../"``, ``""``, only symbols).
    """
    if not isinstance(name, str):
        raise ConfigError(f"map name must be text, got {type(name).__name__}", path="map.name")
    safe = secure_filename(name.strip())
    for suffix in (".yaml", ".yml", ".pgm", ".png"):
        if safe.lower().endswith(suffix):
            safe = safe[: -len(suffix)]
    if safe.lower().endswith(".places"):
        raise ConfigError(f"invalid map name {brief(name)}: '.places' ends the name of a map's places file",
                          path="map.name")
    if not _NAME.match(safe):
        raise ConfigError(f"invalid map name {brief(name)}: use 1-64 letters, digits, '.', '_' or '-' "
                          f"(starting with a letter or digit)", path="map.name")
    return safe


def _uploaded_places(safe: Mapping[str, bytes], places_files: list[str]) -> Places | None:
    """The places file of an upload, read and checked (None: the upload has none)."""
    if not places_files:
        return None
    try:
        return parse_places(safe[places_files[0]].decode("utf-8"), places_files[0])
    except UnicodeDecodeError:
        raise ConfigError("the places file is not UTF-8 text", file=places_files[0]) from None


class MapStore:
    """Maps in ``<data_dir>/maps``; see the module docstring."""

    def __init__(self, data_dir: str | Path, *, builtins: Mapping[str, Path] | None = None,
                 max_upload_bytes: int = MAX_UPLOAD_BYTES, max_cells: int = DEFAULT_MAX_MAP_CELLS) -> None:
        self.dir = Path(data_dir) / "maps"
        self.dir.mkdir(parents=True, exist_ok=True)
        self.builtins = dict(BUILTIN_MAPS if builtins is None else builtins)
        self.max_upload_bytes = max_upload_bytes
        #: Largest map read, in cells (``ui.max_map_cells``).
        self.max_cells = max_cells
        self._active_file = self.dir / "active"

    # -- queries -----------------------------------------------------------------------------------
    def names(self) -> list[str]:
        """Every map name, built-ins first, then stored maps alphabetically."""
        stored = sorted(p.stem for p in self.dir.glob("*.yaml") if _NAME.match(p.stem) and p.stem not in self.builtins
                        and not p.name.endswith(PLACES_SUFFIX))
        return [*self.builtins, *stored]

    def list(self) -> list[MapInfo]:
        active = self.active_name()
        return [MapInfo(n, n in self.builtins, n == active) for n in self.names()]

    def exists(self, name: str) -> bool:
        return name in self.builtins or (self.dir / f"{name}.yaml").is_file()

    def path(self, name: str) -> Path:
        """The YAML of map ``name``; `ConfigError` if there is no such map."""
        if name in self.builtins:
            return self.builtins[name]
        clean = clean_name(name)
        path = self.dir / f"{clean}.yaml"
        if clean != name or not path.is_file():
            raise ConfigError(f"no map named {brief(name)}; known maps: {', '.join(self.names())}", path="map.name")
        return path

    # -- places ------------------------------------------------------------------------------------
    def places_path(self, name: str) -> Path:
        """The places file of map ``name`` as stored (for a built-in: the operator's copy in ``maps/``)."""
        self.path(name)  # an unknown map raises here
        return self.dir / f"{name}{PLACES_SUFFIX}"

    def places(self, name: str) -> Places:
        """Map ``name``'s places: the stored file, else (a built-in) the ones shipped beside it, else none."""
        for path in (self.places_path(name), places_file_of(self.path(name))):
            try:
                text = path.read_text(encoding="utf-8")
            except FileNotFoundError:
                continue
            except OSError as exc:
                raise ConfigError(f"cannot read the places of map {name}: {exc.strerror}", file=str(path)) from None
            return parse_places(text, str(path))
        return NO_PLACES

    def save_places(self, name: str, places: Places) -> None:
        """Store map ``name``'s places (replacing them), atomically: a reader sees the old set or the new."""
        path = self.places_path(name)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(places_text(places), encoding="utf-8")
        tmp.replace(path)

    def load(self, name: str) -> OccupancyMap:
        """Map ``name`` (`ConfigError` if unknown, unreadable or larger than ``max_cells``). Reading a map
        is heavy (up to ``max_cells`` decoded): the robot does it off its control loop."""
        return load_map(self.path(name), max_cells=self.max_cells)

    # -- the active map ----------------------------------------------------------------------------
    def selected_name(self) -> str | None:
        """The map the operator selected, if it still exists; no fallback (the real robot starts on it or
        on none)."""
        try:
            name = self._active_file.read_text(encoding="utf-8").strip()
        except OSError:
            return None
        return name if name and self.exists(name) else None

    def active_name(self) -> str | None:
        """The selected map, or the default built-in when none was selected or the selected one is gone."""
        name = self.selected_name()
        if name is not None:
            return name
        if DEFAULT_MAP in self.builtins:
            return DEFAULT_MAP
        names = self.names()
        return names[0] if names else None

    def active_map(self) -> OccupancyMap | None:
        name = self.active_name()
        return None if name is None else self.load(name)

    def select(self, name: str) -> OccupancyMap:
        """Make ``name`` the active map (it must load); persisted atomically. Returns the map."""
        grid = self.load(name)
        self.set_active(name)
        return grid

    def set_active(self, name: str) -> None:
        """Persist ``name`` (a map that exists, loaded already by the caller) as the active map, atomically."""
        if not self.exists(name):
            raise ConfigError(f"no map named {brief(name)}; known maps: {', '.join(self.names())}", path="map.name")
        tmp = self._active_file.with_name("active.tmp")
        tmp.write_text(name + "\n", encoding="utf-8")
        tmp.replace(self._active_file)

    # -- changes -----------------------------------------------------------------------------------
    def name_to_save(self, name: str, *, overwrite: bool = False) -> str:
        """``name`` as `save` stores it (cleaned), or `ConfigError` when it cannot be: a built-in map's, or a stored
        map's unless ``overwrite``. For a caller that must know before making the map (a replay of minutes)."""
        clean = clean_name(name)
        if clean in self.builtins:
            raise ConfigError(f"'{clean}' is a built-in map and cannot be replaced; choose another name",
                              path="map.name")
        if not overwrite and (self.dir / f"{clean}.yaml").exists():
            raise ConfigError(f"a map named '{clean}' already exists", path="map.name")
        return clean

    def save(self, name: str, grid: OccupancyMap, *, overwrite: bool = False, activate: bool = False,
             places: Places | None = None) -> str:
        """Store ``grid`` as ``name`` (cleaned; the stored name is returned), with its ``places`` when given
        (otherwise a replaced map's places are dropped: they were in the old map's frame); built-in names
        are refused."""
        clean = self.name_to_save(name, overwrite=overwrite)
        save_map(grid, self.dir / f"{clean}.yaml")
        if places is not None and len(places):
            self.save_places(clean, places)
        else:
            (self.dir / f"{clean}{PLACES_SUFFIX}").unlink(missing_ok=True)
        if activate:
            self.select(clean)
        return clean

    def delete(self, name: str) -> None:
        """Remove a stored map (both files); built-ins cannot be deleted. The active map falls back to the default."""
        if name in self.builtins:
            raise ConfigError(f"'{name}' is a built-in map and cannot be deleted", path="map.name")
        yaml_path = self.path(name)
        image = self._image_of(yaml_path)
        yaml_path.unlink()
        (self.dir / f"{name}{PLACES_SUFFIX}").unlink(missing_ok=True)
        if image is not None and image.parent == self.dir and image.is_file():
            image.unlink()

    def _image_of(self, yaml_path: Path) -> Path | None:
        try:
            doc = load_yaml(yaml_path)
        except ConfigError:
            return None
        image = doc.get("image") if isinstance(doc, dict) else None
        if not isinstance(image, str) or Path(image).name != image:
            return None
        return yaml_path.parent / image

    def _safe_files(self, files: Mapping[str, bytes]) -> dict[str, bytes]:
        """An upload's files under their ``secure_filename`` names; `ConfigError` when too large, a name is
        unusable, duplicate or too long."""
        total = sum(len(b) for b in files.values())
        if total > self.max_upload_bytes:
            raise ConfigError(f"upload of {total} bytes is larger than the limit of {self.max_upload_bytes}",
                              path="map.upload")
        safe: dict[str, bytes] = {}
        for raw, content in files.items():
            fname = secure_filename(str(raw))
            if not fname or fname in safe:
                raise ConfigError(f"unusable or duplicate file name {brief(raw)}", path="map.upload")
            if len(fname.encode("utf-8")) > MAX_NAME_BYTES:
                raise ConfigError(f"file name {brief(raw)} is longer than {MAX_NAME_BYTES} bytes", path="map.upload")
            safe[fname] = bytes(content)
        return safe

    def upload(self, files: Mapping[str, bytes], *, name: str | None = None, overwrite: bool = False) -> str:
        """Validate and store an uploaded map: ``files`` maps file names to contents (one ``.yaml``, its image
        and, optionally, its ``.places.yaml``).

        The map is stored under ``name`` (default: the YAML's file name) and the stored name returned.
        Raises `ConfigError` naming the problem; nothing is stored then.
        """
        safe = self._safe_files(files)
        places_files = [f for f in safe if f.lower().endswith(PLACES_SUFFIX)]
        if len(places_files) > 1:
            raise ConfigError(f"an upload has at most one {PLACES_SUFFIX} file, got {len(places_files)}",
                              path="map.upload")
        yamls = [f for f in safe if f.lower().endswith((".yaml", ".yml")) and f not in places_files]
        if len(yamls) != 1:
            raise ConfigError(f"an upload needs exactly one .yaml file (the map_server description), got {len(yamls)}",
                              path="map.upload")
        target = clean_name(name if name is not None else yamls[0])
        if target in self.builtins:
            raise ConfigError(f"'{target}' is a built-in map and cannot be replaced; choose another name",
                              path="map.name")
        if not overwrite and (self.dir / f"{target}.yaml").exists():
            raise ConfigError(f"a map named '{target}' already exists", path="map.name")
        staging = Path(tempfile.mkdtemp(prefix=".upload-", dir=self.dir))
        try:
            for fname, content in safe.items():
                try:
                    (staging / fname).write_bytes(content)
                except OSError as exc:
                    raise ConfigError(f"cannot store the upload: {exc.strerror}", path="map.upload") from None
            yaml_path = staging / yamls[0]
            places = _uploaded_places(safe, places_files)
            try:
                doc = load_yaml(yaml_path)
                image = doc.get("image") if isinstance(doc, dict) else None
                if isinstance(image, str) and (Path(image).name != image or image not in safe):
                    raise ConfigError(f"the map's image {brief(image)} must be one of the uploaded files "
                                      f"({brief_text(', '.join(sorted(safe)), 160)})", path="image")
                # every other check: keys, thresholds, origin, a readable image of at most max_cells
                grid = load_map(yaml_path, max_cells=self.max_cells)
            except ConfigError as exc:  # name the uploaded file, not the staging directory
                reason = exc.reason.replace(f"{staging}/", "")
                raise ConfigError(reason, file=brief_text(yamls[0], 100), line=exc.line, column=exc.column,
                                  path=exc.path) from None
            return self.save(target, grid, overwrite=overwrite, places=places)
        finally:
            shutil.rmtree(staging, ignore_errors=True)


__all__ = ["BUILTIN_MAPS", "DEFAULT_MAP", "MAX_UPLOAD_BYTES", "PLACES_SUFFIX", "MapInfo", "MapStore", "clean_name",
           "parse_places", "places_file_of", "places_text"]
