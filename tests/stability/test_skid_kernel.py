"""The skid-steer model's Newton loop in C (``skid.c``) against its NumPy twin."""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.stability import skid
from mmstab.stability.skid import belts_for_twist, skid_twist, track_patch


def _states(rng: np.random.Generator, n: int):
    """Seeded slopes up to 29 deg (some beyond the cone), CoMs, and belts: pivots, arcs,
    straight runs and standing belts."""
    tilt, az = rng.uniform(0.0, 0.5, n), rng.uniform(-np.pi, np.pi, n)
    g = 9.81 * np.c_[np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), -np.cos(tilt)]
    com = np.c_[rng.normal(0.0, 0.06, n), rng.normal(0.0, 0.05, n), rng.uniform(0.05, 0.3, n)]
    v, w = rng.choice([0.0, 0.15, 0.3], n), rng.choice([0.0, 0.3, -0.6, 1.0], n)
    return g, com, v, w


@pytest.mark.parametrize("shear", [0.0, 0.0041, 0.05])
def test_the_c_loop_equals_numpys(robot, shear):
    patch = track_patch(robot)
    g, com, v, w = _states(np.random.default_rng(4), 300)
    belts = belts_for_twist(v, w, patch.separation)
    a = skid_twist(patch, g, com, belts, 0.7, shear, backend="numpy")
    b = skid_twist(patch, g, com, belts, 0.7, shear, backend="c")
    za, zb = np.c_[a.velocity_body, a.yaw_rate], np.c_[b.velocity_body, b.yaw_rate]
    np.testing.assert_array_equal(np.isnan(za), np.isnan(zb))  # the same rows hold
    assert np.isnan(za).any(axis=1).sum() > 0  # some beyond the cone or the belts
    standing = np.abs(belts).max(axis=1) <= 1e-9
    assert standing.any() and np.all(zb[standing & b.holds] == 0.0)
    ok = ~np.isnan(za)
    np.testing.assert_allclose(zb[ok], za[ok], rtol=0, atol=1e-8)  # [m/s], [rad/s]
    np.testing.assert_array_equal(b.holds, a.holds)
    np.testing.assert_array_equal(b.commanded, a.commanded)


def test_without_a_compiler_numpy_answers(robot, monkeypatch):
    patch = track_patch(robot)
    g, com, v, w = _states(np.random.default_rng(5), 40)
    belts = belts_for_twist(v, w, patch.separation)
    ref = skid_twist(patch, g, com, belts, 0.7, backend="numpy")
    monkeypatch.setattr(skid, "_kernel", lambda: None)
    got = skid_twist(patch, g, com, belts, 0.7)  # the default backend, falling back
    np.testing.assert_array_equal(got.yaw_rate, ref.yaw_rate)
    np.testing.assert_array_equal(got.velocity_body, ref.velocity_body)
