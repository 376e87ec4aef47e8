"""The climb limit's rolls: computed only where a sample may lift the wheel, the same answer.

``mmstab.stability.climb._worst_contact`` rolls the front wheels over the ground ahead and
computes a roll only near samples above the support plane (a sample at or below it never
lifts the wheel off the plane). Here it is compared with the whole computation over every
roll (the function as it was, kept below) on seeded random profiles: flat ground below the
plane, bumps, kerbs lower and higher than the wheel's radius, walls, ground off the map
(-inf), unknown ground (NaN), a sample exactly at the wheel's radius.
"""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.stability.climb import SAMPLE_STEP, _lifted_rolls, _worst_contact


def _every_roll(z: np.ndarray, rolls: int, r: float) -> tuple[float, float]:
    """The whole computation: every roll's window (the function before the rolls were cut)."""
    w = int(np.ceil(r / SAMPLE_STEP))
    offset = np.arange(-w, w + 1) * SAMPLE_STEP
    lift = np.where(np.abs(offset) < r, np.sqrt(np.maximum(r**2 - offset**2, 0.0)), -np.inf)
    pad = np.full((2, w + 1), -np.inf)
    zpad = np.concatenate([pad, z, pad], axis=1)
    windows = np.lib.stride_tricks.sliding_window_view(zpad, 2 * w + 1, axis=1)[:, :rolls]
    centre = windows + lift
    j = centre.argmax(axis=-1)
    top = np.take_along_axis(centre, j[..., None], -1)[..., 0]
    touch = np.take_along_axis(windows, j[..., None], -1)[..., 0]
    with np.errstate(invalid="ignore"):
        sin_roll = np.where(top <= r, 1.0, np.clip((top - touch) / r, -1.0, 1.0))
    k = int(sin_roll.argmin())
    return float(sin_roll.ravel()[k]), float((k % sin_roll.shape[1]) * SAMPLE_STEP)


def _profile(rng: np.random.Generator, n: int, r: float, kind: int) -> np.ndarray:
    """Two tracks' ground heights ahead (2, n) [m] of one of six kinds."""
    u = np.arange(1, n + 1) * SAMPLE_STEP
    z = rng.uniform(-0.03, 0.0, (2, 1)) + rng.normal(0.0, 0.002, (2, n)) * (kind != 0)
    if kind in (1, 5):  # bumps above and below the plane
        z = z + rng.uniform(0.0, 0.04) * np.sin(u / rng.uniform(0.02, 0.2) + rng.uniform(0, 6))
    if kind in (2, 5):  # a kerb of random height (below or above the wheel's radius)
        at = rng.uniform(0.05, 0.5)
        z = z + np.where(u > at, rng.uniform(0.005, 2.5 * r), 0.0)
    if kind == 3:  # a wall: far higher than the wheel
        z = np.where(u > rng.uniform(0.0, 0.4), 1.0, z)
    if kind == 4:  # off the map ahead, some unknown samples, one sample at r exactly
        z = np.where(u > rng.uniform(0.1, 0.5), -np.inf, z)
        z[rng.integers(0, 2), rng.integers(0, n, 3)] = np.nan
        z[rng.integers(0, 2), rng.integers(0, n)] = r
    if kind == 0:  # flat, a few samples barely above the plane
        z[:, rng.integers(0, n, 4)] = rng.uniform(0.0, 1e-6, 4)
    return np.asarray(z)


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("seed", range(6))
def test_worst_contact_equals_every_roll(seed: int, backend: str) -> None:
    rng = np.random.default_rng(4100 + seed)
    lifted = 0
    for trial in range(60):
        r = float(rng.uniform(0.03, 0.09))
        lookahead = float(rng.uniform(0.05, 0.6))
        n = len(np.arange(SAMPLE_STEP, r + lookahead + 1e-12, SAMPLE_STEP))
        rolls = int(np.floor(lookahead / SAMPLE_STEP + 1e-9)) + 1
        z = _profile(rng, n, r, trial % 6)
        fast, whole = _worst_contact(z, rolls, r, backend), _every_roll(z, rolls, r)
        np.testing.assert_equal(fast, whole)  # the same floats (NaN where the whole is NaN)
        lifted += fast[0] < 1.0
        marked = _lifted_rolls(z, rolls, r, int(np.ceil(r / SAMPLE_STEP)))
        if trial % 6 == 0:
            assert marked.mean() < 0.2  # flat ground: few rolls computed
    assert lifted > 20  # steps were met: the comparison covers the computed rolls


def test_no_roll_left_out_that_lifts_the_wheel() -> None:
    """Every roll whose centre rises above r (computed over all) is among those computed."""
    rng = np.random.default_rng(4200)
    for trial in range(40):
        r = float(rng.uniform(0.03, 0.09))
        n, rolls = 900, 700
        z = _profile(rng, n, r, 1 + trial % 5)
        w = int(np.ceil(r / SAMPLE_STEP))
        offset = np.arange(-w, w + 1) * SAMPLE_STEP
        lift = np.where(np.abs(offset) < r, np.sqrt(np.maximum(r**2 - offset**2, 0.0)), -np.inf)
        pad = np.full((2, w + 1), -np.inf)
        windows = np.lib.stride_tricks.sliding_window_view(
            np.concatenate([pad, z, pad], axis=1), 2 * w + 1, axis=1
        )[:, :rolls]
        with np.errstate(invalid="ignore"):
            up = ~((windows + lift).max(axis=-1) <= r)  # above r, or NaN
        assert not (up & ~_lifted_rolls(z, rolls, r, w)).any()
