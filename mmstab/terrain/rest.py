"""The resting pose of a rigid tracked base lowered onto a heightmap (batched over poses).

A pose ``(x, y, yaw)`` in G fixes where the body frame's origin is seen from above and the
heading of its x axis; the ground decides the rest: the height ``z`` [m], the roll and
the pitch [rad], with ``G_R_B = Rz(yaw) Ry(-pitch) Rx(roll)`` (positive roll lifts the
left side, positive pitch lifts the nose, as ``Ramp.roll_pitch``).

**Method: lower, then tip until the supporting contacts hold the CoM.** Lowering the robot
vertically does not move a candidate point's (x, y), so for a given (roll, pitch) the body
comes to rest at ``z = max_k f_k`` with ``f_k = h(xy_k) - (G_R_B c_k)_z`` (``c_k`` the
contact candidates, ``h`` the bilinear ground): the lift point k needs to touch. Starting
level, each round

1. picks the *supporting triangle*: the three candidates whose lifted points
   ``(a_k, f_k)`` span the facet of their upper convex hull above the CoM, where ``a_k``
   is the horizontal moment arm of a vertical force at k (``-d(G_R_B c_k)_z/d(roll,
   pitch)``) and the CoM's is ``-d(G_R_B g_o)_z/d(roll, pitch)``. It is a 2-D linear
   programme (weights w >= 0 summing to one that put the CoM's arm at the contacts'
   average, maximising the average lift) solved exactly by simplex pivots on triangles;
   its weights are the contacts' load shares. If no triangle holds the CoM, the robot
   tips toward the programme's unbounded direction;
2. takes a Newton step in (roll, pitch) that brings those three candidates to the same
   lift (all touching), with the ground's slope under them (``J_k = d f_k/d(roll, pitch)``).

At the fixed point the three touch, nothing penetrates (the facet is level in f) and the
gravity line of the CoM passes through their triangle: the quasi-static rest that
explicit tipping about support edges reaches (as Oehler & von Stryk's contact estimation
for tracked robots). On a plane it is exact in a few rounds. Long steps are shortened so
the rest is approached from one side (an overshoot could tip a marginally stable robot);
a roll or pitch beyond ``max_tilt`` means the robot tips over.

**Speed.** The first rounds use a sparse subset of the candidates; the rounds after that
use each pose's highest candidates only, checked against all at the end, with a re-solve
on all of them where the check fails (:func:`_solve_active`): the reference path's rests
(``active_candidates=0``) at a fraction of the work (``docs/terrain.md``, Speed).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.terrain.contacts import CHASSIS
from mmstab.terrain.heightmap import FloatArray, Heightmap, OffMapError
from mmstab.terrain.rest_c import KernelRests, rest_kernel
from mmstab.terrain.support_lp import support_lp

BoolArray = NDArray[np.bool_]


class RestSettings(NamedTuple):
    """Solver settings of :func:`rest_poses`.

    Attributes:
        max_iterations: linearise-and-solve rounds per pose.
        tol_step: stop when the attitude step is below this [rad].
        max_step: largest attitude step per round [rad].
        max_tilt: a roll or pitch beyond this means the robot tips over [rad].
        contact_tol: a candidate within this of the ground touches it [m].
        compliance: a candidate on a track's flat bottom run within this of the ground
            carries load [m]: the tracks' suspension and rubber yield that much, so the
            rigid rest's few touching points (often three) are not all that holds the
            robot up. Other candidates (arcs, flippers, chassis) carry load only when they
            touch. On a plane the bottom runs all touch, so the support is the ramp's.
        line_width: touching contacts within this of one line are a line contact [m].
        approach: Newton steps longer than this [rad] are shortened ...
        approach_factor: ... by this factor (approach the rest without overshooting it).
        coarse_spacing: the first rounds use candidates this far apart [m] ...
        coarse_tol: ... until their step is below this [rad]; then all candidates.
        active_candidates: ... or only each pose's this many highest, checked against all
            (0 = all candidates every round, the reference path).
        final_step: on the highest candidates, a Newton step below this [rad] on an
            unchanged triangle is the last (quadratic convergence puts the next below
            ``tol_step``).
        active_tol: a left-out candidate higher than the subset's highest by more than
            this [m] sends the pose to another pass.
        backend: ``"c"`` the compiled kernel (:mod:`mmstab.terrain.rest_c`, the default),
            ``"numpy"`` the vectorised NumPy path here: the same algorithm, kept as its
            independent twin (the tests hold one against the other).
    """

    max_iterations: int = 40
    tol_step: float = 1e-11
    max_step: float = 0.35
    max_tilt: float = 1.3
    contact_tol: float = 2e-4
    compliance: float = 0.02
    line_width: float = 1e-3
    approach: float = 0.02
    approach_factor: float = 0.8
    coarse_spacing: float = 0.09
    coarse_tol: float = 1e-3
    active_candidates: int = 24
    final_step: float = 1e-6
    active_tol: float = 1e-10
    backend: str = "c"


class RestPoses(NamedTuple):
    """Resting poses of N base poses against K contact candidates.

    Attributes:
        poses: (N, 3) the queried (x, y, yaw) in G [m, m, rad].
        roll: (N,) [rad]; positive lifts the left side.
        pitch: (N,) [rad]; positive lifts the nose.
        z: (N,) G height of the body origin [m].
        G_T_B: (N, 4, 4) resting body poses in G.
        gap: (N, K) height of each candidate above the ground below it [m].
        touching: (N, K) candidates within ``contact_tol`` of the ground.
        bearing: (N, K) candidates that carry load: the touching ones and the tracks'
            bottom-run candidates within ``compliance`` of the ground; the support polygon
            is their hull.
        high_centred: (N,) the chassis touches the ground.
        line_contact: (N,) the bearing contacts lie on one line (no polygon).
        tips_over: (N,) no resting attitude within ``max_tilt``: the CoM leaves the footprint.
        converged: (N,) the attitude step fell below ``tol_step``.
        iterations: (N,) rounds used.
    """

    poses: FloatArray
    roll: FloatArray
    pitch: FloatArray
    z: FloatArray
    G_T_B: FloatArray
    gap: FloatArray
    touching: BoolArray
    bearing: BoolArray
    high_centred: BoolArray
    line_contact: BoolArray
    tips_over: BoolArray
    converged: BoolArray
    iterations: NDArray[np.int_]

    def flags(self, i: int) -> tuple[str, ...]:
        """The operator flags of pose ``i`` (empty = normal)."""
        names = ("high_centred", "line_contact", "tips_over")
        out = tuple(n for n in names if bool(getattr(self, n)[i]))
        return out if self.converged[i] or self.tips_over[i] else (*out, "not_converged")

    def contacts_G(self, points_body: ArrayLike, i: int) -> FloatArray:
        """The touching candidates of pose ``i`` in G (n, 3) [m]."""
        c = np.asarray(points_body, dtype=float)[self.touching[i]]
        T = self.G_T_B[i]
        return c @ T[:3, :3].T + T[:3, 3]

    def bearing_G(self, points_body: ArrayLike, i: int) -> FloatArray:
        """The bearing candidates of pose ``i`` in G (n, 3) [m] (their hull: the support)."""
        c = np.asarray(points_body, dtype=float)[self.bearing[i]]
        T = self.G_T_B[i]
        return c @ T[:3, :3].T + T[:3, 3]


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


def _products(R: FloatArray, c: FloatArray) -> FloatArray:
    """Rows of ``R`` (n, r, 3) against candidates ``c`` (K, 3) or per pose (n, K, 3) -> (n, r, K).

    One small matrix product per pose (a stacked ``matmul``): each is far below the size
    at which BLAS starts threads, which would only contend on a busy machine, and the
    result of a pose does not depend on the batch it is in.
    """
    return R @ (c.T if c.ndim == 2 else c.transpose(0, 2, 1))


def _lift(
    hm: Heightmap, c: FloatArray, com: FloatArray, xy: FloatArray, yaw: FloatArray, att: FloatArray
) -> tuple[Any, ...]:
    """f_k (n, K), the lever arms (n, K, 2), CoM height gradient (n, 2), valid (n,), rows.

    ``c`` is (K, 3) shared by all poses or (n, K, 3) per pose. The lever arm ``-d (G_R_B
    c_k)_z / d(roll, pitch)`` leaves out the ground's slope under the moving point: it is
    the horizontal moment arm of a vertical contact force, the one that decides
    equilibrium. ``rows`` (n, 9, K) are R, dR/droll, dR/dpitch times the candidates, from
    which :func:`_jacobian` takes the full ``J_k = d f_k / d(roll, pitch)`` of the few
    candidates the Newton step needs (the ground's slope is sampled only there).
    """
    R, dR_r, dR_p = rotations(yaw, att[:, 0], att[:, 1])
    # every row of R, dR/droll, dR/dpitch against every candidate
    m = _products(np.concatenate([R, dR_r, dR_p], axis=1), c)  # (n, 9, K)
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


def _jacobian(hm: Heightmap, m: FloatArray, xy: FloatArray, tri: NDArray[np.int_]) -> FloatArray:
    """``J_k = d f_k / d(roll, pitch)`` (n, 3, 2) of the candidates ``tri`` (n, 3).

    Args:
        hm: the ground.
        m: (n, 9, K) rows of :func:`_lift`.
        xy: (n, 2) pose positions in G [m].
        tri: (n, 3) candidate indices (artificial ones, >= K, are clipped: unused).
    """
    tri = np.minimum(tri, m.shape[2] - 1)
    mt = np.take_along_axis(m, tri[:, None, :], axis=2)  # (n, 9, 3)
    _, hx, hy, _ = hm.sample_rows(xy[:, 0, None] + mt[:, 0], xy[:, 1, None] + mt[:, 1])
    return np.stack([hx * mt[:, j] + hy * mt[:, j + 1] - mt[:, j + 2] for j in (3, 6)], axis=-1)


def _heights(
    hm: Heightmap, c: FloatArray, xy: FloatArray, yaw: FloatArray, att: FloatArray
) -> tuple[FloatArray, BoolArray]:
    """Only the lifts f_k (n, K) [m] of the candidates ``c`` (K, 3), and valid (n,)."""
    n = xy.shape[0]
    f, valid = np.empty((n, c.shape[0])), np.empty(n, dtype=bool)
    R = rotations(yaw, att[:, 0], att[:, 1])[0]
    for i in range(0, n, BLOCK):  # blocks of poses keep the temporaries in cache
        s = slice(i, i + BLOCK)
        m = _products(R[s], c)  # (b, 3, K)
        h, _, _, valid[s] = hm.sample_rows(
            xy[s, 0, None] + m[:, 0], xy[s, 1, None] + m[:, 1], slopes=False
        )
        f[s] = h - m[:, 2]
    return f, valid


#: Poses per block in the samplers of :func:`_lift` and :func:`_heights` (their (block,
#: candidates) temporaries stay in cache while a round works on the whole chunk).
BLOCK = 128


def _touch_step(f: FloatArray, J: FloatArray, tri: NDArray[np.int_]) -> FloatArray:
    """Newton step (n, 2) [rad] bringing the three contacts ``tri`` to the same lift f.

    Args:
        f: (n, K) lifts [m].
        J: (n, 3, 2) their derivatives by (roll, pitch) at ``tri`` (:func:`_jacobian`).
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


def rest_poses(
    heightmap: Heightmap,
    candidates: ArrayLike,
    com_body: ArrayLike,
    poses: ArrayLike,
    part: ArrayLike | None = None,
    settings: RestSettings | None = None,
    strict: bool = True,
    compliant: ArrayLike | None = None,
) -> RestPoses:
    """Resting poses of the rigid base at many poses (vectorised over poses).

    Args:
        heightmap: the ground.
        candidates: (K, 3) contact candidates in B [m] (:func:`contact_candidates`).
        com_body: overall CoM in B, (3,) or (N, 3) [m].
        poses: (3,) or (N, 3) of (x, y, yaw) in G [m, m, rad].
        part: (K,) part codes of the candidates (for ``high_centred``); ``None`` = no chassis.
        settings: solver settings (``None`` = the defaults).
        strict: raise :class:`OffMapError` if a pose needs ground off the map or on unknown
            cells; otherwise such poses come back NaN.
        compliant: (K,) the candidates that bear load within ``settings.compliance`` of the
            ground (:attr:`ContactCandidates.compliant`); ``None`` = none (rigid contacts).

    Returns:
        :class:`RestPoses` (leading axis N, also for a single pose).
    """
    settings = settings or RestSettings()
    c = np.asarray(candidates, dtype=float)
    p = np.atleast_2d(np.asarray(poses, dtype=float))
    n = p.shape[0]
    com = np.broadcast_to(np.asarray(com_body, dtype=float), (n, 3))
    coarse = coarse_subset(c, settings.coarse_spacing)
    if settings.backend == "c":
        att, f, valid, converged, tips, iterations = _rest_c(heightmap, c, coarse, com, p, settings)
        if strict and not valid.all():
            _raise_off_map(heightmap, c, p[:, :2], p[:, 2], att, valid)
        return _finish(c, p, att, f, valid, converged, tips, iterations, part, settings, compliant)
    if settings.backend != "numpy":
        raise ValueError(f"RestSettings.backend: {settings.backend!r} is not 'c' or 'numpy'")
    rough = settings._replace(tol_step=settings.coarse_tol)
    out = []
    for i in range(0, n, CHUNK):
        ci, pi = com[i : i + CHUNK], p[i : i + CHUNK]
        # settle on a sparse subset of the candidates first, then on all of them
        a0, *_, it0, b0 = _solve(heightmap, c[coarse], ci, pi, rough)
        b0 = np.where(
            b0 < len(coarse), coarse[np.minimum(b0, len(coarse) - 1)], b0 - len(coarse) + len(c)
        )
        if 0 < settings.active_candidates < len(c):
            *fine, it1 = _solve_active(heightmap, c, ci, pi, settings, a0, b0)
        else:
            *fine, it1, _ = _solve(heightmap, c, ci, pi, settings, a0, b0)
        out.append((*fine, it0 + it1))
    cat = [np.concatenate(a) for a in zip(*out, strict=True)]
    att, f, iterations = cat[0], cat[1], cat[5]
    valid, converged, tips = cat[2].astype(bool), cat[3].astype(bool), cat[4].astype(bool)
    if strict and not valid.all():
        _raise_off_map(heightmap, c, p[:, :2], p[:, 2], att, valid)
    return _finish(c, p, att, f, valid, converged, tips, iterations, part, settings, compliant)


def _rest_c(
    hm: Heightmap,
    c: FloatArray,
    coarse: NDArray[np.int_],
    com: FloatArray,
    p: FloatArray,
    settings: RestSettings,
) -> KernelRests:
    """:func:`rest_poses`'s stages by the C kernel (one call for all poses)."""
    s = settings
    numbers = [s.max_iterations, s.tol_step, s.max_step, s.max_tilt, s.approach]
    numbers += [s.approach_factor, s.coarse_tol, s.active_candidates, s.final_step, s.active_tol]
    return rest_kernel(
        hm.elevation, hm.origin, hm.resolution, c, coarse,
        _corners(c[coarse]), _corners(c), com, p, tuple(float(x) for x in numbers),
    )  # fmt: skip


def _solve_active(
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
    (:func:`_solve`). Returns what :func:`_solve` does without the triangles.
    """
    n, K = p.shape[0], c.shape[0]
    M = settings.active_candidates
    xy, yaw = p[:, :2], p[:, 2]
    rows = np.arange(n)[:, None]
    corners = _corners(c)
    f0, valid = _heights(hm, c, xy, yaw, att0)
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
    att, _, v, converged, tips, iterations, _ = _solve(
        hm, c[sub], com, p, settings, att0, b_sub, settings.final_step
    )
    f_out, ok = _heights(hm, c, xy, yaw, att)
    top_sub = np.take_along_axis(f_out, sub, axis=1).max(axis=1)
    valid &= v & ok
    held = converged & ~tips & (f_out.max(axis=1) <= top_sub + settings.active_tol)
    redo = np.flatnonzero(valid & ~held)
    if redo.size:
        a, f, v, conv, tip, it, _ = _solve(
            hm, c, com[redo], p[redo], settings, att0[redo], basis0[redo]
        )
        att[redo], f_out[redo], valid[redo] = a, f, v
        converged[redo], tips[redo] = conv, tip
        iterations[redo] += it
    return att, f_out, valid, converged, tips, iterations


#: Poses solved together (large: the per-round Python overhead is paid once per chunk).
CHUNK = 2048


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


def _corners(c: FloatArray) -> NDArray[np.int_]:
    """Indices of the candidates (K, 3) at the footprint's four corners, counter-clockwise."""
    u, v = c[:, 0] + c[:, 1], c[:, 0] - c[:, 1]
    return np.array([np.argmax(u), np.argmax(v), np.argmin(u), np.argmin(v)])


def _solve(
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
    # per-pose candidates (:func:`_solve_active`) hold the footprint's corners first
    corners = np.arange(4) if per_pose else _corners(c)
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
        f, lever, grad, ok, m = _lift(hm, ci, com[idx], xy[idx], yaw[idx], att[idx])
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
        newton = _touch_step(f, _jacobian(hm, m, xy[idx], basis[idx]), basis[idx])
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
        # caller, :func:`_solve_active`)
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


def _raise_off_map(
    hm: Heightmap, c: FloatArray, xy: FloatArray, yaw: FloatArray, att: FloatArray, valid: BoolArray
) -> None:
    i = int(np.flatnonzero(~valid)[0])
    R = rotations(yaw[i : i + 1], att[i : i + 1, 0], att[i : i + 1, 1])[0][0]
    pts = xy[i] + (c @ R.T)[:, :2]
    x, y = xy[i]
    try:
        hm.check(hm.sample(pts), pts, what=f"pose ({x:.3f}, {y:.3f}, {yaw[i]:.3f}): contact")
    except OffMapError:
        raise
    raise OffMapError(f"{hm.source}: pose ({x:.3f}, {y:.3f}) m needs ground off the map")


def _finish(
    c: FloatArray,
    p: FloatArray,
    att: FloatArray,
    f: FloatArray,
    valid: BoolArray,
    converged: BoolArray,
    tips: BoolArray,
    iterations: NDArray[np.int_],
    part: ArrayLike | None,
    settings: RestSettings,
    compliant: ArrayLike | None = None,
) -> RestPoses:
    n, K = p.shape[0], c.shape[0]
    R = rotations(p[:, 2], att[:, 0], att[:, 1])[0]
    z = np.max(f, axis=1)
    gap = z[:, None] - f
    touching = gap <= settings.contact_tol
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = np.concatenate([p[:, :2], z[:, None]], axis=1)
    codes = np.full(K, -1) if part is None else np.asarray(part)
    high = (touching & (codes == CHASSIS)[None, :]).any(axis=1)
    bearing = touching.copy()
    if compliant is not None:
        bearing |= np.asarray(compliant, dtype=bool)[None, :] & (gap <= settings.compliance)
    # line contact: the bearing points' footprint has no width. Its covariance is the
    # bearing candidates' covariance in B turned into G (cheaper than placing them all).
    wgt = bearing / np.maximum(bearing.sum(axis=1), 1)[:, None]
    mean = wgt @ c  # (n, 3)
    second = (wgt @ (c[:, :, None] * c[:, None, :]).reshape(K, 9)).reshape(n, 3, 3)
    cov_B = second - mean[:, :, None] * mean[:, None, :]
    cov = R[:, :2] @ cov_B @ R[:, :2].transpose(0, 2, 1)  # (n, 2, 2) in G's x, y
    sxx, syy, sxy = cov[:, 0, 0], cov[:, 1, 1], cov[:, 0, 1]
    smallest = (sxx + syy) / 2 - np.sqrt(((sxx - syy) / 2) ** 2 + sxy**2)  # 2x2 eigenvalue
    width = 2 * np.sqrt(np.maximum(smallest, 0.0))
    line = width < settings.line_width
    bad = ~valid
    roll, pitch = att[:, 0].copy(), att[:, 1].copy()
    for a in (roll, pitch, z):
        a[bad] = np.nan
    T[bad] = np.nan
    gap[bad] = np.nan
    touching[bad] = False
    bearing[bad] = False
    return RestPoses(
        poses=p,
        roll=roll,
        pitch=pitch,
        z=z,
        G_T_B=T,
        gap=gap,
        touching=touching,
        bearing=bearing,
        high_centred=high & valid,
        line_contact=line & valid,
        tips_over=tips & valid,
        converged=converged & valid,
        iterations=iterations,
    )
