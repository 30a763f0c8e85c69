"""One registry helper for every plugin kind: behaviours, skills, buses, sensor sources, exporters.

Like python-can's ``BACKENDS`` table plus entry points: the core fills a registry with decorators,
third-party packages add to it through ``[options.entry_points]`` group ``atemr.<kind>``, and YAML
builders resolve names only through it, so an unknown name gets the closest known names back.
"""

from __future__ import annotations

import difflib
import logging
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING, Generic, TypeVar

if TYPE_CHECKING:
    from importlib.metadata import EntryPoint

from atemr.errors import RegistryError

log = logging.getLogger(__name__)

T = TypeVar("T")


def entry_points(group: str) -> Iterable[EntryPoint]:
    """The installed entry points of ``group``. importlib.metadata is imported here, on the first lookup: it and
    the scan of installed distributions cost about a tenth of a second, which ``atemr --help`` need not pay."""
    from importlib.metadata import entry_points as installed

    return installed(group=group)


class Registry(Generic[T]):
    """Maps names to plugins of one kind.

    ``kind`` names the plugin kind in messages and the entry-point group (``atemr.<kind>``).
    Entry points are read lazily, on the first lookup, so importing a module that registers does not
    pay for scanning installed distributions.
    """

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._items: dict[str, T] = {}
        self._entry_points_loaded = False

    def register(self, name: str | None = None) -> Callable[[T], T]:
        """Decorator: ``@registry.register()`` uses the object's ``__name__``."""

        def decorate(obj: T) -> T:
            self.add(name or obj.__name__, obj)  # type: ignore[attr-defined]
            return obj

        return decorate

    def add(self, name: str, obj: T) -> None:
        """Register ``obj`` under ``name``; a second, different object under the same name is an error."""
        existing = self._items.get(name)
        if existing is not None and existing is not obj:
            raise RegistryError(f"{self.kind} '{name}' is already registered as {existing!r}")
        self._items[name] = obj

    def get(self, name: str) -> T:
        """The plugin called ``name``; unknown names raise with the closest known names."""
        self._load_entry_points()
        try:
            return self._items[name]
        except KeyError:
            raise RegistryError(self.unknown_message(name)) from None

    def unknown_message(self, name: str) -> str:
        """The message for an unknown name, for builders that wrap it in a `ConfigError`."""
        self._load_entry_points()
        close = difflib.get_close_matches(name, list(self._items), n=3, cutoff=0.5)
        hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
        known = ", ".join(sorted(self._items)) or "none"
        return f"unknown {self.kind} '{name}'{hint}; known: {known}"

    def __contains__(self, name: object) -> bool:
        self._load_entry_points()
        return name in self._items

    def __iter__(self) -> Iterator[str]:
        self._load_entry_points()
        return iter(sorted(self._items))

    def __len__(self) -> int:
        self._load_entry_points()
        return len(self._items)

    def items(self) -> list[tuple[str, T]]:
        """Every (name, plugin) pair, sorted by name."""
        self._load_entry_points()
        return sorted(self._items.items())

    def _load_entry_points(self) -> None:
        if self._entry_points_loaded:
            return
        self._entry_points_loaded = True
        for ep in entry_points(group=f"atemr.{self.kind}"):
            try:
                self.add(ep.name, ep.load())
            except Exception as exc:  # a broken third-party plugin must not take the robot down
                log.error("cannot load %s plugin %r from %s: %s", self.kind, ep.name, ep.value, exc)
