"""The behaviour registry and the base class of every leaf.

A leaf is a py_trees ``Behaviour`` registered by name (``@behaviours.register("Wait")``) with a frozen
``Params`` dataclass that describes its YAML parameters. The builder validates a leaf's ``params`` with
`atemr.typed.merge_into`, so a bad parameter is a `ConfigError` with file:line:column, before any node is
built. Parameters whose field carries ``metadata={"required": True}`` must be given.

A leaf whose skill does not exist in this build is simply not registered (no stubs): YAML that names it
fails validation with the closest known names.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import py_trees

from atemr.errors import ConfigError
from atemr.registry import Registry
from atemr.trees.context import AgentContext, context_from_setup
from atemr.typed import Source, merge_into


@dataclasses.dataclass(frozen=True)
class NoParams:
    """For leaves without parameters."""


class Leaf(py_trees.behaviour.Behaviour):
    """Base of the agent's leaves: configuration in ``__init__``, the context in ``setup``.

    ``reason`` says why the leaf last failed (shown in the snapshot and used in event reasons).
    Subclasses implement ``initialise``/``update``/``terminate`` as py_trees intends; ``update`` never
    blocks and reads time only from ``self.ctx.now``.
    """

    Params: ClassVar[type[Any]] = NoParams
    #: One line for `atemr tree export` and the docs.
    summary: ClassVar[str] = ""

    def __init__(self, name: str, params: Any = None) -> None:
        super().__init__(name)
        self.params = params if params is not None else self.Params()
        self._context: AgentContext | None = None
        self.reason = ""

    def setup(self, **kwargs: Any) -> None:
        self._context = context_from_setup(self, kwargs)

    @property
    def ctx(self) -> AgentContext:
        """The agent context given to ``setup``; using a leaf before setup is a wiring error."""
        if self._context is None:
            raise ConfigError(f"behaviour '{self.name}' was ticked before setup(context=...)")
        return self._context

    def fail(self, reason: str) -> py_trees.common.Status:
        """Record why and return FAILURE (``return self.fail("...")`` in ``update``)."""
        self.reason = reason
        self.feedback_message = reason
        return py_trees.common.Status.FAILURE


behaviours: Registry[type[Leaf]] = Registry("behaviours")


def required_fields(params_cls: type[Any]) -> list[str]:
    """Names of the ``Params`` fields that YAML must set."""
    return [f.name for f in dataclasses.fields(params_cls) if f.metadata.get("required")]


def parse_params(params_cls: type[Any], raw: Mapping[str, Any] | None, source: Source, path: str, *,
                 container: Any = None, key: Any = None) -> Any:
    """A validated ``params_cls`` instance from the YAML mapping ``raw`` (None means no parameters).

    ``container``/``key`` locate ``raw`` in its document, for the 'missing parameter' error.
    """
    layer: Mapping[str, Any] = raw if raw is not None else {}
    params = merge_into(params_cls(), layer, source, prefix=path)
    missing = [name for name in required_fields(params_cls) if name not in layer]
    if missing:
        where = raw if raw is not None else container
        raise source.error(
            f"missing required parameter{'s' if len(missing) > 1 else ''}: {', '.join(missing)}",
            path, where, None if raw is not None else key,
        )
    return params
