"""Each pose's candidate roadmap nodes, without scoring every node (branch and bound).

``method: roadmap`` (:mod:`mmstab.planner.searches.roadmap`) gives each pose the ``count`` best
reachable nodes by Eq. 6's stability term, spread round robin over turret bins (the best
of every bin in turn, :func:`spread_top`), each clear of the robot. Scoring all 288,097
nodes of the default roadmap at every pose (an ``arctan2`` per tip-over axis) took 26 of
the 42 ms per pose. Here the nodes are grouped once per roadmap component into clusters
(turret bin x a :data:`CLUSTER_SIZE` voxel of the arm CoM), and at every pose of a route
(one batch) each cluster gets bounds on its members' values; only the clusters whose upper
bound reaches a threshold that some cluster certifies are scored. The answer is exactly
that of scoring every node (``tests/planner/test_roadmap_candidates.py``).

**Bounds.** Axis j's tip-over angle is ``atan2(s_j, c_j)`` with ``(s_j, c_j)`` affine in the
arm CoM (:mod:`mmstab.planner.fitness`): within a ball of radius r about a cluster's centre
the pair moves by at most ``δ_j = r ||[∂s_j; ∂c_j]||_F``, so the angle by at most
``asin(δ_j / ρ_j)`` (ρ_j: the pair's norm at the centre), when ``δ_j < ρ_j`` and the interval
stays inside (−π, π]; otherwise the axis is unbounded (±π). The value is
``w μ = w |f| min_j θ_j``: bounds per axis give bounds on the value.

**Threshold.** A pose's chosen rows have a rank within their bin below R (the smallest R
with Σ_b min(R, n_b) ≥ count, n_b the bin's rows). A cluster with at least R eligible
members (not known too close) whose lower bound is L proves that the bin's R-th best
eligible value is ≥ L; every row ranked above R then lies in a cluster whose upper bound is
≥ L. A bin where no cluster proves a threshold is scored whole. With the ground under the
arm the eligible rows differ by pose: each pose's proofs count its own (the rows measured
too low there left out; a row not yet measured counts, and the picks, all measured clear,
are then also the best of the clear rows).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.defaults import SECTION_DEFAULTS
from mmstab.model.robot import FloatArray
from mmstab.planner.fitness import LinearFitness
from mmstab.planner.ground.under_arm import SLACK, GroundUnderArm, KeptPieces
from mmstab.planner.grounded import node_lowest
from mmstab.workspace.roadmap import MOVE_CLEARANCE, Roadmap

#: Edge of the arm-CoM voxel that groups nodes into clusters [m]: 4 cm, 5,755 clusters on
#: the default roadmap, 2.4 % of the nodes scored on problems/rough.yaml (2 cm: 19,709
#: clusters, 1.0 %, but the clusters' bounds cost 4x more; 5 cm: 3.3 %).
CLUSTER_SIZE = 0.04
#: Widening of every bounded angle [rad]: float32 round-off of the bounds (the sine and
#: cosine parts are ~10^2 N m, their round-off ~10^-5 N m, so the angle's ~10^-7 rad).
ANGLE_SLACK = 1e-5
#: Slack on the threshold test (value units): round-off never drops a row from the choice.
BOUND_SLACK = 1e-9
#: The arm's least height above the support plane [m] (``planner.ground_clearance``).
GROUND_CLEARANCE: float | None = SECTION_DEFAULTS["planner"]["ground_clearance"]


@dataclasses.dataclass(frozen=True)
class NodeClusters:
    """Rows of the reachable nodes grouped by cluster (turret bin x CoM voxel).

    Attributes:
        rows: reach rows grouped by cluster, ascending within each (N,).
        start: offsets of each cluster's rows in ``rows`` (C + 1,).
        centre: each cluster's centre, body frame (C, 3) [m].
        radius: its members' largest distance from the centre (C,) [m].
        cluster_bin: turret bin of each cluster (C,), ascending.
        bin_start: offsets of each bin's clusters (B + 1,).
        cluster_of: cluster of each reach row (N,).
        bin_rows: rows per bin (B,).
    """

    rows: NDArray[np.intp]
    start: NDArray[np.intp]
    centre: FloatArray
    radius: FloatArray
    cluster_bin: NDArray[np.intp]
    bin_start: NDArray[np.intp]
    cluster_of: NDArray[np.intp]
    bin_rows: NDArray[np.intp]


def node_clusters(
    coms: FloatArray, bins: NDArray[np.intp], count: int, size: float = CLUSTER_SIZE
) -> NodeClusters:
    """Group nodes with CoMs ``coms`` (N, 3) [m] and turret bins ``bins`` (N,) of ``count``."""
    vox = np.floor((coms - coms.min(axis=0)) / size).astype(np.int64)
    dims = tuple(int(d) for d in vox.max(axis=0) + 1)
    key = np.ravel_multi_index((bins.astype(np.int64), *vox.T), (count, *dims))
    uniq, inv = np.unique(key, return_inverse=True)
    inv = inv.reshape(-1)
    rows = np.argsort(inv, kind="stable")
    n = np.bincount(inv, minlength=len(uniq))
    start = np.r_[0, np.cumsum(n)]
    lo = np.full((len(uniq), 3), np.inf)
    hi = np.full((len(uniq), 3), -np.inf)
    np.minimum.at(lo, inv, coms)
    np.maximum.at(hi, inv, coms)
    centre = (lo + hi) / 2
    radius = np.zeros(len(uniq))
    np.maximum.at(radius, inv, np.linalg.norm(coms - centre[inv], axis=1))
    cluster_bin = (uniq // int(np.prod(dims))).astype(np.intp)
    bin_start = np.searchsorted(cluster_bin, np.arange(count + 1)).astype(np.intp)
    return NodeClusters(
        rows=rows.astype(np.intp),
        start=start.astype(np.intp),
        centre=centre,
        radius=radius * (1 + 1e-9) + 1e-12,  # round-off of the centre never shrinks it
        cluster_bin=cluster_bin,
        bin_start=bin_start,
        cluster_of=inv.astype(np.intp),
        bin_rows=np.bincount(bins, minlength=count).astype(np.intp),
    )


def cluster_bounds(cl: NodeClusters, fits: list[LinearFitness]) -> tuple[FloatArray, FloatArray]:
    """Lower and upper bounds (K, C) of each cluster's members' values at K poses.

    The value is LinearFitness's with no motion term: ``w_stability · μ``. Computed in
    float32 (half the time), each angle's interval widened by :data:`ANGLE_SLACK` to
    cover its round-off.
    """
    f32 = np.float32
    sg = np.stack([f.sin_gain for f in fits]).astype(f32)  # (K, 3, n)
    cg = np.stack([f.cos_gain for f in fits]).astype(f32)
    centre = cl.centre.astype(f32)
    s = centre @ sg
    s += np.stack([f.sin_offset for f in fits]).astype(f32)[:, None, :]  # (K, C, n)
    c = centre @ cg
    c += np.stack([f.cos_offset for f in fits]).astype(f32)[:, None, :]
    theta = np.arctan2(s, c)
    rho = np.hypot(s, c, out=c)  # in place: the same values, fewer (K, C, n) arrays
    gain = np.sqrt(np.sum(sg**2, axis=1) + np.sum(cg**2, axis=1))  # (K, n)
    delta = np.multiply(cl.radius.astype(f32)[None, :, None], gain[:, None, :], out=s)
    bounded = delta < rho
    np.divide(delta, rho, out=delta, where=bounded)
    spread = np.arcsin(np.minimum(delta, f32(1.0), out=delta), out=delta)
    spread += f32(ANGLE_SLACK)
    upper = np.add(theta, spread, out=rho)
    lower = np.subtract(theta, spread, out=theta)
    bounded &= (lower > -np.pi) & (upper <= np.pi)
    unbounded = np.logical_not(bounded, out=bounded)
    np.copyto(upper, f32(np.pi), where=unbounded)
    np.copyto(lower, f32(-np.pi), where=unbounded)
    upper, lower = _min_last(upper), _min_last(lower)
    scale = np.array([f.w_stability * f.force for f in fits])[:, None]
    return lower.astype(float) * scale, upper.astype(float) * scale


def _min_last(a: FloatArray) -> FloatArray:
    """``a.min(axis=-1)`` of a 3-D array with a short last axis, an axis at a time (2x faster)."""
    out = a[:, :, 0].copy()
    for j in range(1, a.shape[2]):
        np.minimum(out, a[:, :, j], out=out)
    return out


def scored_rows(
    cl: NodeClusters,
    fits: list[LinearFitness],
    eligible: NDArray[np.bool_],
    rank: int,
    low: list[NDArray[np.intp]] | None = None,
    bounds: tuple[FloatArray, FloatArray] | None = None,
    kept: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None,
) -> tuple[NDArray[np.intp], FloatArray, NDArray[np.bool_]]:
    """Reach rows (ascending) that hold every pose's rows ranked below ``rank`` per bin.

    Returns the rows, the thresholds (K, bins): at pose k, bin b's rows ranked below
    ``rank`` have values at least ``tau[k, b]`` (-inf: the bin is taken whole), and which of
    the rows may reach their bin's threshold at each pose (K, rows): the others' cluster
    bounds lie below it there, so only these need scoring at that pose (a sixth of the rows
    on the random routes: the poses' support polygons differ, and so do their best rows).

    Args:
        cl: the clusters.
        fits: Eq. 6 per pose (the motion term is not used).
        eligible: whether each reach row may be chosen (not known too close) (N,).
        rank: R of :func:`rank_bound`.
        low: per pose, the eligible rows known too low there (not counted at that pose).
        bounds: :func:`cluster_bounds` of ``cl`` and ``fits``, if known.
        kept: :func:`proof_order` of them, if known (a search's rounds share it).
    """
    lower, upper = cluster_bounds(cl, fits) if bounds is None else bounds
    eligible_members, order = proof_order(cl, eligible, lower) if kept is None else kept
    members = np.tile(eligible_members, (len(fits), 1))
    for k, rows in enumerate(low or ()):  # the proofs count each pose's eligible rows
        rows = rows[eligible[rows]]  # a row found low, then too close, counted once
        members[k] -= np.bincount(cl.cluster_of[rows], minlength=members.shape[1])
    counted = np.cumsum(np.take_along_axis(members, order, axis=1), axis=1)
    full = np.flatnonzero(np.diff(cl.bin_start) > 0)
    first = cl.bin_start[full]
    before = np.where(first > 0, counted[:, np.maximum(first - 1, 0)], 0)  # (K, bins)
    within = counted - np.repeat(before, np.diff(cl.bin_start)[full], axis=1)
    proof = np.where(within >= rank, np.take_along_axis(lower, order, axis=1), -np.inf)
    tau = np.full((len(fits), len(cl.bin_start) - 1), -np.inf)
    tau[:, full] = np.maximum.reduceat(proof, first, axis=1)
    reaches = upper >= tau[:, cl.cluster_bin] - BOUND_SLACK  # (K, C)
    take = np.flatnonzero((reaches & (members > 0)).any(axis=0))
    if take.size == 0:  # no clusters (an empty component)
        return np.zeros(0, dtype=np.intp), tau, np.zeros((len(fits), 0), dtype=bool)
    sizes = cl.start[take + 1] - cl.start[take]
    offset = np.repeat(cl.start[take] - np.r_[0, np.cumsum(sizes)[:-1]], sizes)
    rows = np.sort(cl.rows[np.arange(int(sizes.sum())) + offset])
    return rows, tau, reaches[:, cl.cluster_of[rows]]


def proof_order(
    cl: NodeClusters, eligible: NDArray[np.bool_], lower: FloatArray
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Each cluster's eligible members (C,); per pose, the clusters by bin, then best first.

    The R-th best eligible value of a bin is at least the lower bound of the first cluster
    at which its members counted reach R (``lower`` (K, C): :func:`cluster_bounds`).
    """
    span = 2 * float(np.abs(lower).max(initial=0.0)) + 1.0
    order = np.argsort(cl.cluster_bin * span - lower, axis=1)  # bins stay grouped
    return np.bincount(cl.cluster_of[eligible], minlength=len(cl.radius)), order


@dataclasses.dataclass(frozen=True)
class NodeClearance:
    """The reachable nodes' test: clear of the robot, of the support plane and of the ground.

    A node must keep :data:`MOVE_CLEARANCE` [m] from the robot: the tracked arm follows the
    plan's postures within a few millimetres, and a tracking run must keep 1 mm
    (``mmstab.runs.verdict.MIN_CLEARANCE``); on random routes postures 1.5 mm from the body
    were chosen and touched it when tracked. The nodes' FCL clearances are kept with the
    roadmap (``Roadmap.node_clearance``). Its arm's lowest point must be ``ground`` [m] above
    the support plane z_B = 0 (``Roadmap.node_ground``, ``planner.ground_clearance``; None:
    not checked): V and the roadmap know the robot's body only, and a low arm CoM maximises
    μ, so without it the plans of the shipped routes put the arm 50–61 cm below the plane
    the tracks rest on. These tests are pose-independent (:meth:`eligible`). With ``under``
    (the ground under the arm at each of the route's poses,
    :class:`mmstab.planner.ground.under_arm.GroundUnderArm`) a node must also keep its arm
    ``ground`` above the terrain under it at the pose it is chosen for: measured lazily for
    the nodes chosen (:meth:`measure`), those found too low at pose k learnt (:meth:`low`);
    the nodes too low there whatever the ground, and those that surely clear it, are known
    before measuring from their pieces' least z_B (:func:`mmstab.planner.grounded.node_lowest`).
    ``excluded`` holds other per-pose tests, known for every row at once: pose k's mask of
    the eligible rows it may not choose (the climb limit, :mod:`mmstab.planner.climbing`).
    """

    roadmap: Roadmap
    reach: NDArray[np.intp]
    ground: float | None = GROUND_CLEARANCE
    under: GroundUnderArm | None = None
    excluded: dict[int, NDArray[np.bool_]] = dataclasses.field(default_factory=dict)
    _low: dict[int, NDArray[np.bool_]] = dataclasses.field(default_factory=dict)
    _known: dict[int, NDArray[np.bool_]] = dataclasses.field(default_factory=dict)
    _low_rows: dict[int, tuple[object, NDArray[np.intp]]] = dataclasses.field(default_factory=dict)

    @functools.cached_property
    def above(self) -> NDArray[np.bool_]:
        """Per reach row: the arm's lowest point at least ``ground`` above z_B = 0 (N,)."""
        if self.ground is None:
            return np.ones(len(self.reach), dtype=bool)
        return np.asarray(self.roadmap.node_ground[self.reach] >= self.ground)

    def __call__(self, rows: NDArray[np.intp]) -> NDArray[np.bool_]:
        """Whether the nodes ``reach[rows]`` clear the robot and the ground."""
        return self.eligible()[rows]

    def eligible(self) -> NDArray[np.bool_]:
        """Per reach row: clears the ground and keeps the clearance from the robot (N,)."""
        return self._eligible

    @functools.cached_property
    def _eligible(self) -> NDArray[np.bool_]:
        clear = self.roadmap.node_clearance[self.reach] >= MOVE_CLEARANCE
        return np.asarray(self.above & clear)

    @functools.cached_property
    def _pieces(self) -> KeptPieces:
        assert self.under is not None
        return KeptPieces(self.under, self.roadmap.nodes_q)  # by node (no copy of the reach's)

    def low(self, poses: int) -> list[NDArray[np.intp]]:
        """Per pose, the eligible rows it may not choose: too low there, or ``excluded``."""
        out = []
        for k in range(poses):  # kept until pose k learns a low row or its exclusion changes
            self._start(k)
            kept = self._low_rows.get(k)
            if kept is not None and kept[0] is self.excluded.get(k):
                out.append(kept[1])
                continue
            masks = [m[k] for m in (self._low, self.excluded) if k in m]
            out.append(np.flatnonzero(np.logical_or.reduce(masks)) if masks else _NONE)
            self._low_rows[k] = (self.excluded.get(k), out[-1])
        return out

    def measure(self, rows: list[NDArray[np.intp]]) -> None:
        """Measure each pose's ``rows`` against the ground under the arm there (learnt)."""
        if self.under is None or self.ground is None:
            return
        for k in range(len(rows)):
            self._start(k)
        todo = [_distinct(x[~self._known[k][x]]) for k, x in enumerate(rows)]
        for k, x in enumerate(todo):  # high above the highest ground in reach: clear
            if x.size:
                sure = self.under.surely_clear(k, self._lowest[0][x], self.ground)
                self._known[k][x[sure]] = True
                todo[k] = x[~sure]
        self._pieces.add(self.reach[np.concatenate([np.zeros(0, dtype=np.intp), *todo])])
        for k, x in enumerate(todo):
            if x.size:
                q = self.roadmap.nodes_q[self.reach[x]]
                clear = self.under.clear(k, q, self.ground, self._pieces.view(self.reach[x]))
                self._known[k][x] = True
                if not clear.all():
                    self._low[k][x[~clear]] = True
                    self._low_rows.pop(k, None)

    @functools.cached_property
    def _lowest(self) -> tuple[FloatArray, NDArray[np.intp]]:
        """Per reach row its pieces' least z_B over the tilts [m]; the rows that may be low.

        A row whose pieces' least z_B, over the pose's cos_tilt, is below the clearance is
        too low at that pose whatever the ground (the measure takes a piece's height above
        the ground as at most that), and only rows below the clearance in z_B can be.
        """
        assert self.under is not None and self.ground is not None
        lowest = node_lowest(self.roadmap, self.under)[self.reach]
        return lowest, np.flatnonzero(~(lowest >= self.ground - SLACK))  # NaN: maybe

    def _start(self, k: int) -> None:
        """Pose k's rows known before measuring: those too low there (:attr:`_lowest`).

        The same answers as measuring them, learnt at once: without them a search measured
        hundreds of thousands of such rows a route, chosen and found low round after round.
        """
        if k in self._known or self.under is None or self.ground is None:
            return
        n = len(self.reach)
        known, low = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        lowest, maybe = self._lowest
        sure = maybe[lowest[maybe] / self.under.poses[k].cos_tilt < self.ground - SLACK]
        known[sure] = low[sure] = True  # the measure's own test
        self._known[k], self._low[k] = known, low

    def at(self, k: int, rows: NDArray[np.intp]) -> NDArray[np.bool_]:
        """Whether the rows (M,) keep the arm ``ground`` up at pose ``k`` (measured, learnt)."""
        if self.under is None or self.ground is None:
            return np.ones(len(rows), dtype=bool)
        self.measure([np.zeros(0, dtype=np.intp)] * k + [np.asarray(rows)])
        return np.asarray(~self._low[k][rows])


_NONE, _NO_V = np.zeros(0, dtype=np.intp), np.zeros(0)


def _distinct(rows: NDArray[np.intp]) -> NDArray[np.intp]:
    """``rows`` once each: as they are when already increasing, else ``np.unique``."""
    if len(rows) < 2 or bool((rows[1:] > rows[:-1]).all()):
        return rows
    return np.unique(rows)


class Candidates(NamedTuple):
    """Each pose's candidate nodes.

    Attributes:
        rows: reach rows (K, count).
        value: Eq. 6's stability term (K, count); -inf where unstable (μ ≤ 0) or not clear.
        mu: force-angle measure (K, count) [N rad].
    """

    rows: NDArray[np.intp]
    value: FloatArray
    mu: FloatArray


@dataclasses.dataclass
class SearchMemo:
    """What the searches of one route share (its poses' fits, clusters and rows fixed).

    Attributes:
        bounds: :func:`cluster_bounds` at the route's poses (None: not computed yet).
        order: :func:`proof_order` of them for the eligible rows ``order_for``.
        order_for: the eligible rows ``order`` was computed for.
        scored: per pose, the rows valued last (ascending) and their values: a row's value
            does not depend on the search, so a later search looks them up.
    """

    bounds: tuple[FloatArray, FloatArray] | None = None
    order: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None
    order_for: NDArray[np.bool_] | None = None
    scored: list[tuple[NDArray[np.intp], FloatArray]] = dataclasses.field(default_factory=list)


def route_candidates(
    fits: list[LinearFitness],
    samples: FloatArray,
    bins: NDArray[np.intp],
    cl: NodeClusters,
    count: int,
    clear: NodeClearance,
    before: Candidates | None = None,
    changed: NDArray[np.intp] | None = None,
    memo: SearchMemo | None = None,
) -> Candidates:
    """Every pose's ``count`` best clear nodes spread over the turret bins (module text).

    Args:
        fits: Eq. 6 per pose (stability term only: ``w_motion`` 0).
        samples: the reach rows' arm CoMs, body frame (N, 3) [m].
        bins: their turret bins (N,).
        cl: their clusters (:func:`node_clusters`).
        count: candidates per pose (at most N).
        clear: the clearance test; a chosen node measured too close (or, at its pose, too
            low above the ground) is dropped and the choice is made again, until every
            finite choice is clear.
        before: the candidates of a search before (None: none).
        changed: with ``before``, the poses whose exclusions changed since: only they are
            chosen again, the others' candidates kept (None: all chosen again).
        memo: what the route's searches share (kept in it; None: this search's own).

    A pose's choice depends on its own fitness, exclusions and rows found too low only, so
    each round chooses again only at the poses whose choice held a row found too low (the
    others' choices stand: the same answer as choosing every pose again).
    """
    K, rank = len(fits), rank_bound(cl.bin_rows, count)
    if before is None:
        rows, value = np.empty((K, count), dtype=np.intp), np.empty((K, count))
        todo = np.arange(K)
    else:
        rows, value = before.rows.copy(), before.value.copy()
        todo = np.unique(np.asarray(changed if changed is not None else np.arange(K), np.intp))
    redone = np.zeros(K, dtype=bool)  # the poses chosen again (their mu recomputed)
    ahead = np.full(K, 4)  # the next best measured too, more where picks were too low
    memo = SearchMemo() if memo is None else memo
    if memo.bounds is None:
        memo.bounds = cluster_bounds(cl, fits)
    if not memo.scored:
        memo.scored = [(_NONE, _NO_V)] * K
    bounds_all = memo.bounds
    slot, hit = np.full(len(samples), -1, dtype=np.intp), np.zeros(len(samples), dtype=bool)
    scored, kept_v = [r for r, _ in memo.scored], [v for _, v in memo.scored]
    while len(todo):
        redone[todo] = True
        eligible, low_all = clear.eligible(), clear.low(K)
        order = memo.order
        stands = memo.order_for is not None and np.array_equal(eligible, memo.order_for)
        if order is None or not stands:  # kept while the eligible rows stand
            order = memo.order = proof_order(cl, eligible, bounds_all[0])
            memo.order_for = eligible.copy()
        fits_todo, low = [fits[k] for k in todo], [low_all[k] for k in todo]
        bounds, kept = (bounds_all[0][todo], bounds_all[1][todo]), (order[0], order[1][todo])
        union, tau, reaches = scored_rows(cl, fits_todo, eligible, rank, low, bounds, kept)
        more = [_NONE] * K
        union_bins, union_bad = bins[union], ~eligible[union]
        for j, (k, fit) in enumerate(zip(todo, fits_todo, strict=True)):
            at = np.flatnonzero(reaches[j])  # the rest lie below the threshold: never in ``top``
            sub, bad, sub_bins = union[at], union_bad[at], union_bins[at]
            v = scored_values(fit, samples, sub, scored[k], kept_v[k], slot)
            scored[k], kept_v[k] = sub, v.copy()  # a row's value is computed once a search
            v[bad] = -np.inf
            if len(low[j]):  # too low above the ground at this pose
                hit[low[j]] = True
                v[hit[sub]] = -np.inf
                hit[low[j]] = False
            top = np.flatnonzero(v >= tau[j, sub_bins] - BOUND_SLACK)  # the rest rank >= R
            pick = top[spread_top(v[top], sub_bins[top], count)]
            n = len(pick)  # < count only when fewer nodes than count are eligible
            rows[k, n:], value[k, n:] = sub[pick[0]] if n else 0, -np.inf
            rows[k, :n], value[k, :n] = sub[pick], v[pick]
            best = top[np.isfinite(v[top])]
            if len(best) > count * ahead[k]:
                best = np.sort(
                    best[np.argpartition(-v[best], count * ahead[k])[: count * ahead[k]]]
                )
            more[k] = sub[best]
        finite = np.isfinite(value)
        near = clear(np.unique(rows[finite])).all()  # both tests learn what they measure
        clear.measure(more)
        low_all = clear.low(K)
        deep = np.array([among(rows[k, finite[k]], low_all[k]).any() for k in range(K)], bool)
        if near and not deep.any():
            break
        ahead = np.where(deep, np.minimum(2 * ahead, 32), ahead)
        todo = np.flatnonzero(deep) if near else np.arange(K)
    memo.scored = list(zip(scored, kept_v, strict=True))
    mu = np.empty(rows.shape) if before is None else before.mu.copy()
    for k in np.flatnonzero(redone):
        mu[k] = fits[k].mu(samples[rows[k]])
        value[k] = np.where(mu[k] > 0, value[k], -np.inf)
    return Candidates(rows, value, mu)


# The rows a pose's candidates are picked from: the rank bound of the picks within their
# turret bins, the round robin over the bins, and the values of a search's rows, each row
# scored once per search.


def rank_bound(bin_rows: NDArray[np.intp], count: int) -> int:
    """The smallest R with Σ_b min(R, n_b) ≥ count: chosen rows rank below R in their bin."""
    n = np.sort(np.asarray(bin_rows))
    for r in range(1, int(n.max(initial=0)) + 1):
        if int(np.minimum(n, r).sum()) >= count:
            return r
    return int(n.max(initial=0))


def spread_top(values: FloatArray, bins: NDArray[np.intp], count: int) -> NDArray[np.intp]:
    """``count`` rows: the best of every turret bin in turn (round robin), best first.

    The same answer as :func:`mmstab.planner.searches.sequence._diverse_top` (ties by row order),
    without a Python loop over the bins.
    """
    leaders = bin_leaders(values, bins, count)
    if leaders is not None:  # the rows ranked past the picks' ranks in their bins left out
        return leaders[_spread_top(values[leaders], bins[leaders], count)]
    return _spread_top(values, bins, count)


def _spread_top(values: FloatArray, bins: NDArray[np.intp], count: int) -> NDArray[np.intp]:
    """:func:`spread_top` of every row given."""
    order = np.argsort(-values, kind="stable")
    b = bins[order]
    if len(b) and 0 <= b.min() and b.max() < 256:  # a radix sort: the same stable order
        b = b.astype(np.uint8)
    by_bin = np.argsort(b, kind="stable")  # value order kept within each bin
    sb = b[by_bin]
    rank = np.empty(len(order), dtype=np.intp)
    rank[by_bin] = np.arange(len(order)) - np.searchsorted(sb, sb, side="left")
    if len(order) > count > 0:  # rows ranked past the count-th smallest rank come later
        keep = np.flatnonzero(rank <= np.partition(rank, count - 1)[count - 1])
        order, rank = order[keep], rank[keep]
    chosen = order[np.lexsort((-values[order], rank))][:count]
    return chosen[np.argsort(-values[chosen], kind="stable")]


def bin_leaders(values: FloatArray, bins: NDArray[np.intp], count: int) -> NDArray[np.intp] | None:
    """Rows (ascending) holding :func:`spread_top`'s picks, or None: take every row.

    The picks rank at most c in their bins (by value, from 0), c the smallest r with
    Σ_b min(r + 1, n_b) ≥ ``count``; a row below its bin's (c + 1)-th largest value ranks
    past c. The rows kept keep their ranks (every row above one in its bin is kept), so
    :func:`spread_top` of them picks the same rows in the same order. None when no row
    can be left out, the bins are not 0..255, a value is NaN, or the bins are so uneven that
    the padded (bins x largest bin) table costs more than the sort it saves.
    """
    n = len(values)
    if n <= count or count <= 0 or bins.min() < 0 or bins.max() >= 256:
        return None
    b = bins.astype(np.uint8)
    n_b = np.bincount(b)
    width = int(n_b.max())
    if len(n_b) * width > 4 * n or bool(np.isnan(values).any()):
        return None
    covered = np.minimum(np.arange(1, width + 1)[:, None], n_b[None, :]).sum(axis=1)
    c = int(np.searchsorted(covered, count))  # covered[r]: rows ranked at most r
    if c + 1 >= width:
        return None
    by_bin = np.argsort(b, kind="stable")
    sb = b[by_bin]
    pad = np.full((len(n_b), width), -np.inf)
    pad[sb, np.arange(n) - np.r_[0, np.cumsum(n_b)[:-1]][sb]] = values[by_bin]
    least = np.partition(pad, width - c - 1, axis=1)[:, width - c - 1]  # (c + 1)-th largest
    return np.flatnonzero(values >= least[b])


def among(rows: NDArray[np.intp], sorted_rows: NDArray[np.intp]) -> NDArray[np.bool_]:
    """Whether each of ``rows`` is one of ``sorted_rows`` (ascending)."""
    at = np.minimum(np.searchsorted(sorted_rows, rows), max(len(sorted_rows) - 1, 0))
    return np.asarray(sorted_rows[at] == rows) if len(sorted_rows) else np.zeros(len(rows), bool)


def scored_values(
    fit: LinearFitness,
    samples: FloatArray,
    rows: NDArray[np.intp],
    before: NDArray[np.intp],
    values: FloatArray,
    slot: NDArray[np.intp],
) -> FloatArray:
    """Eq. 6's values [-] of reach rows ``rows`` (distinct), each scored once a search.

    A row's value does not depend on the rows scored with it, so those of ``before``
    (distinct, the last round's) are taken from their ``values``.

    Args:
        fit: Eq. 6 at the pose.
        samples: the reach rows' arm CoMs, body frame (N, 3) [m].
        rows: the rows to value.
        before: rows valued before.
        values: their values [-].
        slot: -1 per reach row (N,), scratch: each of ``before``'s index there meanwhile.
    """
    if len(before) == 0:
        return np.asarray(fit(samples[rows]))
    slot[before] = np.arange(len(before))
    at = slot[rows]
    slot[before] = -1
    new = np.flatnonzero(at < 0)
    v = values[at]  # the new rows' (at -1) overwritten below
    if new.size:
        v[new] = fit(samples[rows[new]])
    return v
