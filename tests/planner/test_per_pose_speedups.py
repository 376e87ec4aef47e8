"""The one-off plan's per-pose speed-ups compute the same floats as the code they replace.

Each faster function is compared, bitwise, with the computation it replaced (kept here as
the reference) on seeded random inputs with ties, infinities and NaN; the plans themselves
are compared in ``test_plans_unchanged.py``.
"""

from __future__ import annotations

import gc

import numpy as np

from mmstab.planner import candidates
from mmstab.planner.fitness import LinearFitness
from mmstab.planner.plan import freeze_long_lived
from mmstab.stability.static import _cross_last
from mmstab.terrain.polygon import _cross


def spread_top_before(values, bins, count):  # type: ignore[no-untyped-def]
    """``spread_top`` as it was: three stable sorts over every row."""
    order = np.argsort(-values, kind="stable")
    b = bins[order]
    by_bin = np.argsort(b, kind="stable")
    sb = b[by_bin]
    rank = np.empty(len(order), dtype=np.intp)
    rank[by_bin] = np.arange(len(order)) - np.searchsorted(sb, sb, side="left")
    chosen = order[np.lexsort((-values[order], rank))][:count]
    return chosen[np.argsort(-values[chosen], kind="stable")]


def test_spread_top_picks_the_rows_it_picked_before():
    rng = np.random.default_rng(7)
    for _ in range(2000):
        n = int(rng.integers(0, 300))
        values = np.round(rng.normal(size=n), int(rng.integers(0, 3)))  # ties
        values[rng.uniform(size=n) < 0.1] = -np.inf
        nbins = int(rng.integers(1, 300))  # past 256 bins: no radix sort
        bins = rng.integers(0, nbins, n)
        count = int(rng.integers(0, 320))
        want = spread_top_before(values, bins, count)
        np.testing.assert_array_equal(candidates.spread_top(values, bins, count), want)


def test_the_bounds_min_over_axes_is_numpys():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(4, 50, 7)).astype(np.float32)
    a[0, 3, 2] = np.nan
    a[1, 4, :] = np.pi
    np.testing.assert_array_equal(candidates._min_last(a), a.min(axis=2))


def test_the_cross_products_are_numpys_to_the_bit():
    rng = np.random.default_rng(5)
    for _ in range(2000):
        scale = 10 ** rng.uniform(-6, 6, size=2)
        a, b = rng.normal(size=3) * scale[0], rng.normal(size=3) * scale[1]
        np.testing.assert_array_equal(_cross(a, b), np.cross(a, b))
        A = rng.normal(size=(2, 5, 3)) * scale[0]
        B = rng.normal(size=(1, 5, 3)) * scale[1]
        np.testing.assert_array_equal(_cross_last(A, B), np.cross(A, B))


def test_eq6_without_its_motion_term_is_the_same_floats():
    rng = np.random.default_rng(11)
    fit = LinearFitness(
        sin_gain=rng.normal(size=(3, 5)) * 100,
        sin_offset=rng.normal(size=5) * 50,
        cos_gain=rng.normal(size=(3, 5)) * 100,
        cos_offset=rng.normal(size=5) * 50,
        force=620.0,
        previous_com=np.array([0.1, -0.2, 0.3]),
        w_stability=1 / 370.0,
        w_motion=0.0,
    )
    coms = rng.normal(size=(1000, 3)) * 0.4
    theta = np.arctan2(coms @ fit.sin_gain + fit.sin_offset, coms @ fit.cos_gain + fit.cos_offset)
    np.testing.assert_array_equal(fit.mu(coms), theta.min(axis=1) * fit.force)
    motion = np.sum((coms - fit.previous_com) ** 2, axis=1)
    want = fit.w_stability * fit.mu(coms) - fit.w_motion * motion  # the formula in full
    np.testing.assert_array_equal(fit(coms), want)
    moving = fit._replace(w_motion=0.5)
    np.testing.assert_array_equal(moving(coms), moving.w_stability * moving.mu(coms) - 0.5 * motion)


def test_the_long_lived_objects_are_frozen_once_a_process():
    freeze_long_lived()
    frozen = gc.get_freeze_count()
    assert frozen > 0
    kept = [[i] for i in range(100)]  # objects the collector tracks, made after the freeze
    freeze_long_lived()  # a second plan: nothing more frozen (frozen objects may still die)
    assert gc.get_freeze_count() <= frozen and len(kept) == 100


def test_a_loop_that_unfreezes_all_leaves_the_next_plan_to_freeze_again():
    from mmstab.planner.plan import unfreeze_long_lived

    freeze_long_lived()
    assert gc.get_freeze_count() > 0
    unfreeze_long_lived()  # as the online loop ends (it froze its own set-up)
    assert gc.get_freeze_count() == 0
    freeze_long_lived()  # the next plan in this process
    assert gc.get_freeze_count() > 0
