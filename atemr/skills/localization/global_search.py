"""Global localization from one scan: where on the whole map could the robot be, and is one place clearly best?

Three stages, each vectorised:

1. **Correlation over the whole map** (rotation-decoupled correlative matching, after Olson 2009). The map's
   surfaces become a score field ``exp(−d²/2σ²)`` (``d``: distance to the nearest occupied cell),
   max-pooled onto a lattice of ``step_xy_m`` cells. For every heading of a ``step_yaw_rad`` grid the
   scan's points, rotated, are binned into a kernel of lattice offsets; the score of every position at that
   heading is the kernel correlated with the field, all headings at once by FFT (the field's transform is
   computed once per map). Positions where the robot does not fit (not free, or closer than
   ``clearance_m`` to a wall) are not candidates.
2. **Refinement** of the best ``keep`` distinct hypotheses (non-maximum suppression in position and
   heading) on the likelihood field: a grid search over the box the lattice cell stands for, then grids of
   halving steps down to an eighth of a map cell, every hypothesis in one call per stage.
3. **Verification** at every refined pose with the honest agreement (`MapAgreement`: beams that end on
   mapped structure without crossing a wall, over the whole scan), which decides:

   * ``localized``: the best place explains at least ``min_agreement`` of the scan, and it is *clearly*
     better than every other distinct place that does: McNemar's test on the beams that hit the map at one
     place and not at the other, ``z = (a − b) / √(a + b) ≥ min_z``. The scan's open beams (a return beyond
     the range: `atemr.skills.localization.scan.open_ray_ends`) count in that test and in the ranking too,
     each explained where no wall crosses it; the confidence is the returns' share alone;
   * ``ambiguous``: another distinct place explains the scan as well (no significant difference: both
     rooms of a symmetric flat, two bays of a warehouse): every such place is a candidate, best first, and
     none is chosen;
   * ``failed``: no place explains ``min_agreement`` of the scan.

``confidence`` is the best place's agreement, shared among the places that explain the scan equally well
(divided by their number), so it reaches ``min_agreement`` only when the outcome is ``localized``.

Hypotheses can also take more scans (`Hypotheses.add_scan`): each place is carried along by the odometry
since the first scan, refined again and its beams pooled, so a robot that turns or moves gathers the
evidence one scan could not give (`atemr.skills.localization.localizer` does this while ambiguous).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy import fft

from atemr.errors import ConfigError
from atemr.msgs import Pose2D
from atemr.skills.diff_drive import wrap_angle
from atemr.skills.localization.geometry import FloatArray, as_array, as_pose, compose
from atemr.skills.localization.icp import IcpParams, IcpTarget, icp
from atemr.skills.localization.likelihood_field import LikelihoodField
from atemr.skills.localization.map_agreement import HIT, MapAgreement
from atemr.skills.localization.scan import evenly_spread
from atemr.skills.localization.scan_to_map import pose_grid

Outcome = Literal["localized", "ambiguous", "failed"]
#: Places this far below the limit (or the best) are still finished by ICP: a degree off costs a few percent.
POLISH_MARGIN = 0.1
#: ICP of the finish: about this many points, from a pose already within a few centimetres.
POLISH_POINTS = 120
POLISH_ICP = IcpParams(max_correspondence_m=0.3, max_iterations=10)
#: Points a place is settled on (about): every beam would be fairest, half of them is close and half the cost.
SETTLE_POINTS = 180


@dataclass(frozen=True)
class GlobalSearchParams:
    """How finely the whole map is searched and how the outcome is decided."""

    #: Lattice of the correlation (m) and its headings (rad).
    step_xy_m: float = 0.2
    step_yaw_rad: float = math.radians(3.0)
    #: Scan points correlated and refined (evenly spread over the valid beams); the verification uses all.
    beams: int = 90
    #: Width of the score field round every surface (m).
    sigma_m: float = 0.1
    #: Candidate positions keep at least this distance to the nearest wall (the robot's radius, less a margin).
    clearance_m: float = 0.15
    #: Hypotheses refined and verified, and what makes two of them distinct places.
    keep: int = 16
    #: Best lattice cells scored again off the lattice before the distinct places are chosen.
    rescore: int = 500
    #: An ambiguous scan is searched again examining this many times more places.
    widen_ambiguous: int = 4
    distinct_xy_m: float = 0.5
    distinct_yaw_rad: float = 0.5
    #: A place must explain this share of the scan (the localization limit).
    min_agreement: float = 0.7
    #: How clearly the best place must beat every other plausible one (McNemar's z on their beams).
    min_z: float = 3.0
    #: Longest range used (m): the lidar's.
    range_max_m: float = 8.0

    def __post_init__(self) -> None:
        for name in ("step_xy_m", "step_yaw_rad", "sigma_m", "distinct_xy_m", "distinct_yaw_rad", "range_max_m",
                     "min_z"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a finite number > 0, got {value!r}", path=f"localization.global.{name}")
        if not (math.isfinite(self.clearance_m) and self.clearance_m >= 0):
            raise ConfigError(f"must be a finite number >= 0, got {self.clearance_m!r}",
                              path="localization.global.clearance_m")
        if self.beams < 3 or self.keep < 1 or self.rescore < 1 or self.widen_ambiguous < 1:
            raise ConfigError(f"need beams >= 3 and keep >= 1, got {self.beams}, {self.keep}",
                              path="localization.global.beams")
        if not 0 < self.min_agreement < 1:
            raise ConfigError(f"must be within (0, 1), got {self.min_agreement!r}", path="localization.min_agreement")


@dataclass(frozen=True)
class Hypothesis:
    """One place the scan could have been taken from: its pose and the share of the scan on the map there."""

    pose: Pose2D
    agreement: float


@dataclass(frozen=True)
class GlobalResult:
    """The outcome, the pose (localized only), the confidence and the places considered, best first.

    ``candidates``: for ``ambiguous`` the places that explain the scan equally well; for ``localized`` the
    winner alone; for ``failed`` the best places found, none good enough.
    """

    outcome: Outcome
    pose: Pose2D | None
    confidence: float
    candidates: tuple[Hypothesis, ...]
    reason: str
    #: How clearly the best place beat its closest plausible rival (McNemar's z; inf: no rival explains the
    #: limit's share of the scan).
    margin_z: float = math.inf


def mcnemar_z(a_hits: NDArray[np.bool_], b_hits: NDArray[np.bool_]) -> float:
    """How much better place A explains the same beams than place B: ``(a − b) / √(a + b)``, where ``a`` counts
    the beams on the map at A only and ``b`` those at B only (0 when they agree on every beam)."""
    a = int(np.count_nonzero(a_hits & ~b_hits))
    b = int(np.count_nonzero(b_hits & ~a_hits))
    return (a - b) / math.sqrt(a + b) if a + b else 0.0


@dataclass
class Hypotheses:
    """Places under consideration (map-frame poses at the first scan's odometry) and their pooled beam hits.

    ``poses``: ``(K, 3)`` at the time of the first scan; ``hits``: one ``(K, M_i)`` boolean array per scan (its
    beams on the map); ``opens``: one ``(K, F_i)`` array per scan (its open beams clear of walls), or none.
    """

    search: GlobalSearch
    poses: FloatArray
    first_odom: FloatArray
    hits: list[NDArray[np.bool_]] = field(default_factory=list)
    opens: list[NDArray[np.bool_]] = field(default_factory=list)
    #: The odometry motion from the first scan to the latest one added (base frame of the first).
    last_delta: FloatArray = field(default_factory=lambda: np.zeros(3))

    @property
    def agreement(self) -> FloatArray:
        """Each place's share of every pooled beam on the map."""
        if not self.hits or self.poses.shape[0] == 0:
            return np.zeros(self.poses.shape[0])
        return np.hstack(self.hits).mean(axis=1)

    @property
    def evidence(self) -> NDArray[np.bool_]:
        """Every pooled observation each place explains: the beams on the map, then the open beams kept clear:
        ``(K, total)``. Places are ranked and told apart on this; the confidence is the beams' share alone."""
        return np.hstack([*self.hits, *self.opens]) if self.hits else np.zeros((self.poses.shape[0], 0), bool)

    def ranked(self, odom_delta: FloatArray | None = None) -> tuple[Hypothesis, ...]:
        """The places, best first (by the pooled evidence, as `decide` ranks them), each with its share of the
        returns on the map: as of the latest scan added, or moved by ``odom_delta`` (the odometry since the first
        scan, base frame of the first) when given."""
        poses = self.current() if odom_delta is None else compose(self.poses, np.asarray(odom_delta, np.float64))
        agreement = self.agreement
        order = _rank(self.evidence)
        return tuple(Hypothesis(as_pose(poses[i]), float(agreement[i])) for i in order)

    def add_scan(self, points: FloatArray, sensor_xy: tuple[float, float], odom_delta: FloatArray,
                 open_ends: FloatArray | None = None) -> None:
        """Another scan, taken after the robot moved ``odom_delta`` (``[dx, dy, dyaw]`` in the base frame of the
        first scan): every place is carried along, refined again near where it lands, and its beams pooled
        (``open_ends``: the scan's open beams, `atemr.skills.localization.scan.open_ray_ends`)."""
        if self.poses.shape[0] == 0:
            return
        moved = compose(self.poses, np.asarray(odom_delta, dtype=np.float64))
        thin = self.search.thin(points)
        refined = self.search.polish(self.search.refine(moved, thin, wide=False), _valid(points), thin)
        self.hits.append(self.search.hit_mask(refined, points, sensor_xy))
        if open_ends is not None:
            self.opens.append(self.search.agreement.open_clear(refined, open_ends, sensor_xy))
        self.poses = compose(refined, _inverse_delta(odom_delta))
        self.last_delta = np.asarray(odom_delta, dtype=np.float64)

    def current(self) -> FloatArray:
        """The places as of the latest scan added (the first one's poses carried along by the odometry)."""
        return compose(self.poses, self.last_delta)

    def keep(self, mask: NDArray[np.bool_]) -> None:
        """Drop the places not in ``mask``."""
        self.poses = self.poses[mask]
        self.hits = [h[mask] for h in self.hits]
        self.opens = [o[mask] for o in self.opens]

    def decide(self) -> GlobalResult:
        """The three outcomes on the evidence pooled so far (poses as of the first scan)."""
        return self.search.decide(self)


def _rank(evidence: NDArray[np.bool_]) -> NDArray[np.intp]:
    """Places by how much of the pooled evidence each explains, best first (ties keep their order)."""
    return np.argsort(-evidence.mean(axis=1) if evidence.shape[1] else np.zeros(evidence.shape[0]), kind="stable")


def _valid(points: FloatArray) -> FloatArray:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return pts[np.isfinite(pts).all(axis=1)]


def _unique(poses: FloatArray, xy_m: float = 0.05, yaw_rad: float = 0.03) -> FloatArray:
    """The poses without near-duplicates (hypotheses the refinement brought to the same spot)."""
    kept: list[int] = []
    for i in range(poses.shape[0]):
        if not any(math.hypot(*(poses[i, :2] - poses[j, :2])) < xy_m
                   and abs(float(wrap_angle(poses[i, 2] - poses[j, 2]))) < yaw_rad for j in kept):
            kept.append(i)
    return poses[kept]


def _inverse_delta(delta: FloatArray) -> FloatArray:
    d = np.asarray(delta, dtype=np.float64)
    c, s = math.cos(float(d[2])), math.sin(float(d[2]))
    return np.array([-c * d[0] - s * d[1], s * d[0] - c * d[1], -d[2]])


def _block_max(a: FloatArray, k: int) -> FloatArray:
    """``a`` cut into ``k × k`` blocks (padded with 0), each block's maximum."""
    h, w = a.shape
    padded = np.zeros((-(-h // k) * k, -(-w // k) * k), dtype=a.dtype)
    padded[:h, :w] = a
    return padded.reshape(padded.shape[0] // k, k, padded.shape[1] // k, k).max(axis=(1, 3))


class GlobalSearch:
    """The whole-map search against one map; build once per map (the expensive tables), then `localize`."""

    def __init__(self, field: LikelihoodField, agreement: MapAgreement, params: GlobalSearchParams | None = None,
                 target: IcpTarget | None = None) -> None:
        """``target``: the map's surface points for ICP (`ScanToMapMatcher.target`; built here if not given)."""
        self.field = field
        self.agreement = agreement
        self.params = p = params or GlobalSearchParams()
        self.target = target or IcpTarget(field.obstacle_points(), IcpParams(max_correspondence_m=0.3))
        grid = field.map
        self.k = max(1, round(p.step_xy_m / grid.resolution_m))
        self.step_m = self.k * grid.resolution_m
        # Only the part of the map round its walls takes part (a map mostly unknown, as a SLAM map often is,
        # shrinks a lot): beyond a few σ from every wall the score field is zero anyway.
        rows, cols = np.nonzero(grid.occupied)
        margin = math.ceil(4 * p.sigma_m / grid.resolution_m) + self.k
        r0, c0 = max(0, int(rows.min()) - margin), max(0, int(cols.min()) - margin)
        r1, c1 = int(rows.max()) + margin + 1, int(cols.max()) + margin + 1
        #: Grid-frame offset (m) of the lattice's lower-left corner.
        self.corner_m = np.array([c0 * grid.resolution_m, r0 * grid.resolution_m])
        distance = field.distance_m[r0:r1, c0:c1]
        lattice = _block_max(np.exp(-0.5 * (distance / p.sigma_m) ** 2), self.k)
        clear = (grid.free[r0:r1, c0:c1] & (distance >= p.clearance_m)).astype(np.float64)
        self.candidates = _block_max(clear, self.k) > 0
        if not self.candidates.any():
            raise ConfigError(f"map '{grid.name}' has no free space {p.clearance_m:.2f} m from the walls: "
                              "nowhere to localize")
        reach = math.ceil(p.range_max_m / self.step_m) + 1
        hc, wc = lattice.shape
        self.shape = (fft.next_fast_len(hc + reach), fft.next_fast_len(wc + reach, real=True))
        padded = np.zeros(self.shape, dtype=np.float32)
        padded[:hc, :wc] = lattice
        self._field_hat = fft.rfft2(padded)
        half_turn = max(1, round(math.pi / p.step_yaw_rad))  # headings come in opposite pairs (see `correlate`)
        self.yaws = np.arange(2 * half_turn) * (math.pi / half_turn)
        self._cells = np.nonzero(self.candidates)
        o = grid.origin
        self._origin = np.array([o.x_m, o.y_m, o.yaw_rad])

    # -- stage 1: correlation -------------------------------------------------------------------------
    def correlate(self, points: FloatArray) -> FloatArray:
        """Mean score of the scan at every heading and candidate cell (``candidates``' true cells, row-major):
        ``(headings, cells)``, in [0, 1]. Headings and cells are in the grid frame (the map's origin)."""
        n0, n1 = self.shape
        half = self.yaws.size // 2
        c, s = np.cos(self.yaws[:half])[:, None], np.sin(self.yaws[:half])[:, None]
        col = np.rint((c * points[:, 0] - s * points[:, 1]) / self.step_m).astype(np.intp) % n1
        row = np.rint((s * points[:, 0] + c * points[:, 1]) / self.step_m).astype(np.intp) % n0
        kernel = np.zeros((half, n0, n1), dtype=np.float32)
        heading = np.broadcast_to(np.arange(half)[:, None], row.shape)
        np.add.at(kernel, (heading, row, col), np.float32(1.0))
        # The kernel of the opposite heading is this one point-reflected (offsets negated, rint is odd), and
        # the transform of a reflected real array is the conjugate: half the forward transforms suffice.
        k_hat = fft.rfft2(kernel)
        # circular cross-correlation S(c) = Σ_o K(o) F(c + o) is conj(K̂)·F̂; the field's zero padding
        # absorbs the wrap-around
        spectra = np.concatenate([np.conj(k_hat), k_hat]) * self._field_hat[None]
        scores = fft.irfft2(spectra, s=self.shape)
        return scores[:, self._cells[0], self._cells[1]] / points.shape[0]

    def _distinct_best(self, scores: FloatArray, points: FloatArray, widen: int = 1) -> FloatArray:
        """Grid-frame poses of the best ``keep`` places, no two within the distinct distance and heading.

        The lattice's scores only rank: a pose off its cell's centre, or between two headings, scores less
        than it deserves, so in a flat of repeated shelves the true place can rank below many look-alikes.
        The ``rescore`` best cells are scored again, each at 27 poses round its centre on the map's own
        field, and the suppression (greedy, best first) runs on those scores.
        """
        p = self.params
        flat = scores.ravel()
        top = min(flat.size, p.rescore * widen)
        best = np.argpartition(-flat, top - 1)[:top]
        best = best[flat[best] > 0.0]
        a, cell = np.unravel_index(best, scores.shape)
        r, c = self._cells[0][cell], self._cells[1][cell]
        cand = np.column_stack([self.corner_m[0] + (c + 0.5) * self.step_m, self.corner_m[1] + (r + 0.5) * self.step_m,
                                self.yaws[a]])
        offsets = pose_grid(np.zeros(3), self.step_m / 3, p.step_yaw_rad / 2, self.step_m / 3, p.step_yaw_rad / 2)
        trial = compose(self._origin, (cand[:, None, :] + offsets[None]).reshape(-1, 3))
        fit = np.exp(-0.5 * (self.field.distances(trial, points) / p.sigma_m) ** 2).mean(axis=1)
        fit = fit.reshape(cand.shape[0], offsets.shape[0])
        pick = np.argmax(fit, axis=1)
        cand = cand + offsets[pick]
        order = np.argsort(-fit[np.arange(cand.shape[0]), pick], kind="stable")
        cand = cand[order]
        kept: list[FloatArray] = []
        alive = np.ones(cand.shape[0], dtype=bool)
        while alive.any() and len(kept) < p.keep * widen:
            chosen = cand[int(np.argmax(alive))]
            kept.append(chosen)
            alive &= ~((np.hypot(cand[:, 0] - chosen[0], cand[:, 1] - chosen[1]) < p.distinct_xy_m)
                       & (np.abs(wrap_angle(cand[:, 2] - chosen[2])) < p.distinct_yaw_rad))
        return np.array(kept).reshape(-1, 3)

    # -- stage 2: refinement --------------------------------------------------------------------------
    def thin(self, points: FloatArray) -> FloatArray:
        """The valid points within ``range_max_m`` (farther ones would wrap round the correlation's padding: a
        lidar configured for a longer range than the search), at most ``beams`` of them, evenly spread."""
        pts = _valid(points)
        pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= self.params.range_max_m]
        if pts.shape[0] <= self.params.beams:
            return pts
        return pts[evenly_spread(pts.shape[0], self.params.beams)]

    def refine(self, world: FloatArray, points: FloatArray, *, wide: bool = True) -> FloatArray:
        """Each map-frame pose moved to the best of a pattern search on the likelihood field: a grid over a
        window, then 3 × 3 × 3 grids of halving steps down to an eighth of a map cell.

        ``wide``: the window is the box a lattice cell and heading stand for (± 1.5 cells, ± 1 heading
        step); otherwise ± two map cells and one degree (a place carried along by odometry).
        """
        res = self.field.map.resolution_m
        if wide:
            step_xy, step_yaw = self.step_m / 2, self.params.step_yaw_rad / 2
            half_xy, half_yaw = 3 * step_xy, 2 * step_yaw
        else:
            step_xy, step_yaw = res, math.radians(0.5)
            half_xy, half_yaw = 2 * step_xy, 2 * step_yaw
        while step_xy > res / 8:
            offsets = pose_grid(np.zeros(3), half_xy, half_yaw, step_xy, step_yaw)
            trial = world[:, None, :] + offsets[None, :, :]
            ll = self.field.log_likelihood(trial.reshape(-1, 3), points).reshape(trial.shape[:2])
            world = trial[np.arange(world.shape[0]), np.argmax(ll, axis=1)]
            half_xy, half_yaw = step_xy / 2, step_yaw / 2
            step_xy, step_yaw = half_xy, half_yaw
        out = world.copy()
        out[:, 2] = wrap_angle(out[:, 2])
        return out

    def polish(self, world: FloatArray, points: FloatArray, thin: FloatArray) -> FloatArray:
        """Each pose finished by point-to-line ICP against the map's surfaces (all valid points), kept unless it
        fits the field clearly worse: places that are twins must be compared at their best, not at where a
        grid search stopped (a degree off loses a few percent of the beams)."""
        out = world.copy()
        before = self.field.log_likelihood(world, thin)
        source = points[:: max(1, points.shape[0] // POLISH_POINTS)]
        for i in range(world.shape[0]):
            result = icp(source, self.target, as_pose(world[i]), POLISH_ICP)
            if not result.ok:
                continue
            cand = as_array(result.pose)
            if float(self.field.log_likelihood(cand[None], thin)[0]) >= before[i] - 0.025 * thin.shape[0]:
                out[i] = cand
        return out

    def settle(self, world: FloatArray, points: FloatArray) -> FloatArray:
        """Each pose moved, within ± 3 cm and ± 1.5°, to where most end points lie on the map: places are
        compared by the beams they explain, so each is judged where it explains the most (twin places left a
        degree apart by ICP would otherwise differ by the beams that degree flips)."""
        offsets = pose_grid(np.zeros(3), 0.03, math.radians(1.5), 0.01, math.radians(0.25))
        trial = world[:, None, :] + offsets[None, :, :]
        near = self.field.distances(trial.reshape(-1, 3), points) <= self.agreement.params.hit_tolerance_m
        count = near.sum(axis=1).reshape(trial.shape[:2])
        centre = offsets.shape[0] // 2
        best = np.where(count.max(axis=1) > count[:, centre], np.argmax(count, axis=1), centre)
        return trial[np.arange(world.shape[0]), best]

    # -- stage 3: verification and decision -----------------------------------------------------------
    def hit_mask(self, poses: FloatArray, points: FloatArray, sensor_xy: tuple[float, float]) -> NDArray[np.bool_]:
        """Which beams of the whole scan end on the map, honestly, under each pose: ``(K, M)``."""
        return self.agreement.classify(poses, _valid(points), sensor_xy) == HIT

    def hypotheses(self, points: FloatArray, sensor_xy: tuple[float, float] = (0.0, 0.0),
                   odom: FloatArray | None = None, *, widen: int = 1, open_ends: FloatArray | None = None
                   ) -> Hypotheses:
        """The ``keep`` best distinct places for the scan (base-frame points), refined and verified.

        ``odom``: the odometry pose of the scan, kept so later scans can be added (`Hypotheses.add_scan`);
        ``widen``: examine that many times more places (`search`, once the scan proved ambiguous);
        ``open_ends``: the scan's open beams (`atemr.skills.localization.scan.open_ray_ends`), checked at every
        verified place: where the scan's walls alone look alike (aisles of identical shelves), the open beams
        often tell the places apart (one aisle runs on past the lidar's range, the other ends in a wall).
        """
        first = np.zeros(3) if odom is None else np.asarray(odom, dtype=np.float64)
        thin = self.thin(points)
        if thin.shape[0] < 3:
            return Hypotheses(self, np.zeros((0, 3)), first)
        coarse = self._distinct_best(self.correlate(thin), thin[:: max(1, thin.shape[0] // 20)], widen)
        if coarse.shape[0] == 0:
            return Hypotheses(self, np.zeros((0, 3)), first)
        refined = self.refine(compose(self._origin, coarse), thin)
        # End points near the map bound the honest agreement from above: a place below the limit even by that
        # measure cannot explain the scan, and is not worth walking its beams.
        pts = _valid(points)
        near = (self.field.distances(refined, pts) <= self.agreement.params.hit_tolerance_m).mean(axis=1)
        refined = _unique(refined[near >= min(self.params.min_agreement, float(near.max())) - POLISH_MARGIN])
        hits = self.hit_mask(refined, pts, sensor_xy)
        # Every place within reach of the limit is finished (ICP, then settled) and counted again: a rival left
        # where the grid search stopped would look worse than it is, and the best would win against it unfairly.
        agreement = hits.mean(axis=1)
        best = float(agreement.max())
        close = agreement >= min(self.params.min_agreement, best) - POLISH_MARGIN
        polish = close & (agreement >= best - POLISH_MARGIN)  # ICP for the best and its closest rivals only
        if close.any():
            refined[polish] = self.polish(refined[polish], pts, thin)
            refined[close] = self.settle(refined[close], pts[:: max(1, pts.shape[0] // SETTLE_POINTS)])
            hits[close] = self.hit_mask(refined[close], pts, sensor_xy)
        opens = [] if open_ends is None else [self.agreement.open_clear(refined, open_ends, sensor_xy)]
        return Hypotheses(self, refined, first, [hits], opens)

    def _same_place(self, a: FloatArray, b: FloatArray) -> bool:
        p = self.params
        return bool(math.hypot(a[0] - b[0], a[1] - b[1]) < p.distinct_xy_m
                    and abs(float(wrap_angle(a[2] - b[2]))) < p.distinct_yaw_rad)

    def decide(self, hyps: Hypotheses) -> GlobalResult:
        """The three outcomes from the verified places (module docstring)."""
        p = self.params
        if hyps.poses.shape[0] == 0 or not hyps.hits:
            return GlobalResult("failed", None, 0.0, (), "the scan has too few valid returns to localize")
        agreement = hyps.agreement
        evidence = hyps.evidence
        poses = hyps.current()
        if agreement.max() < p.min_agreement:
            by_share = np.argsort(-agreement, kind="stable")
            near = [Hypothesis(as_pose(poses[i]), float(agreement[i])) for i in by_share[:3]]
            return GlobalResult("failed", None, near[0].agreement, tuple(near),
                                f"no place on the map explains the scan: at best {near[0].agreement:.0%} of it "
                                f"agrees (at {_where(near[0].pose)}), below {p.min_agreement:.0%}")
        # Among the places that explain the limit's share of the beams, the best explains the most evidence
        # (beams and open beams); every other one is a rival unless the best is clearly better on that evidence.
        order = [int(i) for i in _rank(evidence) if agreement[i] >= p.min_agreement]
        best = order[0]
        ranked = [Hypothesis(as_pose(poses[i]), float(agreement[i])) for i in order]
        rivals: list[int] = []
        margin = math.inf
        for i in order[1:]:
            if self._same_place(poses[i], poses[best]):
                continue
            if any(self._same_place(poses[i], poses[j]) for j in rivals):
                continue
            z = mcnemar_z(evidence[best], evidence[i])
            margin = min(margin, z)
            if z < p.min_z:
                rivals.append(int(i))
        if rivals:
            places = [Hypothesis(as_pose(poses[i]), float(agreement[i])) for i in [best, *rivals]]
            listed = "; ".join(f"{_where(h.pose)} {h.agreement:.0%}" for h in places)
            return GlobalResult("ambiguous", None, float(agreement[best]) / len(places), tuple(places),
                                f"{len(places)} places explain the scan about equally: {listed}", margin)
        return GlobalResult("localized", ranked[0].pose, float(agreement[best]), (ranked[0],),
                            f"localized at {_where(ranked[0].pose)}: {agreement[best]:.0%} of the scan on the map, "
                            "clearly better than anywhere else", margin)

    def search(self, points: FloatArray, sensor_xy: tuple[float, float] = (0.0, 0.0),
               odom: FloatArray | None = None, open_ends: FloatArray | None = None) -> tuple[GlobalResult, Hypotheses]:
        """Search the whole map for one scan and decide. A scan that is ambiguous, or won only narrowly (a rival
        within twice the margin), is searched again examining ``widen_ambiguous`` times more places: where one
        look-alike was found there are often many (aisles of identical shelves), the true place among them
        may not have been examined yet, and every one of them belongs among the candidates."""
        hyps = self.hypotheses(points, sensor_xy, odom, open_ends=open_ends)
        result = self.decide(hyps)
        narrow = result.outcome == "ambiguous" or result.margin_z < 2 * self.params.min_z
        if narrow and result.outcome != "failed" and self.params.widen_ambiguous > 1:
            hyps = self.hypotheses(points, sensor_xy, odom, widen=self.params.widen_ambiguous, open_ends=open_ends)
            result = self.decide(hyps)
        return result, hyps

    def localize(self, points: FloatArray, sensor_xy: tuple[float, float] = (0.0, 0.0),
                 open_ends: FloatArray | None = None) -> GlobalResult:
        """Search the whole map for one scan (base-frame points; ``sensor_xy`` where its beams start;
        ``open_ends`` its open beams, `atemr.skills.localization.scan.open_ray_ends`)."""
        return self.search(points, sensor_xy, open_ends=open_ends)[0]


def _where(pose: Pose2D) -> str:
    return f"({pose.x_m:.2f}, {pose.y_m:.2f}, {math.degrees(pose.yaw_rad):.0f}°)"


__all__ = ["GlobalResult", "GlobalSearch", "GlobalSearchParams", "Hypotheses", "Hypothesis", "Outcome", "mcnemar_z"]
