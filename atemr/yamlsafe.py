"""Safe YAML loading that remembers where every value came from.

Every document the framework reads (config, agent, missions, worlds, fuzzy engines) goes through
`load_yaml`: ``yaml.SafeLoader`` only (no ``!!python/object``), duplicate keys rejected, size, depth and
aliases bounded, and each mapping and list remembers the line and column of its items, so a validator can
raise `ConfigError` pointing at ``file:line:column`` and the YAML path.

Aliases are bounded twice: their number (`MAX_ALIASES`) and the nodes they stand for once expanded
(`MAX_ALIAS_NODES`). A few hundred bytes of nested aliases can stand for billions of values: free to
parse (PyYAML shares them), but everything that walks the result pays for each one, a ``repr`` in an
error message first of all. A structure that contains itself (an alias inside its own anchor) is refused.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from atemr.errors import ConfigError, brief

MAX_BYTES = 1_000_000
MAX_DEPTH = 64
MAX_ALIASES = 100
#: Most nodes all the aliases of a document may stand for together, counted expanded (an alias to a list
#: of 9 aliases to lists of 9 scalars stands for 1 + 9 * (1 + 9) = 91 nodes).
MAX_ALIAS_NODES = 100_000


class MarkedDict(dict[str, Any]):
    """A mapping that knows its own position and the position of each key and value (1-based)."""

    file: str | None = None
    line: int = 0
    column: int = 0
    key_marks: dict[Any, tuple[int, int]]
    value_marks: dict[Any, tuple[int, int]]


class MarkedList(list[Any]):
    """A list that knows its own position and the position of each item (1-based)."""

    file: str | None = None
    line: int = 0
    column: int = 0
    item_marks: list[tuple[int, int]]


def _mark(node: Node) -> tuple[int, int]:
    return node.start_mark.line + 1, node.start_mark.column + 1


class _Loader(yaml.SafeLoader):
    """SafeLoader with marks, duplicate-key rejection and bounded depth/aliases."""

    source: str | None = None

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._aliases = 0
        self._alias_nodes = 0
        #: Expanded size (nodes) of each composed node, by id: what an alias to it stands for.
        self._sizes: dict[int, int] = {}

    def compose_node(self, parent: Node | None, index: Any) -> Node | None:
        alias = self.check_event(yaml.AliasEvent)
        if alias:
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                event = self.peek_event()
                raise ConfigError(
                    f"more than {MAX_ALIASES} aliases: refusing a document that may expand without bound",
                    file=self.source, line=event.start_mark.line + 1, column=event.start_mark.column + 1,
                )
            start = self.peek_event().start_mark
        self._depth += 1
        if self._depth > MAX_DEPTH:
            event = self.peek_event()
            raise ConfigError(
                f"nested more than {MAX_DEPTH} levels deep",
                file=self.source, line=event.start_mark.line + 1, column=event.start_mark.column + 1,
            )
        try:
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        if node is None:
            return node
        if alias:
            size = self._sizes.get(id(node))
            if size is None:  # an alias inside the node it names: a structure that contains itself
                raise ConfigError("an alias refers to a node that contains it (a recursive structure)",
                                  file=self.source, line=start.line + 1, column=start.column + 1)
            self._alias_nodes += size
            if self._alias_nodes > MAX_ALIAS_NODES:
                raise ConfigError(
                    f"aliases expand to more than {MAX_ALIAS_NODES} nodes: refusing a document that may expand "
                    "without bound", file=self.source, line=start.line + 1, column=start.column + 1,
                )
        else:
            self._sizes[id(node)] = self._size_of(node)
        return node

    def _size_of(self, node: Node) -> int:
        """Nodes ``node`` stands for once its aliases are expanded (its children are composed already)."""
        if isinstance(node, SequenceNode):
            return 1 + sum(self._sizes.get(id(child), 1) for child in node.value)
        if isinstance(node, MappingNode):
            return 1 + sum(self._sizes.get(id(k), 1) + self._sizes.get(id(v), 1) for k, v in node.value)
        return 1

    def construct_marked_mapping(self, node: MappingNode) -> Iterator[MarkedDict]:
        result = MarkedDict()
        result.file = self.source
        result.line, result.column = _mark(node)
        result.key_marks = {}
        result.value_marks = {}
        yield result  # PyYAML's two-step construction, so recursive nodes can refer to it
        self.flatten_mapping(node)
        for key_node, value_node in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                hash(key)
            except TypeError:
                line, col = _mark(key_node)
                raise ConfigError(
                    "a mapping key must be a plain value", file=self.source, line=line, column=col
                ) from None
            if key in result:
                line, col = _mark(key_node)
                first = result.key_marks[key]
                raise ConfigError(
                    f"duplicate key {brief(key)} (first defined at line {first[0]})",
                    file=self.source, line=line, column=col,
                )
            result[key] = self.construct_object(value_node, deep=True)
            result.key_marks[key] = _mark(key_node)
            result.value_marks[key] = _mark(value_node)

    def construct_bounded_int(self, node: ScalarNode) -> int:
        """An integer, or `ConfigError` for one Python refuses to read (more than 4300 digits)."""
        try:
            return int(super().construct_yaml_int(node))
        except ValueError:
            line, col = _mark(node)
            raise ConfigError(f"an integer of {len(str(node.value))} characters is too long to read",
                              file=self.source, line=line, column=col) from None

    def construct_marked_sequence(self, node: SequenceNode) -> Iterator[MarkedList]:
        result = MarkedList()
        result.file = self.source
        result.line, result.column = _mark(node)
        result.item_marks = [_mark(child) for child in node.value]
        yield result
        result.extend(self.construct_object(child, deep=True) for child in node.value)


_Loader.add_constructor("tag:yaml.org,2002:map", _Loader.construct_marked_mapping)
_Loader.add_constructor("tag:yaml.org,2002:seq", _Loader.construct_marked_sequence)
_Loader.add_constructor("tag:yaml.org,2002:int", _Loader.construct_bounded_int)


def load_yaml(source: str | Path, *, text: str | None = None, max_bytes: int = MAX_BYTES) -> Any:  # noqa: PLR0912  each read and parse failure becomes a ConfigError with its place
    """Parse one YAML document safely.

    ``source`` is a path to read, or (with ``text``) the name used in error messages. Raises
    `ConfigError` with file, line and column for anything wrong: unreadable file, oversize document,
    syntax error, unsafe tag, duplicate key, excessive nesting or aliases.
    """
    name = str(source)
    if text is None:
        path = Path(source)
        try:
            size = path.stat().st_size
            if size > max_bytes:
                raise ConfigError(f"document is {size} bytes, more than the limit of {max_bytes}", file=name)
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise ConfigError("file not found", file=name) from None
        except UnicodeDecodeError as exc:
            raise ConfigError(f"not UTF-8 text ({exc.reason} at byte {exc.start})", file=name) from None
        except IsADirectoryError:
            raise ConfigError("is a directory, expected a YAML file", file=name) from None
        except OSError as exc:
            raise ConfigError(f"cannot read: {exc.strerror}", file=name) from None
    encoded_len = len(text.encode("utf-8"))
    if encoded_len > max_bytes:
        raise ConfigError(f"document is {encoded_len} bytes, more than the limit of {max_bytes}", file=name)
    loader: _Loader | None = None
    try:
        loader = _Loader(text)  # the reader checks characters here: a control character raises already
        loader.source = name
        return loader.get_single_data()
    except ConfigError:
        raise
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        problem = exc.problem or "invalid YAML"
        if exc.context:
            problem = f"{problem} ({exc.context})"
        if "could not determine a constructor" in str(exc.problem):
            problem = f"unsafe or unknown tag refused: {problem}"
        raise ConfigError(
            problem, file=name,
            line=mark.line + 1 if mark else None, column=mark.column + 1 if mark else None,
        ) from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"invalid YAML: {exc}", file=name) from None
    except RecursionError:
        raise ConfigError("document is nested too deeply", file=name) from None
    finally:
        if loader is not None:
            loader.dispose()


def mark_of(container: Any, key: Any = None) -> tuple[int | None, int | None]:
    """(line, column) of ``container[key]`` (or of the container itself when key is None), if known."""
    if key is None:
        line = getattr(container, "line", 0)
        return (line, getattr(container, "column", None)) if line else (None, None)
    if isinstance(container, MarkedDict) and key in container.value_marks:
        return container.value_marks[key]
    if isinstance(container, MarkedList) and isinstance(key, int) and 0 <= key < len(container.item_marks):
        return container.item_marks[key]
    return mark_of(container)


def key_mark_of(container: Any, key: Any) -> tuple[int | None, int | None]:
    """(line, column) of a mapping key itself (used for 'unknown key' errors)."""
    if isinstance(container, MarkedDict) and key in container.key_marks:
        return container.key_marks[key]
    return mark_of(container)
