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
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.terrain.contacts import CHASSIS
from mmstab.terrain.heightmap import FloatArray, Heightmap, OffMapError
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
        line_width: touching contacts within this of one line are a line contact [m].
        approach: Newton steps longer than this [rad] are shortened ...
        approach_factor: ... by this factor (approach the rest without overshooting it).
        coarse_spacing: the first rounds use candidates this far apart [m] ...
        coarse_tol: ... until their step is below this [rad]; then all candidates.
    """

    max_iterations: int = 40
    tol_step: float = 1e-11
    max_step: float = 0.35
    max_tilt: float = 1.3
    contact_tol: float = 2e-4
    line_width: float = 1e-3
    approach: float = 0.02
    approach_factor: float = 0.8
    coarse_spacing: float = 0.09
    coarse_tol: float = 1e-6


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
        high_centred: (N,) the chassis touches the ground.
        line_contact: (N,) the touching contacts lie on one line (no polygon).
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


def _lift(
    hm: Heightmap, c: FloatArray, com: FloatArray, xy: FloatArray, yaw: FloatArray, att: FloatArray
) -> tuple[Any, ...]:
    """f_k (n, K), J_k and its lever part (n, K, 2), CoM height gradient (n, 2), valid (n,).

    ``J_k = d f_k / d(roll, pitch)``; the lever part ``-d (G_R_B c_k)_z / d(roll, pitch)``
    leaves out the ground's slope under the moving point: it is the horizontal moment arm
    of a vertical contact force, the one that decides equilibrium.
    """
    R, dR_r, dR_p = rotations(yaw, att[:, 0], att[:, 1])
    # every row of R, dR/droll, dR/dpitch against every candidate
    M = np.concatenate([R, dR_r, dR_p], axis=1)  # (n, 9, 3)
    # (elementwise, not BLAS: a 3-long inner product gains nothing from threads, which
    # only contend on a busy machine)
    m = M[:, :, 0, None] * c[:, 0] + M[:, :, 1, None] * c[:, 1] + M[:, :, 2, None] * c[:, 2]
    h, hx, hy, valid = hm.sample_rows(xy[:, 0, None] + m[:, 0], xy[:, 1, None] + m[:, 1])
    f = h - m[:, 2]
    jac = [hx * m[:, j] + hy * m[:, j + 1] - m[:, j + 2] for j in (3, 6)]
    grad = np.stack([np.einsum("nj,nj->n", dR[:, 2, :], com) for dR in (dR_r, dR_p)], axis=1)
    lever = np.stack([-m[:, 5], -m[:, 8]], axis=-1)
    return f, np.stack(jac, axis=-1), lever, grad, valid


def _touch_step(f: FloatArray, J: FloatArray, tri: NDArray[np.int_]) -> FloatArray:
    """Newton step (n, 2) [rad] bringing the three contacts ``tri`` to the same lift f."""
    r = np.arange(f.shape[0])[:, None]
    fa, Ja = f[r, tri], J[r, tri]  # (n, 3), (n, 3, 2)
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

    Returns:
        :class:`RestPoses` (leading axis N, also for a single pose).
    """
    settings = settings or RestSettings()
    c = np.asarray(candidates, dtype=float)
    p = np.atleast_2d(np.asarray(poses, dtype=float))
    n = p.shape[0]
    com = np.broadcast_to(np.asarray(com_body, dtype=float), (n, 3))
    coarse = coarse_subset(c, settings.coarse_spacing)
    rough = settings._replace(tol_step=settings.coarse_tol)
    out = []
    for i in range(0, n, CHUNK):
        ci, pi = com[i : i + CHUNK], p[i : i + CHUNK]
        # settle on a sparse subset of the candidates first, then on all of them
        a0, *_, it0, b0 = _solve(heightmap, c[coarse], ci, pi, rough)
        b0 = np.where(
            b0 < len(coarse), coarse[np.minimum(b0, len(coarse) - 1)], b0 - len(coarse) + len(c)
        )
        *fine, it1, _ = _solve(heightmap, c, ci, pi, settings, a0, b0)
        out.append((*fine, it0 + it1))
    cat = [np.concatenate(a) for a in zip(*out, strict=True)]
    att, f, iterations = cat[0], cat[1], cat[5]
    valid, converged, tips = cat[2].astype(bool), cat[3].astype(bool), cat[4].astype(bool)
    if strict and not valid.all():
        _raise_off_map(heightmap, c, p[:, :2], p[:, 2], att, valid)
    return _finish(c, p, att, f, valid, converged, tips, iterations, part, settings)


#: Poses solved together (keeps the (poses, candidates) arrays in cache).
CHUNK = 1024


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


def _solve(
    hm: Heightmap,
    c: FloatArray,
    com: FloatArray,
    p: FloatArray,
    settings: RestSettings,
    att0: FloatArray | None = None,
    basis0: NDArray[np.int_] | None = None,
) -> tuple[Any, ...]:
    """One chunk: attitudes (n, 2), f at them (n, K), per-pose flags, rounds, triangles."""
    n, K = p.shape[0], c.shape[0]
    xy, yaw = p[:, :2], p[:, 2]
    att = np.zeros((n, 2)) if att0 is None else att0.copy()  # (roll, pitch): lowered level
    f_last = np.full((n, K), np.nan)
    last = np.zeros((n, 2))  # the last Newton step taken [rad]
    basis: NDArray[np.int_] = np.tile(np.arange(K, K + 3), (n, 1)) if basis0 is None else basis0
    u, v = c[:, 0] + c[:, 1], c[:, 0] - c[:, 1]
    corners = np.array([np.argmax(u), np.argmax(v), np.argmin(u), np.argmin(v)])  # CCW-ish
    active = np.ones(n, dtype=bool)
    valid = np.ones(n, dtype=bool)
    converged = np.zeros(n, dtype=bool)
    tips = np.zeros(n, dtype=bool)
    iterations = np.zeros(n, dtype=np.int_)
    for it in range(settings.max_iterations + 1):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        f, J, lever, grad, ok = _lift(hm, c, com[idx], xy[idx], yaw[idx], att[idx])
        if not ok.all():
            valid[idx[~ok]] = False
            active[idx[~ok]] = False
            idx, f, J, lever, grad = idx[ok], f[ok], J[ok], lever[ok], grad[ok]
            if idx.size == 0:
                break
        f_last[idx] = f
        if it == settings.max_iterations:
            break  # f_last now belongs to the final attitude
        warm = basis[idx] if it or basis0 is not None else None
        _, tip, basis[idx], bounded = support_lp(lever, f, -grad, warm, corners)
        newton = _touch_step(f, J, basis[idx])
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
        over = ~done & ~back & (np.abs(att[idx]) > settings.max_tilt).any(axis=1)
        limit = settings.max_step * (0.5 ** max(0, it - 20))  # damp a late limit cycle
        step *= np.minimum(1.0, limit / np.maximum(norm, 1e-300))[:, None]
        step[done | over] = 0.0  # f_last is at the final attitude
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
) -> RestPoses:
    n, K = p.shape[0], c.shape[0]
    R = rotations(p[:, 2], att[:, 0], att[:, 1])[0]
    m = R[:, :, 0, None] * c[:, 0] + R[:, :, 1, None] * c[:, 1] + R[:, :, 2, None] * c[:, 2]
    foot = np.stack([p[:, 0, None] + m[:, 0], p[:, 1, None] + m[:, 1]], axis=-1)  # (n, K, 2)
    z = np.max(f, axis=1)
    gap = z[:, None] - f
    touching = gap <= settings.contact_tol
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = np.concatenate([p[:, :2], z[:, None]], axis=1)
    codes = np.full(K, -1) if part is None else np.asarray(part)
    high = (touching & (codes == CHASSIS)[None, :]).any(axis=1)
    # line contact: the touching points' footprint has no width
    wgt = touching / np.maximum(touching.sum(axis=1), 1)[:, None]
    mx, my = (foot[..., 0] * wgt).sum(axis=1), (foot[..., 1] * wgt).sum(axis=1)
    dx, dy = foot[..., 0] - mx[:, None], foot[..., 1] - my[:, None]
    sxx, syy, sxy = (dx * dx * wgt).sum(1), (dy * dy * wgt).sum(1), (dx * dy * wgt).sum(1)
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
    return RestPoses(
        poses=p,
        roll=roll,
        pitch=pitch,
        z=z,
        G_T_B=T,
        gap=gap,
        touching=touching,
        high_centred=high & valid,
        line_contact=line & valid,
        tips_over=tips & valid,
        converged=converged & valid,
        iterations=iterations,
    )
