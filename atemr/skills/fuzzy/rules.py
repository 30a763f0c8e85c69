"""The rule language: ``if FR is NEAR and (FL is FAR or LC is very FAR) then angSteer is LEFT with 0.8``.

The grammar is fuzzylite's: propositions ``VARIABLE is [hedge ...] TERM`` joined by ``and``/``or`` with
parentheses; ``and`` binds tighter than ``or``; the consequent is one or more ``OUTPUT is [hedge ...] TERM``
joined by ``and``; an optional ``with W`` weights the rule. Parsing checks every name against the engine
and raises `ConfigError` naming the closest known names; the loaders add the file and line.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from atemr.errors import ConfigError
from atemr.skills.fuzzy.norms import HEDGES, Norm

Array = NDArray[np.float64]
KEYWORDS = {"if", "then", "is", "and", "or", "with", "(", ")"}


@dataclass(frozen=True)
class Proposition:
    """``variable is [hedges] term``; hedges apply right to left, like fuzzylite (``not very X``)."""

    variable: str
    hedges: tuple[str, ...]
    term: str

    def __str__(self) -> str:
        return " ".join([self.variable, "is", *self.hedges, self.term])


@dataclass(frozen=True)
class Operator:
    """``left and right`` (the block's conjunction) or ``left or right`` (its disjunction)."""

    kind: str
    left: Expression
    right: Expression

    def __str__(self) -> str:
        def side(e: Expression) -> str:
            return f"({e})" if isinstance(e, Operator) and e.kind != self.kind else str(e)

        return f"{side(self.left)} {self.kind} {side(self.right)}"


Expression = Proposition | Operator


@dataclass(frozen=True)
class Rule:
    """One parsed rule: antecedent tree, consequent propositions and weight."""

    text: str
    antecedent: Expression
    consequents: tuple[Proposition, ...]
    weight: float = 1.0

    def uses(self, kind: str) -> bool:
        """Whether the antecedent contains the operator ``kind`` (``and``/``or``)."""

        def walk(e: Expression) -> bool:
            return isinstance(e, Operator) and (e.kind == kind or walk(e.left) or walk(e.right))

        return walk(self.antecedent)

    def degree(
        self, membership: Callable[[str, str], Array], conjunction: Norm | None, disjunction: Norm | None
    ) -> Array:
        """Activation degree for every input row: weight × antecedent (with hedges and norms applied)."""

        def ev(e: Expression) -> Array:
            if isinstance(e, Proposition):
                mu = membership(e.variable, e.term)
                for hedge in reversed(e.hedges):
                    mu = HEDGES.get(hedge)(mu)
                return mu
            norm = conjunction if e.kind == "and" else disjunction
            if norm is None:  # the loaders refuse this; kept as a guard for hand-built engines
                raise ConfigError(f"rule '{self.text}' uses '{e.kind}' but its rule block has no operator for it")
            return norm(ev(e.left), ev(e.right))

        return self.weight * ev(self.antecedent)


def _closest(word: str, known: Sequence[str]) -> str:
    close = difflib.get_close_matches(word, list(known), n=3, cutoff=0.5)
    hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
    return f"{hint}; known: {', '.join(sorted(known)) or 'none'}"


class _Parser:
    def __init__(self, text: str, inputs: Mapping[str, Sequence[str]], outputs: Mapping[str, Sequence[str]]) -> None:
        self.text = text
        body = text.split("#", 1)[0]
        self.tokens = re.findall(r"\(|\)|[^\s()]+", body)
        self.pos = 0
        self.inputs = inputs
        self.outputs = outputs

    def error(self, why: str) -> ConfigError:
        return ConfigError(f"rule '{self.text.strip()}': {why}")

    def peek(self) -> str | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def take(self, what: str) -> str:
        tok = self.peek()
        if tok is None:
            raise self.error(f"expected {what} but the rule ended")
        self.pos += 1
        return tok

    def expect(self, word: str) -> None:
        tok = self.take(f"'{word}'")
        if tok != word:
            raise self.error(f"expected '{word}' but found '{tok}'")

    def parse(self) -> Rule:
        self.expect("if")
        antecedent = self.disjunction()
        self.expect("then")
        consequents = [self.proposition(self.outputs, "output")]
        while self.peek() == "and":
            self.pos += 1
            consequents.append(self.proposition(self.outputs, "output"))
        weight = 1.0
        if self.peek() == "with":
            self.pos += 1
            tok = self.take("a weight")
            try:
                weight = float(tok)
            except ValueError:
                raise self.error(f"the weight after 'with' must be a number, got '{tok}'") from None
            if not 0.0 <= weight <= 1.0:
                raise self.error(f"the weight must be within [0, 1], got {weight:g}")
        if self.peek() is not None:
            raise self.error(f"unexpected '{self.peek()}' after the consequent")
        return Rule(self.text.strip(), antecedent, tuple(consequents), weight)

    def disjunction(self) -> Expression:
        left = self.conjunction()
        while self.peek() == "or":
            self.pos += 1
            left = Operator("or", left, self.conjunction())
        return left

    def conjunction(self) -> Expression:
        left = self.atom()
        while self.peek() == "and":
            self.pos += 1
            left = Operator("and", left, self.atom())
        return left

    def atom(self) -> Expression:
        if self.peek() == "(":
            self.pos += 1
            inner = self.disjunction()
            self.expect(")")
            return inner
        return self.proposition(self.inputs, "input")

    def proposition(self, variables: Mapping[str, Sequence[str]], role: str) -> Proposition:
        var = self.take(f"an {role} variable")
        if var in KEYWORDS:
            raise self.error(f"expected an {role} variable but found '{var}'")
        if var not in variables:
            raise self.error(f"unknown {role} variable '{var}'{_closest(var, list(variables))}")
        self.expect("is")
        hedges: list[str] = []
        while True:
            word = self.take(f"a term of '{var}'")
            if word in HEDGES and word not in variables[var]:
                hedges.append(word)
                continue
            break
        if word not in variables[var]:
            raise self.error(f"'{var}' has no term '{word}'{_closest(word, list(variables[var]))}")
        return Proposition(var, tuple(hedges), word)


def parse_rule(text: str, inputs: Mapping[str, Sequence[str]], outputs: Mapping[str, Sequence[str]]) -> Rule:
    """Parse one rule against the engine's variables (name → term names); errors raise `ConfigError`."""
    return _Parser(text, inputs, outputs).parse()
