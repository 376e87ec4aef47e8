"""method roadmap's candidates by branch and bound (mmstab.planner.candidates) equal the
candidates of scoring every node; the culled clearance is exact below its cut."""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.model.collision import CollisionChecker
from mmstab.planner.candidates import (
    cluster_bounds,
    node_clusters,
    rank_bound,
    route_candidates,
    scored_rows,
    spread_top,
)
from mmstab.planner.fitness import linear_fitness
from mmstab.planner.searches.roadmap import TURRET_BINS, node_coms
from mmstab.planner.searches.sequence import _diverse_top, _turret_bins
from mmstab.stability.static import base_polygon, mu_max
from mmstab.workspace import build_workspace
from mmstab.workspace.roadmap import build_roadmap

GRID = (12, 10, 9, 9)


@pytest.fixture(scope="module")
def nodes(robot):
    ws = build_workspace(robot, GRID, progress=False)
    rm = build_roadmap(robot, ws)
    reach = np.flatnonzero(rm.component == np.bincount(rm.component).argmax())
    coms = node_coms(robot, rm)[reach]
    bins = _turret_bins(rm.nodes_q[reach, 0], TURRET_BINS)
    return coms, bins, rm


def _fits(robot, coms, rng, poses):
    """Eq. 6's stability term at random tilts up to 0.6 rad (gravity in B)."""
    polygon = base_polygon(robot).vertices
    out = []
    for _ in range(poses):
        tilt, az = rng.uniform(0, 0.6), rng.uniform(-np.pi, np.pi)
        g = -9.81 * np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
        w = 0.9 / mu_max(robot)
        out.append(linear_fitness(robot, polygon, g, robot.arm_com(robot.stowed), w, 0.0))
    return out


class FakeClearance:
    """A clearance test with a fixed set of too-close rows, learnt as rows are measured."""

    def __init__(self, too_close: np.ndarray, n: int):
        self.bad = np.zeros(n, dtype=bool)
        self.bad[too_close] = True
        self.known = np.zeros(n, dtype=bool)

    def __call__(self, rows):
        self.known[rows] = True
        return ~self.bad[rows]

    def eligible(self):
        return ~(self.known & self.bad)

    def low(self, poses):
        return [np.zeros(0, dtype=np.intp)] * poses

    def measure(self, rows):
        pass


class FakePoseClearance(FakeClearance):
    """Too-close rows as FakeClearance, and per pose a set of rows too low, learnt as measured."""

    def __init__(self, too_close: np.ndarray, n: int, too_low: list[np.ndarray]):
        super().__init__(too_close, n)
        self.deep = np.zeros((len(too_low), n), dtype=bool)
        for k, rows in enumerate(too_low):
            self.deep[k, rows] = True
        self.measured = np.zeros_like(self.deep)

    def low(self, poses):
        return [np.flatnonzero(self.measured[k] & self.deep[k]) for k in range(poses)]

    def measure(self, rows):
        for k, r in enumerate(rows):
            self.measured[k, r] = True


def _reference(fit, coms, bins, count, clear):
    """Every node scored; a chosen too-close node dropped and the choice remade."""
    members = [np.flatnonzero(bins == b) for b in range(TURRET_BINS)]
    v = fit(coms)
    v[~clear.eligible()] = -np.inf
    while True:
        rows = _diverse_top(v, bins, count, members)
        finite = rows[np.isfinite(v[rows])]
        bad = finite[~clear(finite)]
        if bad.size == 0:
            return rows, v[rows]
        v[bad] = -np.inf


@pytest.mark.parametrize("size", [0.02, 0.05])
def test_branch_and_bound_candidates_equal_scoring_every_node(robot, nodes, size):
    coms, bins, _ = nodes
    rng = np.random.default_rng(5)
    fits = _fits(robot, coms, rng, 12)
    cl = node_clusters(coms, bins, TURRET_BINS, size)
    too_close = rng.choice(len(coms), len(coms) // 20, replace=False)
    count = 96
    got = route_candidates(fits, coms, bins, cl, count, FakeClearance(too_close, len(coms)))
    every, rank = np.ones(len(coms), dtype=bool), rank_bound(cl.bin_rows, count)
    scored = [len(scored_rows(cl, [f], every, rank)[0]) / len(coms) for f in fits]
    assert np.median(scored) < 0.5, scored  # the bounds prune (else the test proves little)
    ref_clear = FakeClearance(too_close, len(coms))
    for k, fit in enumerate(fits):
        rows, value = _reference(fit, coms, bins, count, ref_clear)
        np.testing.assert_array_equal(got.rows[k], rows)
        mu = fit.mu(coms[rows])
        np.testing.assert_array_equal(got.value[k], np.where(mu > 0, value, -np.inf))


def _low_poses(robot, coms, seed: int, poses: int, best: int, low: int):
    """Seeded poses' fits, each with up to ``low`` of its ``best`` rows too low, and the rows
    too close (a fortieth)."""
    rng = np.random.default_rng(seed)
    fits = _fits(robot, coms, rng, poses)
    tops = [np.argsort(-f(coms))[:best] for f in fits]  # too low: many of each pose's best
    too_low = [rng.choice(b, int(rng.integers(0, low)), replace=False) for b in tops]
    return fits, too_low, rng.choice(len(coms), len(coms) // 40, replace=False)


def test_candidates_with_rows_too_low_at_some_poses_equal_scoring_every_node(robot, nodes):
    """Per-pose eligibility (the ground under the arm): each pose's proofs count its own rows."""
    coms, bins, _ = nodes
    fits, too_low, too_close = _low_poses(robot, coms, 8, 10, 2000, 1500)
    cl = node_clusters(coms, bins, TURRET_BINS, 0.04)
    count = 96
    clear = FakePoseClearance(too_close, len(coms), too_low)
    got = route_candidates(fits, coms, bins, cl, count, clear)
    for k, fit in enumerate(fits):
        ref_clear = FakeClearance(np.union1d(too_close, too_low[k]), len(coms))
        rows, value = _reference(fit, coms, bins, count, ref_clear)
        np.testing.assert_array_equal(got.rows[k], rows)
        mu = fit.mu(coms[rows])
        np.testing.assert_array_equal(got.value[k], np.where(mu > 0, value, -np.inf))
        assert not np.isin(got.rows[k][np.isfinite(got.value[k])], too_low[k]).any()
    assert sum(len(x) for x in clear.low(len(fits))) > 0  # some picks were found too low


class FakeExcluding(FakePoseClearance):
    """FakePoseClearance with per-pose exclusions (the climb and slide limits' masks)."""

    excluded: dict[int, np.ndarray] = {}

    def low(self, poses):
        low = super().low(poses)
        return [np.union1d(x, self.excluded.get(k, x[:0])) for k, x in enumerate(low)]


def test_candidates_chosen_again_at_changed_poses_equal_scoring_every_node(robot, nodes):
    """A second search after new exclusions at some poses chooses only those again."""
    coms, bins, _ = nodes
    fits, too_low, too_close = _low_poses(robot, coms, 11, 8, 1500, 800)
    cl = node_clusters(coms, bins, TURRET_BINS, 0.04)
    count = 64
    clear = FakeExcluding(too_close, len(coms), too_low)
    first = route_candidates(fits, coms, bins, cl, count, clear)
    changed = np.array([2, 5])
    # the first picks' better half excluded there: the choice must change
    clear.excluded = {int(k): first.rows[k][np.isfinite(first.value[k])][: count // 2]
                      for k in changed}  # fmt: skip
    kept = first._replace(value=first.value.copy())

    class Untouched(type(fits[0])):  # the other poses' fits: their bounds only, no value
        def __call__(self, com_body):
            raise AssertionError("an unchanged pose was scored again")

        def mu(self, com_body):
            raise AssertionError("an unchanged pose's mu was computed again")

    guarded = [f if k in changed else Untouched(*f) for k, f in enumerate(fits)]
    got = route_candidates(guarded, coms, bins, cl, count, clear, kept, changed)
    for k, fit in enumerate(fits):
        out = np.union1d(too_low[k], clear.excluded.get(k, too_low[k][:0]))
        rows, value = _reference(
            fit, coms, bins, count, FakeClearance(np.union1d(too_close, out), len(coms))
        )
        np.testing.assert_array_equal(got.rows[k], rows)
        mu = fit.mu(coms[rows])
        np.testing.assert_array_equal(got.value[k], np.where(mu > 0, value, -np.inf))
        np.testing.assert_array_equal(got.mu[k], mu)
        if k not in changed:
            np.testing.assert_array_equal(got.rows[k], first.rows[k])
        else:
            assert not np.array_equal(got.rows[k], first.rows[k])


def test_cluster_bounds_hold_for_every_member(robot, nodes):
    coms, bins, _ = nodes
    fits = _fits(robot, coms, np.random.default_rng(9), 6)
    cl = node_clusters(coms, bins, TURRET_BINS, 0.05)
    lower, upper = cluster_bounds(cl, fits)
    for k, fit in enumerate(fits):
        v = fit(coms)
        assert np.all(v <= upper[k, cl.cluster_of] + 1e-12)
        assert np.all(v >= lower[k, cl.cluster_of] - 1e-12)
        # bounds that prune: most clusters are bounded within 0.05 of their value range
        assert np.median(upper[k] - lower[k]) < 0.05


def test_spread_top_equals_the_round_robin_with_ties_and_minus_infinity():
    rng = np.random.default_rng(2)
    for _ in range(20):
        n = int(rng.integers(5, 400))
        values = np.round(rng.normal(size=n), 1)  # many ties
        values[rng.random(n) < 0.2] = -np.inf
        bins = rng.integers(0, 7, n)
        count = int(rng.integers(1, n + 1))
        np.testing.assert_array_equal(
            spread_top(values, bins, count), _diverse_top(values, bins, count)
        )


def test_rank_bound():
    assert rank_bound(np.array([100, 100, 100]), 7) == 3
    assert rank_bound(np.array([1, 1, 100]), 10) == 8  # 1 + 1 + 8
    assert rank_bound(np.array([5, 5]), 10) == 5


def test_culled_clearance_is_exact_below_the_cut(robot, nodes):
    """Collision-free grid postures, some a few mm from the robot, some far."""
    rm = nodes[2]
    q = rm.nodes_q[np.random.default_rng(4).choice(len(rm.nodes_q), 400, replace=False)]
    checker = CollisionChecker(robot)
    exact = checker.clearance(q)
    for cut in (0.003, 0.008):  # (a link keeps 1 cm from the body at every posture)
        culled = checker.clearance(q, cull_above=cut)
        below = exact < cut
        assert below.any() and (~below).any()
        np.testing.assert_array_equal(culled[below], exact[below])
        assert np.all(culled[~below] >= cut)
        assert np.all(culled[~below] <= exact[~below] + 1e-12)


def test_spread_top_of_the_bins_leaders_equals_spread_top_of_every_row():
    """bin_leaders leaves rows out only when spread_top's picks are the same, same order."""
    from mmstab.planner.candidates import _spread_top, bin_leaders

    rng = np.random.default_rng(7)
    filtered = 0
    for i in range(2000):
        n, n_bins = int(rng.integers(0, 700)), int(rng.integers(1, 30))
        v = rng.integers(0, 12, n).astype(float) if i % 2 else rng.normal(size=n)
        v[rng.random(n) < 0.1] = -np.inf  # too close or too low
        bins = rng.integers(0, n_bins, n)
        count = int(rng.integers(1, 300))
        filtered += bin_leaders(v, bins, count) is not None
        assert np.array_equal(spread_top(v, bins, count), _spread_top(v, bins, count))
    assert filtered > 1000  # the shortcut taken in most cases
