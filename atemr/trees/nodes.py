"""The composites and decorators a tree document may use, by name, and how each is built.

They are py_trees' own (Sequence, Selector, Parallel, Retry, Repeat, Inverter, ...), with one exception:
py_trees' ``Timeout`` reads ``time.monotonic()``, which would make a simulated run depend on the speed of
the CPU, so ``Timeout`` here is `ClockTimeout`, the same decorator on the agent's injected clock.
Options are plain frozen dataclasses, validated like leaf parameters.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import py_trees

from atemr.clock import due
from atemr.trees.context import AgentContext, context_from_setup

Behaviour = py_trees.behaviour.Behaviour
Status = py_trees.common.Status


class ClockTimeout(py_trees.decorators.Decorator):
    """py_trees' Timeout on the agent's clock: FAILURE (child stopped) once ``duration_s`` has passed."""

    def __init__(self, name: str, child: Behaviour, duration_s: float) -> None:
        super().__init__(name=name, child=child)
        self.duration_s = duration_s
        self._context: AgentContext | None = None
        self._deadline = 0.0

    def setup(self, **kwargs: Any) -> None:
        self._context = context_from_setup(self, kwargs)

    def _now(self) -> float:
        return self._context.now if self._context is not None else 0.0

    def initialise(self) -> None:
        self._deadline = self._now() + self.duration_s
        self.feedback_message = ""

    def update(self) -> py_trees.common.Status:
        if self.decorated.status == Status.RUNNING and due(self._now(), self._deadline):
            self.feedback_message = f"timed out after {self.duration_s:g} s"
            self.decorated.stop(Status.INVALID)
            return Status.FAILURE
        if self.decorated.status == Status.RUNNING:
            self.feedback_message = f"{self._deadline - self._now():.1f} s left"
        return self.decorated.status


# -- options ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SequenceOptions:
    memory: bool = True


@dataclass(frozen=True)
class SelectorOptions:
    memory: bool = False


@dataclass(frozen=True)
class ParallelOptions:
    policy: Literal["all", "one"] = field(default="all", metadata={"help": "succeed when all/one child succeeds"})
    synchronise: bool = True


@dataclass(frozen=True)
class NoOptions:
    pass


@dataclass(frozen=True)
class RetryOptions:
    num_failures: int = field(default=1, metadata={"min": 1, "max": 1000, "required": True})


@dataclass(frozen=True)
class RepeatOptions:
    num_success: int = field(default=-1, metadata={"min": -1, "max": 1_000_000, "help": "-1: forever"})

    def validate(self) -> None:
        if self.num_success == 0:
            raise ValueError("num_success must be -1 (forever) or at least 1")


@dataclass(frozen=True)
class TimeoutOptions:
    duration_s: float = field(default=0.0, metadata={"min": 0.0, "max": 86_400.0, "required": True})


@dataclass(frozen=True)
class OneShotOptions:
    policy: Literal["on_completion", "on_successful_completion"] = "on_successful_completion"


CompositeFactory = Callable[[str, Any, Sequence[Behaviour]], Behaviour]
DecoratorFactory = Callable[[str, Any, Behaviour], Behaviour]


def _parallel(name: str, o: ParallelOptions, children: Sequence[Behaviour]) -> Behaviour:
    policy: py_trees.common.ParallelPolicy.Base = (
        py_trees.common.ParallelPolicy.SuccessOnAll(synchronise=o.synchronise) if o.policy == "all"
        else py_trees.common.ParallelPolicy.SuccessOnOne()
    )
    return py_trees.composites.Parallel(name, policy, children=list(children))


#: name → (options dataclass, factory(name, options, children)).
COMPOSITES: dict[str, tuple[type[Any], CompositeFactory]] = {
    "Sequence": (SequenceOptions, lambda n, o, c: py_trees.composites.Sequence(n, o.memory, list(c))),
    "Selector": (SelectorOptions, lambda n, o, c: py_trees.composites.Selector(n, o.memory, list(c))),
    "Parallel": (ParallelOptions, _parallel),
}


def _simple(cls: type[py_trees.decorators.Decorator]) -> tuple[type[Any], DecoratorFactory]:
    return NoOptions, lambda n, o, c: cls(name=n, child=c)


_ONESHOT = {"on_completion": py_trees.common.OneShotPolicy.ON_COMPLETION,
            "on_successful_completion": py_trees.common.OneShotPolicy.ON_SUCCESSFUL_COMPLETION}

#: name → (options dataclass, factory(name, options, child)).
DECORATORS: dict[str, tuple[type[Any], DecoratorFactory]] = {
    "Retry": (RetryOptions, lambda n, o, c: py_trees.decorators.Retry(n, c, o.num_failures)),
    "Repeat": (RepeatOptions, lambda n, o, c: py_trees.decorators.Repeat(n, c, o.num_success)),
    "Timeout": (TimeoutOptions, lambda n, o, c: ClockTimeout(n, c, o.duration_s)),
    "OneShot": (OneShotOptions, lambda n, o, c: py_trees.decorators.OneShot(n, c, _ONESHOT[o.policy])),
    "Inverter": _simple(py_trees.decorators.Inverter),
    "FailureIsSuccess": _simple(py_trees.decorators.FailureIsSuccess),
    "FailureIsRunning": _simple(py_trees.decorators.FailureIsRunning),
    "SuccessIsFailure": _simple(py_trees.decorators.SuccessIsFailure),
    "SuccessIsRunning": _simple(py_trees.decorators.SuccessIsRunning),
    "RunningIsFailure": _simple(py_trees.decorators.RunningIsFailure),
    "RunningIsSuccess": _simple(py_trees.decorators.RunningIsSuccess),
}

#: The node that stands for "what Exec was asked to do" (a mission or a goal), built when Exec starts.
TASK = "Task"
