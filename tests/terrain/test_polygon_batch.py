"""The batched support hulls and μ against the per-set reference (``hull_along``)."""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.stability.static import axis_angles, padded_axis_angles
from mmstab.terrain.polygon import hull_along
from mmstab.terrain.polygon_batch import hulls_along_batch


def _sets(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """N seeded support sets (N, K, 3) with masks: grids of track points, noise, degeneracies."""
    K = 40
    pts = np.zeros((n, K, 3))
    mask = np.zeros((n, K), dtype=bool)
    for i in range(n):
        kind = i % 6
        yaw, tilt = rng.uniform(-np.pi, np.pi), rng.uniform(-0.5, 0.5)
        cy, sy, ct, st = np.cos(yaw), np.sin(yaw), np.cos(tilt), np.sin(tilt)
        R = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]) @ np.array(
            [[1, 0, 0], [0, ct, -st], [0, st, ct]]
        )
        if kind in (0, 1):  # two tracks' bottom runs: rows of collinear points
            xs = np.arange(-0.5, 0.51, 0.05)
            body = np.array([[x, y, 0.0] for y in (-0.3, 0.3) for x in xs])
            body = body[rng.random(len(body)) < 0.8]
        elif kind == 2:  # scattered contacts in 3-D
            body = rng.uniform(-0.5, 0.5, size=(rng.integers(3, K), 3)) * [1, 1, 0.1]
        elif kind == 3:  # near-duplicates closer than 1 mm
            base = rng.uniform(-0.5, 0.5, size=(10, 3)) * [1, 1, 0.05]
            body = np.vstack([base, base[:5] + rng.normal(scale=3e-4, size=(5, 3))])
        elif kind == 4:  # collinear or nearly so
            s = rng.uniform(-0.5, 0.5, size=(8, 1))
            body = s * np.array([1.0, 0.3, 0.1]) + rng.normal(
                scale=10.0 ** -rng.integers(8, 17), size=(8, 3)
            )
        else:  # stacked along the force: the same 2-D point at two heights
            base = rng.uniform(-0.5, 0.5, size=(8, 3)) * [1, 1, 0.05]
            body = np.vstack([base, base[:3] + [0.0, 0.0, 0.02]])
        body = body[:K]
        pts[i, : len(body)] = body @ R.T + rng.uniform(-10, 10, size=3)
        mask[i, : len(body)] = True
    return pts, mask


@pytest.mark.parametrize("direction", [(0.0, 0.0, -9.81), (1.5, -2.0, -9.0)])
def test_batch_hulls_give_the_per_set_mu(direction):
    """Where the batch answers: the reference polygon up to its start (and rounding), the same μ."""
    rng = np.random.default_rng(7)
    pts, mask = _sets(rng, 300)
    f = np.asarray(direction) * 50.0
    hulls = hulls_along_batch(pts, mask, f)
    com = pts[:, 0] + [0.02, -0.03, 0.6]
    answered = exact = 0
    for i in range(len(pts)):
        try:
            ref = hull_along(pts[i][mask[i]], f)
        except ValueError:
            assert not hulls.ok[i], i  # the reference raises: the batch must not answer
            continue
        if not hulls.ok[i]:
            continue
        answered += 1
        got = hulls.vertices[i, : hulls.n_vertices[i]]
        # the same vertices in the same cyclic order, but for points Qhull keeps on an
        # edge's line (within its rounding): they change no axis beyond rounding
        start = int(np.flatnonzero((ref == got[0]).all(axis=1))[0])
        rolled = np.roll(ref, -start, axis=0)
        at = [int(np.flatnonzero((rolled == g).all(axis=1))[0]) for g in got]
        assert at == sorted(at), i
        exact += len(ref) == len(got)
        mu_ref = np.min(axis_angles(ref, com[i], f)) * np.linalg.norm(f)
        theta = padded_axis_angles(
            hulls.vertices[i : i + 1], hulls.n_vertices[i : i + 1], com[i : i + 1], f
        )
        assert abs(np.min(theta) * np.linalg.norm(f) - mu_ref) <= 1e-12, i
    assert answered >= 150  # the tracks' grids and scattered sets are answered
    assert exact >= 0.8 * answered


def test_degenerate_sets_are_left_to_the_reference():
    f = np.array([0.0, 0.0, -1.0])
    line = np.array([[[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]])
    dup = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0.0005, -0.0001, 0]]])
    two = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0]]])
    two_mask = np.array([[True, True, False, False]])
    for pts, mask in ((line, np.ones((1, 4), bool)), (dup, np.ones((1, 4), bool)), (two, two_mask)):
        assert not hulls_along_batch(pts, mask, f).ok[0]
    square = np.array([[[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]])
    h = hulls_along_batch(square, np.ones((1, 4), bool), f)
    assert h.ok[0] and h.n_vertices[0] == 4
    # CCW about up (+z): the signed area is positive
    v = h.vertices[0, :4, :2]
    assert 0.5 * np.sum(
        v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]
    ) == pytest.approx(1.0)
