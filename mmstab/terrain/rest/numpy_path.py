"""The resting pose's NumPy path: lower, then tip until the supporting contacts hold the CoM.

The algorithm of :mod:`mmstab.terrain.rest.poses` vectorised over poses, in chunks of
:data:`CHUNK`: a coarse stage on a sparse subset of the candidates, then the fine stage on
each pose's highest candidates (:func:`solve_active`) or on all of them (:func:`solve`,
the reference path). The C kernel (:mod:`mmstab.terrain.rest.kernel`) runs the same stages; this
path is its independent twin.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.terrain.heightmap import FloatArray, Heightmap
from mmstab.terrain.rest.geometry import footprint_corners, heights, jacobian, lift
from mmstab.terrain.rest.types import BoolArray, RestSettings
from mmstab.terrain.support_lp import support_lp

#: Poses solved together (large: the per-round Python overhead is paid once per chunk).
CHUNK = 2048


def numpy_rests(
    hm: Heightmap,
    c: FloatArray,
    coarse: NDArray[np.int_],
    com: FloatArray,
    p: FloatArray,
    settings: RestSettings,
) -> tuple[FloatArray, FloatArray, BoolArray, BoolArray, BoolArray, NDArray[np.int_]]:
    """:func:`mmstab.terrain.rest.poses.rest_poses`'s stages in NumPy, chunk by chunk.

    Args:
        hm: the ground.
        c: (K, 3) contact candidates in B [m].
        coarse: indices of the sparse subset the first rounds use.
        com: (N, 3) CoM in B [m].
        p: (N, 3) poses (x, y, yaw) in G [m, m, rad].
        settings: solver settings.

    Returns:
        attitudes (N, 2) [rad], lifts f at them (N, K) [m], valid, converged, tips over
        (N,), rounds used (N,).
    """
    n = p.shape[0]
    rough = settings._replace(tol_step=settings.coarse_tol)
    out = []
    for i in range(0, n, CHUNK):
        ci, pi = com[i : i + CHUNK], p[i : i + CHUNK]
        # settle on a sparse subset of the candidates first, then on all of them
        a0, *_, it0, b0 = solve(hm, c[coarse], ci, pi, rough)
        b0 = np.where(
            b0 < len(coarse), coarse[np.minimum(b0, len(coarse) - 1)], b0 - len(coarse) + len(c)
        )
        if 0 < settings.active_candidates < len(c):
            *fine, it1 = solve_active(hm, c, ci, pi, settings, a0, b0)
        else:
            *fine, it1, _ = solve(hm, c, ci, pi, settings, a0, b0)
        out.append((*fine, it0 + it1))
    cat = [np.concatenate(a) for a in zip(*out, strict=True)]
    att, f, iterations = cat[0], cat[1], cat[5]
    valid, converged, tips = cat[2].astype(bool), cat[3].astype(bool), cat[4].astype(bool)
    return att, f, valid, converged, tips, iterations


def touch_step(f: FloatArray, J: FloatArray, tri: NDArray[np.int_]) -> FloatArray:
    """Newton step (n, 2) [rad] bringing the three contacts ``tri`` to the same lift f.

    Args:
        f: (n, K) lifts [m].
        J: (n, 3, 2) their derivatives by (roll, pitch) at ``tri`` (:func:`jacobian`).
        tri: (n, 3) the contacts.
    """
    r = np.arange(f.shape[0])[:, None]
    fa, Ja = f[r, np.minimum(tri, f.shape[1] - 1)], J  # (n, 3), (n, 3, 2)
    A = Ja[:, :1] - Ja[:, 1:]  # rows: J_a - J_b, J_a - J_c
    b = fa[:, 1:] - fa[:, :1]  # -(f_a - f_b), -(f_a - f_c)
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    ok = np.abs(det) > 1e-14
    det = np.where(ok, det, 1.0)
    d0 = (A[:, 1, 1] * b[:, 0] - A[:, 0, 1] * b[:, 1]) / det
    d1 = (-A[:, 1, 0] * b[:, 0] + A[:, 0, 0] * b[:, 1]) / det
    return np.where(ok[:, None], np.stack([d0, d1], axis=1), 0.0)


def solve_active(
    hm: Heightmap,
    c: FloatArray,
    com: FloatArray,
    p: FloatArray,
    settings: RestSettings,
    att0: FloatArray,
    basis0: NDArray[np.int_],
) -> tuple[Any, ...]:
    """The fine stage on each pose's highest candidates, checked against all of them.

    Near the rest only candidates that lift the body nearly as high as the highest can
    join the support, so each pose solves on its ``active_candidates`` highest at the
    starting attitude (plus the footprint's corners and its current triangle). At a
    converged rest the supporting facet is level (``d = 0``, ``t = max f``), so it is the
    rest on *all* candidates exactly when no left-out candidate lifts the body higher. That
    is checked; a pose where one does, or that did not converge or tipped on its subset,
    is solved again on all candidates from the same start: the reference path
    (:func:`solve`). Returns what :func:`solve` does without the triangles.
    """
    n, K = p.shape[0], c.shape[0]
    M = settings.active_candidates
    xy, yaw = p[:, :2], p[:, 2]
    rows = np.arange(n)[:, None]
    corners = footprint_corners(c)
    f0, valid = heights(hm, c, xy, yaw, att0)
    score = np.where(valid[:, None], f0, 0.0)
    # the current triangle stays in; the footprint's corners come first (the cold start)
    bk = np.minimum(basis0, K - 1)
    score[rows, bk] = np.where(basis0 < K, np.inf, score[rows, bk])
    score[:, corners] = -np.inf
    top = np.argpartition(-score, M - 5, axis=1)[:, : M - 4]
    sub = np.concatenate([np.broadcast_to(corners, (n, 4)), top], axis=1)  # (n, M) into K
    # the triangle in the subset's numbering (artificial vertices stay past the end)
    pos = np.argmax(sub[:, None, :] == basis0[:, :, None], axis=2)
    b_sub = np.where(basis0 < K, pos, basis0 - K + M)
    att, _, v, converged, tips, iterations, _ = solve(
        hm, c[sub], com, p, settings, att0, b_sub, settings.final_step
    )
    f_out, ok = heights(hm, c, xy, yaw, att)
    top_sub = np.take_along_axis(f_out, sub, axis=1).max(axis=1)
    valid &= v & ok
    held = converged & ~tips & (f_out.max(axis=1) <= top_sub + settings.active_tol)
    redo = np.flatnonzero(valid & ~held)
    if redo.size:
        a, f, v, conv, tip, it, _ = solve(
            hm, c, com[redo], p[redo], settings, att0[redo], basis0[redo]
        )
        att[redo], f_out[redo], valid[redo] = a, f, v
        converged[redo], tips[redo] = conv, tip
        iterations[redo] += it
    return att, f_out, valid, converged, tips, iterations


def solve(
    hm: Heightmap,
    c: FloatArray,
    com: FloatArray,
    p: FloatArray,
    settings: RestSettings,
    att0: FloatArray | None = None,
    basis0: NDArray[np.int_] | None = None,
    final_step: float = 0.0,
) -> tuple[Any, ...]:
    """One chunk: attitudes (n, 2), f at them (n, K), per-pose flags, rounds, triangles.

    ``final_step`` [rad] > 0: a Newton step this short on an unchanged triangle is the
    last (f is then not at the final attitude: the caller recomputes it).
    """
    n, K = p.shape[0], c.shape[-2]
    xy, yaw = p[:, :2], p[:, 2]
    att = np.zeros((n, 2)) if att0 is None else att0.copy()  # (roll, pitch): lowered level
    f_last = np.full((n, K), np.nan)
    last = np.zeros((n, 2))  # the last Newton step taken [rad]
    basis: NDArray[np.int_] = np.tile(np.arange(K, K + 3), (n, 1)) if basis0 is None else basis0
    per_pose = c.ndim == 3  # candidates (n, K, 3) per pose: no shared cold-start corners
    # per-pose candidates (:func:`solve_active`) hold the footprint's corners first
    corners = np.arange(4) if per_pose else footprint_corners(c)
    active = np.ones(n, dtype=bool)
    valid = np.ones(n, dtype=bool)
    converged = np.zeros(n, dtype=bool)
    tips = np.zeros(n, dtype=bool)
    iterations = np.zeros(n, dtype=np.int_)
    for it in range(settings.max_iterations + 1):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        ci = c[idx] if per_pose else c
        f, lever, grad, ok, m = lift(hm, ci, com[idx], xy[idx], yaw[idx], att[idx])
        if not ok.all():
            valid[idx[~ok]] = False
            active[idx[~ok]] = False
            idx, f, lever, grad, m = idx[ok], f[ok], lever[ok], grad[ok], m[ok]
            if idx.size == 0:
                break
        if it == settings.max_iterations:
            f_last[idx] = f  # at the final attitude
            break
        warm = basis[idx] if it or basis0 is not None else None
        tri_before = basis[idx]
        _, tip, basis[idx], bounded = support_lp(lever, f, -grad, warm, corners)
        newton = touch_step(f, jacobian(hm, m, xy[idx], basis[idx]), basis[idx])
        # long Newton steps are shortened so they approach the rest from the side they
        # started on: an overshoot can put the CoM outside its support and tip a stable robot
        n_norm = np.linalg.norm(newton, axis=1, keepdims=True)
        newton *= np.where(n_norm > settings.approach, settings.approach_factor, 1.0)
        step = np.where(bounded[:, None], newton, tip)
        norm = np.linalg.norm(step, axis=1)
        # a Newton step that overshot the rest put the CoM outside its support: go half back
        # (tipping is believed only once it appears after a tiny step)
        back = ~bounded & (np.linalg.norm(last[idx], axis=1) > 1e-7)
        done = bounded & (norm <= settings.tol_step)
        # Newton converges quadratically: after a tiny step on an unchanged triangle the next
        # one would be below tol_step, so take it and stop (f is then recomputed by the
        # caller, :func:`solve_active`)
        last_step = ~done & bounded & (norm <= final_step) & (basis[idx] == tri_before).all(axis=1)
        over = ~done & ~back & (np.abs(att[idx]) > settings.max_tilt).any(axis=1)
        limit = settings.max_step * (0.5 ** max(0, it - 20))  # damp a late limit cycle
        step *= np.minimum(1.0, limit / np.maximum(norm, 1e-300))[:, None]
        step[done | over] = 0.0
        f_last[idx[done | over]] = f[done | over]  # at the final attitude
        done |= last_step
        half = 0.5 * last[idx]
        step = np.where(back[:, None], -half, step)
        last[idx] = np.where(back[:, None], half, np.where(bounded[:, None], step, 0.0))
        att[idx] += step
        iterations[idx] = it + 1
        tips[idx[over]] = True
        converged[idx[done]] = True
        active[idx[done | over]] = False
    return att, f_last, valid, converged, tips, iterations, basis
