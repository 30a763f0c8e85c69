"""Named places on a map: "kitchen", "Mum's armchair", ``home`` (the dock).

A carer thinks in rooms, not coordinates, so the robot keeps a set of named poses with each map (the map
store saves them beside it, `atemr.io.map_store`), missions name them (``go_to: {place: kitchen}``), and
the dashboard lists them to send the robot there. A place is a pose in its map's frame, so the set
belongs to one map and travels with it (export, upload).

`Places` is immutable: every change (`with_place`, `renamed`, `without`) returns a new set after checking
it, so a refused change leaves the old set exactly as it was. Names are matched without regard to case
or repeated spaces ("Living  Room" is "living room"), because people type them; they are kept as written.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Literal

from atemr.errors import ConfigError, brief
from atemr.msgs import Pose2D

#: A place where the robot charges; ``home`` is the usual one.
PlaceKind = Literal["place", "dock"]
PLACE_KINDS: tuple[PlaceKind, ...] = ("place", "dock")
#: Longest place name, in characters (what fits a button on the robot's screen).
MAX_NAME_CHARS = 40
#: Most places one map may hold (a list a carer can read, a file that stays small).
MAX_PLACES = 200
#: How far from the map's origin a place may be, metres (as a mission's poses).
MAX_COORD_M = 1e4
_NAME = re.compile(r"^[\w][\w '’.,()&/-]*$", re.UNICODE)


def place_key(name: str) -> str:
    """The form names are compared in: lower case, runs of spaces as one, no outer spaces."""
    return " ".join(name.split()).casefold()


def check_name(name: Any, where: str = "place.name") -> str:
    """A usable place name (outer spaces removed), else `ConfigError` saying what is allowed."""
    if not isinstance(name, str):
        raise ConfigError(f"a place name is text, got {brief(name)}", path=where)
    clean = " ".join(name.split())
    if not clean or len(clean) > MAX_NAME_CHARS or not _NAME.match(clean):
        raise ConfigError(f"invalid place name {brief(name)}: use 1-{MAX_NAME_CHARS} letters, digits, spaces and "
                          "' . , ( ) & / - (starting with a letter or digit)", path=where)
    return clean


@dataclass(frozen=True)
class Place:
    """One named pose in a map's frame; ``kind`` ``dock`` where the robot charges."""

    name: str
    pose: Pose2D
    kind: PlaceKind = "place"

    def __post_init__(self) -> None:
        check_name(self.name)
        values = (self.pose.x_m, self.pose.y_m, self.pose.yaw_rad)
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values):
            raise ConfigError(f"place {self.name!r} has a non-finite pose {values}", path=f"places.{self.name}")
        if abs(self.pose.x_m) > MAX_COORD_M or abs(self.pose.y_m) > MAX_COORD_M:
            raise ConfigError(f"place {self.name!r} lies more than {MAX_COORD_M:g} m from the map origin",
                              path=f"places.{self.name}")
        if self.kind not in PLACE_KINDS:
            raise ConfigError(f"place {self.name!r}: kind is one of {', '.join(PLACE_KINDS)}, got {brief(self.kind)}",
                              path=f"places.{self.name}.kind")

    def to_json(self) -> dict[str, Any]:
        """The wire and file form: ``{name, x_m, y_m, yaw_rad, kind}``, rounded to a millimetre / milliradian."""
        return {"name": self.name, "x_m": round(self.pose.x_m, 3), "y_m": round(self.pose.y_m, 3),
                "yaw_rad": round(self.pose.yaw_rad, 3), "kind": self.kind}


class Places(Mapping[str, Place]):
    """A map's places, in the order they were added; looked up by name (case and spacing ignored)."""

    def __init__(self, places: tuple[Place, ...] | list[Place] = ()) -> None:
        by_key: dict[str, Place] = {}
        for place in places:
            key = place_key(place.name)
            if key in by_key:
                raise ConfigError(f"two places are named {place.name!r}", path=f"places.{place.name}")
            by_key[key] = place
        if len(by_key) > MAX_PLACES:
            raise ConfigError(f"a map holds at most {MAX_PLACES} places, got {len(by_key)}", path="places")
        self._by_key = by_key

    # -- Mapping -----------------------------------------------------------------------------------
    def __getitem__(self, name: str) -> Place:
        return self._by_key[place_key(name)]

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and place_key(name) in self._by_key

    def __iter__(self) -> Iterator[str]:
        return (p.name for p in self._by_key.values())

    def __len__(self) -> int:
        return len(self._by_key)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Places) and list(self._by_key.values()) == list(other._by_key.values())

    def __hash__(self) -> int:
        return hash(tuple(self._by_key.values()))

    def __repr__(self) -> str:
        return f"Places({', '.join(self)})"

    # -- queries -----------------------------------------------------------------------------------
    def all(self) -> tuple[Place, ...]:
        return tuple(self._by_key.values())

    def closest(self, name: str, n: int = 3) -> list[str]:
        """The names most like ``name`` (for "no place named 'kichen' (closest: kitchen)")."""
        keys = difflib.get_close_matches(place_key(name), list(self._by_key), n=n, cutoff=0.6)
        return [self._by_key[k].name for k in keys]

    def hint(self, name: str) -> str:
        """What to say of a name that is not here: the closest names, else every name."""
        close = self.closest(name) if isinstance(name, str) else []
        return f"closest: {', '.join(close)}" if close else f"places: {', '.join(self) or 'none'}"

    def find(self, name: str, where: str = "place") -> Place:
        """The place called ``name``, else `ConfigError` naming the closest names (or every name)."""
        if name in self:
            return self[name]
        raise ConfigError(f"no place named {brief(name)} on this map ({self.hint(name)})", path=where)

    def dock(self) -> Place | None:
        """Where the robot charges: the first ``dock``, else a place called ``home``."""
        return next((p for p in self._by_key.values() if p.kind == "dock"), self._by_key.get("home"))

    # -- changes (each returns a new, checked set) -------------------------------------------------
    def with_place(self, place: Place, *, replace: bool = False) -> Places:
        """Add ``place``; with ``replace`` an existing place of that name is moved (kept in its position)."""
        key = place_key(place.name)
        if key in self._by_key and not replace:
            raise ConfigError(f"a place named {self[place.name].name!r} exists already", path="place.name")
        items = dict(self._by_key)
        items[key] = place
        return Places(list(items.values()))

    def renamed(self, old: str, new: str) -> Places:
        """Rename ``old`` to ``new`` (a new name that another place has is refused)."""
        place = self.find(old)
        clean = check_name(new)
        if clean in self and place_key(clean) != place_key(old):
            raise ConfigError(f"a place named {self[clean].name!r} exists already", path="place.name")
        return Places([Place(clean, p.pose, p.kind) if p is place else p for p in self._by_key.values()])

    def without(self, name: str) -> Places:
        place = self.find(name)
        return Places([p for p in self._by_key.values() if p is not place])

    # -- the file form ------------------------------------------------------------------------------
    def to_json(self) -> list[dict[str, Any]]:
        return [p.to_json() for p in self._by_key.values()]

    @classmethod
    def from_json(cls, items: Any, where: str = "places") -> Places:
        """From ``[{name, x_m, y_m, yaw_rad?, kind?}, ...]``; `ConfigError` naming the item and key at fault."""
        if items is None:
            return cls()
        if not isinstance(items, list):
            raise ConfigError(f"places are a list of {{name, x_m, y_m, yaw_rad, kind}}, got {brief(items)}",
                              path=where)
        places = []
        for i, item in enumerate(items):
            at = f"{where}[{i}]"
            if not isinstance(item, Mapping):
                raise ConfigError(f"a place is a mapping {{name, x_m, y_m, yaw_rad, kind}}, got {brief(item)}",
                                  path=at)
            unknown = sorted(str(k) for k in item if k not in ("name", "x_m", "y_m", "yaw_rad", "kind"))
            if unknown:
                raise ConfigError(f"unknown key {brief(unknown[0])}; a place has name, x_m, y_m, yaw_rad, kind",
                                  path=f"{at}.{unknown[0]}")
            for key in ("name", "x_m", "y_m"):
                if key not in item:
                    raise ConfigError(f"a place needs '{key}'", path=at)
            coords = []
            for key in ("x_m", "y_m", "yaw_rad"):
                value = item.get(key, 0.0)
                if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                    raise ConfigError(f"expected a finite number, got {brief(value)}", path=f"{at}.{key}")
                coords.append(float(value))
            name = check_name(item["name"], f"{at}.name")
            kind = item.get("kind", "place")
            if kind not in PLACE_KINDS:
                raise ConfigError(f"kind is one of {', '.join(PLACE_KINDS)}, got {brief(kind)}", path=f"{at}.kind")
            try:
                places.append(Place(name, Pose2D(*coords), kind))
            except ConfigError as exc:
                raise ConfigError(exc.reason, path=at) from None
        try:
            return cls(places)
        except ConfigError as exc:
            raise ConfigError(exc.reason, path=where) from None


NO_PLACES = Places()

__all__ = ["MAX_NAME_CHARS", "MAX_PLACES", "NO_PLACES", "PLACE_KINDS", "Place", "PlaceKind", "Places", "check_name",
           "place_key"]
