"""The geometry of the resting pose: a body attitude's lifts, lever arms and their slopes.

For a pose ``(x, y, yaw)`` and an attitude ``(roll, pitch)`` [rad], a contact candidate
``c_k`` (in B) needs the body origin at ``f_k = h(xy_k) - (G_R_B c_k)_z`` [m] to touch the
ground ``h``; these are the batched evaluations of ``f_k``, of the lever arms and of their
derivatives that the NumPy solver (:mod:`mmstab.terrain.rest.numpy_path`) iterates on, and the
candidate subsets (sparse, footprint corners) that both solvers start from.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.terrain.heightmap import FloatArray, Heightmap
from mmstab.terrain.rest.types import BoolArray

#: Poses per block in the samplers of :func:`lift` and :func:`heights` (their (block,
#: candidates) temporaries stay in cache while a round works on the whole chunk).
BLOCK = 128


def rotations(yaw: FloatArray, roll: FloatArray, pitch: FloatArray) -> tuple[FloatArray, ...]:
    """``G_R_B = Rz(yaw) Ry(-pitch) Rx(roll)`` and its derivatives by roll and pitch (N, 3, 3)."""
    n = yaw.shape[0]
    cy, sy = np.cos(yaw), np.sin(yaw)
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    z, o = np.zeros(n), np.ones(n)
    Rz = np.stack([cy, -sy, z, sy, cy, z, z, z, o], axis=1).reshape(n, 3, 3)
    Ry = np.stack([cp, z, -sp, z, o, z, sp, z, cp], axis=1).reshape(n, 3, 3)
    Rx = np.stack([o, z, z, z, cr, -sr, z, sr, cr], axis=1).reshape(n, 3, 3)
    dRy = np.stack([-sp, z, -cp, z, z, z, cp, z, -sp], axis=1).reshape(n, 3, 3)
    dRx = np.stack([z, z, z, z, -sr, -cr, z, cr, -sr], axis=1).reshape(n, 3, 3)
    RzRy = Rz @ Ry
    return RzRy @ Rx, RzRy @ dRx, Rz @ dRy @ Rx


def products(R: FloatArray, c: FloatArray) -> FloatArray:
    """Rows of ``R`` (n, r, 3) against candidates ``c`` (K, 3) or per pose (n, K, 3) -> (n, r, K).

    One small matrix product per pose (a stacked ``matmul``): each is far below the size
    at which BLAS starts threads, which would only contend on a busy machine, and the
    result of a pose does not depend on the batch it is in.
    """
    return R @ (c.T if c.ndim == 2 else c.transpose(0, 2, 1))


def lift(
    hm: Heightmap, c: FloatArray, com: FloatArray, xy: FloatArray, yaw: FloatArray, att: FloatArray
) -> tuple[Any, ...]:
    """f_k (n, K), the lever arms (n, K, 2), CoM height gradient (n, 2), valid (n,), rows.

    ``c`` is (K, 3) shared by all poses or (n, K, 3) per pose. The lever arm ``-d (G_R_B
    c_k)_z / d(roll, pitch)`` leaves out the ground's slope under the moving point: it is
    the horizontal moment arm of a vertical contact force, the one that decides
    equilibrium. ``rows`` (n, 9, K) are R, dR/droll, dR/dpitch times the candidates, from
    which :func:`jacobian` takes the full ``J_k = d f_k / d(roll, pitch)`` of the few
    candidates the Newton step needs (the ground's slope is sampled only there).
    """
    R, dR_r, dR_p = rotations(yaw, att[:, 0], att[:, 1])
    # every row of R, dR/droll, dR/dpitch against every candidate
    m = products(np.concatenate([R, dR_r, dR_p], axis=1), c)  # (n, 9, K)
    n = m.shape[0]
    f, valid = np.empty((n, m.shape[2])), np.empty(n, dtype=bool)
    for i in range(0, n, BLOCK):  # blocks of poses keep the sampler's temporaries in cache
        b = slice(i, i + BLOCK)
        h, _, _, valid[b] = hm.sample_rows(
            xy[b, 0, None] + m[b, 0], xy[b, 1, None] + m[b, 1], slopes=False
        )
        f[b] = h - m[b, 2]
    grad = np.stack([np.einsum("nj,nj->n", dR[:, 2, :], com) for dR in (dR_r, dR_p)], axis=1)
    lever = np.stack([-m[:, 5], -m[:, 8]], axis=-1)
    return f, lever, grad, valid, m


def jacobian(hm: Heightmap, m: FloatArray, xy: FloatArray, tri: NDArray[np.int_]) -> FloatArray:
    """``J_k = d f_k / d(roll, pitch)`` (n, 3, 2) of the candidates ``tri`` (n, 3).

    Args:
        hm: the ground.
        m: (n, 9, K) rows of :func:`lift`.
        xy: (n, 2) pose positions in G [m].
        tri: (n, 3) candidate indices (artificial ones, >= K, are clipped: unused).
    """
    tri = np.minimum(tri, m.shape[2] - 1)
    mt = np.take_along_axis(m, tri[:, None, :], axis=2)  # (n, 9, 3)
    _, hx, hy, _ = hm.sample_rows(xy[:, 0, None] + mt[:, 0], xy[:, 1, None] + mt[:, 1])
    return np.stack([hx * mt[:, j] + hy * mt[:, j + 1] - mt[:, j + 2] for j in (3, 6)], axis=-1)


def heights(
    hm: Heightmap, c: FloatArray, xy: FloatArray, yaw: FloatArray, att: FloatArray
) -> tuple[FloatArray, BoolArray]:
    """Only the lifts f_k (n, K) [m] of the candidates ``c`` (K, 3), and valid (n,)."""
    n = xy.shape[0]
    f, valid = np.empty((n, c.shape[0])), np.empty(n, dtype=bool)
    R = rotations(yaw, att[:, 0], att[:, 1])[0]
    for i in range(0, n, BLOCK):  # blocks of poses keep the temporaries in cache
        s = slice(i, i + BLOCK)
        m = products(R[s], c)  # (b, 3, K)
        h, _, _, valid[s] = hm.sample_rows(
            xy[s, 0, None] + m[:, 0], xy[s, 1, None] + m[:, 1], slopes=False
        )
        f[s] = h - m[:, 2]
    return f, valid


def coarse_subset(c: FloatArray, spacing: float) -> NDArray[np.int_]:
    """Indices of candidates at least ``spacing`` [m] apart (greedy, in order; cached)."""
    key = (c.tobytes(), c.shape, float(spacing))
    if key not in _COARSE:
        far = np.linalg.norm(c[:, None, :] - c[None, :, :], axis=-1) >= spacing
        keep = np.zeros(len(c), dtype=bool)
        for k in range(len(c)):
            keep[k] = bool(far[k, keep].all())
        _COARSE.clear()  # one robot at a time
        _COARSE[key] = np.flatnonzero(keep)
    return _COARSE[key]


_COARSE: dict[tuple[bytes, tuple[int, ...], float], NDArray[np.int_]] = {}


def footprint_corners(c: FloatArray) -> NDArray[np.int_]:
    """Indices of the candidates (K, 3) at the footprint's four corners, counter-clockwise."""
    u, v = c[:, 0] + c[:, 1], c[:, 0] - c[:, 1]
    return np.array([np.argmax(u), np.argmax(v), np.argmin(u), np.argmin(v)])
