"""The reactive ("awareness") engine (thesis 3.4.3): HEX-90 sectors → a twist, by two fuzzy engines.

* Base idle (and the operator's awareness flag on): the IDLE engine has full control. Its outputs
  linSteer and angSteer are fractions of the reactive limits, so the twist is
  ``(linSteer · max_linear_mps, angSteer · idle_max_angular_radps)``: it backs off from what comes at
  it from the front, drives off from what comes from behind, veers away from the sides.
* Operator driving (MANUAL mode, awareness on): the MANUAL engine proposes a yaw rate W_ME (its
  fwdSteer output while the operator drives forward, revSteer while reversing, as fractions of
  ``manual_max_angular_radps``), blended with the operator's W_IO by thesis eq. 3.1,
  ``W = W_ME·τ + W_IO·(1 − τ)`` (`atemr.skills.fuzzy.blend`), and the speed is limited to the engine's
  0.26 m/s (thesis 5.2).

τ is not a constant here: with a fixed τ the operator's own turns would be damped by (1 − τ) even in
an empty room, where the engine has nothing to say. So τ = ``tau_max`` × how NEAR the nearest sector
is, by the MANUAL engine's own NEAR term: the engine takes over as obstacles come close and hands the
wheel back as they recede. The engines are pure functions of the sectors, so each is evaluated once per
new `HexSectors` (once per scan, ~10 Hz), not once per 50 Hz control tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from atemr.errors import ConfigError
from atemr.msgs import Twist
from atemr.skills.fuzzy import MANUAL_ENGINE_SPEED_LIMIT_MPS, Engine, blend, load_builtin_engine
from atemr.skills.fuzzy.terms import Term
from atemr.skills.hexpattern import HEX90, SECTORS, HexSectors


@dataclass(frozen=True)
class ReactiveParams:
    """Scales and limits of the reactive engine."""

    max_linear_mps: float = field(
        default=MANUAL_ENGINE_SPEED_LIMIT_MPS, metadata={"min": 0.0, "max": 0.5, "help": "speed scale and limit"}
    )
    idle_max_angular_radps: float = field(default=1.0, metadata={"min": 0.0, "max": 3.0})
    #: As the slow zone's 1.6 rad/s: the engine often steers where the ramp is already in the slow zone.
    manual_max_angular_radps: float = field(default=1.6, metadata={"min": 0.0, "max": 3.0})
    tau_max: float = field(default=0.8, metadata={"min": 0.0, "max": 1.0, "help": "engine weight when very near"})

    def __post_init__(self) -> None:
        for name in ("max_linear_mps", "idle_max_angular_radps", "manual_max_angular_radps", "tau_max"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(f"reactive: {name} must be a non-negative number, got {value!r}")
        if self.tau_max > 1.0:
            raise ConfigError(f"reactive: tau_max must be within [0, 1], got {self.tau_max}")


@dataclass(frozen=True)
class ManualAssist:
    """The MANUAL engine's contribution this tick: the applied twist, W_ME (rad/s) and the τ used."""

    twist: Twist
    engine_radps: float
    tau: float


#: Outputs smaller than this are zero: a centroid of symmetric sets is 0 only up to rounding (1e-17),
#: and a base that 'moves' at 1e-18 m/s would flip the speed ramp's direction of travel.
_DEADBAND = 1e-6


def _output(values: dict[str, np.ndarray], name: str) -> float:
    """An engine output as a fraction in [-1, 1]; NaN (no rule fired, no default) means do nothing."""
    v = float(values[name])
    if not math.isfinite(v) or abs(v) < _DEADBAND:
        return 0.0
    return min(max(v, -1.0), 1.0)


class ReactiveEngine:
    """Both fuzzy engines behind one object; stateless except for the per-scan caches."""

    def __init__(
        self,
        idle_engine: Engine | None = None,
        manual_engine: Engine | None = None,
        params: ReactiveParams | None = None,
    ) -> None:
        self.idle_engine = idle_engine or load_builtin_engine("idle")
        self.manual_engine = manual_engine or load_builtin_engine("manual")
        self.params = params or ReactiveParams()
        expected = ((self.idle_engine, ("linSteer", "angSteer")), (self.manual_engine, ("fwdSteer", "revSteer")))
        for engine, outs in expected:
            if sorted(engine.input_names) != sorted(SECTORS) or not set(outs) <= set(engine.output_names):
                raise ConfigError(
                    f"reactive: engine '{engine.name}' must take the six sectors {', '.join(SECTORS)} and give "
                    f"{', '.join(outs)}; it takes {', '.join(engine.input_names)} and gives "
                    f"{', '.join(engine.output_names)}"
                )
        self._near: dict[str, Term] = {}
        for var in self.manual_engine.inputs:
            near = next((t for t in var.terms if t.name == "NEAR"), None)
            if near is not None:
                self._near[var.name] = near
        # the shipped engines give every sector the same NEAR term: then one vectorised call does all six
        terms = list(self._near.values())
        self._shared_near: Term | None = terms[0] if terms and all(t == terms[0] for t in terms) else None
        self._idle_cache: tuple[HexSectors, Twist] | None = None
        self._manual_cache: tuple[HexSectors, float, float, float] | None = None

    @staticmethod
    def _inputs(sectors: HexSectors) -> dict[str, float]:
        if sectors.layout != HEX90:
            raise ConfigError(f"reactive: the fuzzy engines are built on HEX-90 sectors, got '{sectors.layout.name}'")
        return sectors.as_dict()

    def idle_twist(self, sectors: HexSectors) -> Twist:
        """Full control while idle: move away from whatever approaches."""
        cached = self._idle_cache
        if cached is not None and cached[0] is sectors:
            return cached[1]
        out = self.idle_engine.process(self._inputs(sectors))
        p = self.params
        twist = Twist(_output(out, "linSteer") * p.max_linear_mps, _output(out, "angSteer") * p.idle_max_angular_radps)
        self._idle_cache = (sectors, twist)
        return twist

    def nearness(self, sectors: HexSectors) -> float:
        """How NEAR the nearest sector is (0..1) by the MANUAL engine's NEAR term (1 if it has none)."""
        if not self._near:
            return 1.0
        values = sectors.as_dict()
        if self._shared_near is not None:
            mu = self._shared_near.membership(np.array([values[name] for name in self._near]))
            return float(np.clip(mu, 0.0, 1.0).max())
        return max(float(np.clip(term.membership(values[name]), 0.0, 1.0)) for name, term in self._near.items())

    def manual_assist(self, sectors: HexSectors, operator: Twist) -> ManualAssist:
        """The operator's command with the MANUAL engine's steering blended in and the speed limited."""
        p = self.params
        cached = self._manual_cache
        if cached is not None and cached[0] is sectors:
            fwd, rev, near = cached[1], cached[2], cached[3]
        else:
            out = self.manual_engine.process(self._inputs(sectors))
            fwd, rev = _output(out, "fwdSteer"), _output(out, "revSteer")
            near = self.nearness(sectors)
            self._manual_cache = (sectors, fwd, rev, near)
        v = min(max(operator.linear_mps, -p.max_linear_mps), p.max_linear_mps)
        if v == 0.0:  # turning on the spot: no path to steer round anything; the operator's turn as given
            return ManualAssist(Twist(0.0, operator.angular_radps), 0.0, 0.0)
        w_engine = (fwd if v > 0 else rev) * p.manual_max_angular_radps
        tau = p.tau_max * near
        w = float(blend(w_engine, operator.angular_radps, tau))
        return ManualAssist(Twist(v, w), w_engine, tau)


__all__ = ["ManualAssist", "ReactiveEngine", "ReactiveParams"]
