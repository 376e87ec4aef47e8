"""The resting pose of a rigid tracked base lowered onto a heightmap (batched over poses).

A pose ``(x, y, yaw)`` in G fixes where the body frame's origin is seen from above and the
heading of its x axis; the ground decides the rest: the height ``z`` [m], the roll and
the pitch [rad], with ``G_R_B = Rz(yaw) Ry(-pitch) Rx(roll)`` (positive roll lifts the
left side, positive pitch lifts the nose, as ``Ramp.roll_pitch``).

**Method: least potential energy without penetration.** Lowering the robot vertically
does not move a candidate point's (x, y), so for a given (roll, pitch) the body comes to
rest at ``z = max_k f_k`` with ``f_k = h(xy_k) - (G_R_B c_k)_z`` (``c_k`` the contact
candidates, ``h`` the bilinear ground). The resting attitude minimises the height of the
centre of mass, ``U = max_k f_k + (G_R_B g_o)_z``. Each iteration linearises the ``f_k``
about the current attitude and solves the linear programme
``min_{t, d} t + grad_U_com . d  s.t.  t >= f_k + J_k . d`` exactly: its dual is the upper
convex hull of the lifted points ``(J_k, f_k)`` above ``q = -grad_U_com``, found by a
simplex pivot on triangles (big-M start). The optimal triangle is the three supporting
contacts and its barycentric weights their (non-negative) load shares, so the solution is
the physical tip-until-stable rest: contacts hold the robot and the gravity line of the
CoM passes through their polygon (Oehler & von Stryk's contact estimation reaches the
same state by explicit tipping). Newton-like: on a plane it is exact in a few steps.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.terrain.contacts import CHASSIS
from mmstab.terrain.heightmap import FloatArray, Heightmap, OffMapError

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
    """

    max_iterations: int = 40
    tol_step: float = 1e-11
    max_step: float = 0.35
    max_tilt: float = 1.3
    contact_tol: float = 2e-4
    line_width: float = 1e-3


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
        return out if self.converged[i] else (*out, "not_converged")

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
    """f_k (n, K), J_k (n, K, 2), grad of the CoM height (n, 2), valid (n,)."""
    R, dR_r, dR_p = rotations(yaw, att[:, 0], att[:, 1])
    n, K = yaw.shape[0], c.shape[0]
    # every row of R, dR/droll, dR/dpitch against every candidate: one matrix product
    rows = np.concatenate([R, dR_r, dR_p], axis=1).reshape(n * 9, 3) @ c.T
    m = rows.reshape(n, 9, K)
    s = hm.sample(np.stack([xy[:, 0, None] + m[:, 0], xy[:, 1, None] + m[:, 1]], axis=-1))
    f = s.height - m[:, 2]
    jac = [s.dh_dx * m[:, j] + s.dh_dy * m[:, j + 1] - m[:, j + 2] for j in (3, 6)]
    grad = np.stack([np.einsum("nj,nj->n", dR[:, 2, :], com) for dR in (dR_r, dR_p)], axis=1)
    return f, np.stack(jac, axis=-1), grad, s.valid.all(axis=1)


def _bary(P: FloatArray, x: FloatArray) -> FloatArray:
    """Barycentric coordinates (n, 3) of points x (n, 2) in triangles P (n, 3, 2)."""
    a, b, c = P[:, 0], P[:, 1], P[:, 2]
    ab, ac, ax = b - a, c - a, x - a
    den = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    den = np.where(np.abs(den) > 1e-300, den, 1e-300)
    lb = (ax[:, 0] * ac[:, 1] - ax[:, 1] * ac[:, 0]) / den
    lc = (ab[:, 0] * ax[:, 1] - ab[:, 1] * ax[:, 0]) / den
    return np.stack([1.0 - lb - lc, lb, lc], axis=1)


def _plane(P: FloatArray, F: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(t (n,), d (n, 2)) of the plane ``value(J) = t - d . J`` through 3 lifted points."""
    a, b, c = P[:, 0], P[:, 1], P[:, 2]
    ab, ac = b - a, c - a
    den = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    den = np.where(np.abs(den) > 1e-300, den, 1e-300)
    fb, fc = F[:, 1] - F[:, 0], F[:, 2] - F[:, 0]
    gx = (fb * ac[:, 1] - fc * ab[:, 1]) / den  # gradient of the plane's value over J
    gy = (-fb * ac[:, 0] + fc * ab[:, 0]) / den
    t = F[:, 0] - gx * a[:, 0] - gy * a[:, 1]
    return t, -np.stack([gx, gy], axis=1)


def support_lp(
    J: FloatArray,
    f: FloatArray,
    q: FloatArray,
    basis: NDArray[np.int_] | None = None,
    corners: NDArray[np.int_] | None = None,
) -> tuple[FloatArray, FloatArray, NDArray[np.int_], BoolArray]:
    """Solve ``min_{t,d} t - q . d  s.t.  t >= f_k + J_k . d`` for n problems at once.

    The dual is ``max sum_k w_k f_k`` over weights ``w >= 0``, ``sum w = 1``,
    ``sum w_k J_k = q``: the upper hull of the lifted points ``(J_k, f_k)`` above ``q``.
    Simplex pivots on triangles holding ``q``: the most violated point enters, the ratio
    test keeps ``q`` inside; a big-M triangle of artificial points starts it when no
    given triangle holds ``q``.

    Args:
        J: (n, K, 2) constraint slopes.
        f: (n, K) constraint values.
        q: (n, 2) the point whose supporting facet is sought (minus the objective slope).
        basis: (n, 3) a warm-start triangle of indices into K, or ``None``.
        corners: (4,) indices into K of a quadrilateral likely to hold ``q`` (the
            footprint's corners); a triangle of it that does is the cold start.

    Returns:
        ``(t (n,), d (n, 2), basis (n, 3), bounded (n,))``; ``bounded`` is False when ``q``
        lies outside the hull of the ``J_k`` (an artificial vertex stays in the basis).
    """
    n, K = f.shape
    rows = np.arange(n)
    scale = np.abs(J).max(axis=(1, 2)) + np.abs(q).max(axis=1) + 1.0
    ang = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    art = q[:, None, :] + 100.0 * scale[:, None, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
    big = 1e6 * (np.ptp(f, axis=1) + 1.0)
    P = np.concatenate([J, art], axis=1)
    F = np.concatenate([f, -np.repeat(big[:, None], 3, axis=1)], axis=1)
    start = np.tile(np.arange(K, K + 3), (n, 1))
    tries = [] if corners is None else [np.delete(corners, j) for j in range(4)]
    if basis is not None:
        tries.insert(0, basis)
    found = np.zeros(n, dtype=bool)
    for tri in tries:
        tri = np.broadcast_to(tri, (n, 3))
        lam = _bary(P[rows[:, None], tri], q)
        ok = ~found & (lam >= -1e-12).all(axis=1)
        start[ok] = tri[ok]
        found |= ok
    basis = start
    tol = 1e-12 * (np.abs(f).max(axis=1) + 1.0)
    t = np.zeros(n)
    d = np.zeros((n, 2))
    idx = rows
    for _ in range(4 * K + 12):
        b = basis[idx]
        Pb = P[idx[:, None], b]
        ti, di = _plane(Pb, F[idx[:, None], b])
        t[idx], d[idx] = ti, di
        Ji = J[idx]
        viol = f[idx] + Ji[..., 0] * di[:, 0, None] + Ji[..., 1] * di[:, 1, None] - ti[:, None]
        e = np.argmax(viol, axis=1)
        go = viol[np.arange(idx.size), e] > tol[idx]
        if not go.any():
            break
        idx, e, Pg = idx[go], e[go], Pb[go]
        lam = _bary(Pg, q[idx])
        mu = _bary(Pg, J[idx, e])
        pos = mu > 1e-12
        ratio = np.where(pos, lam / np.where(pos, mu, 1.0), np.inf)
        leave = np.argmin(ratio, axis=1)
        basis[idx, leave] = e
    bounded = (basis < K).all(axis=1)
    return t, d, basis, bounded


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
    out = [
        _solve(heightmap, c, com[i : i + CHUNK], p[i : i + CHUNK], settings)
        for i in range(0, n, CHUNK)
    ]
    cat = [np.concatenate(a) for a in zip(*out, strict=True)]
    att, f, iterations = cat[0], cat[1], cat[5]
    valid, converged, tips = cat[2].astype(bool), cat[3].astype(bool), cat[4].astype(bool)
    if strict and not valid.all():
        _raise_off_map(heightmap, c, p[:, :2], p[:, 2], att, valid)
    return _finish(c, p, att, f, valid, converged, tips, iterations, part, settings)


#: Poses solved together (keeps the (poses, candidates) arrays in cache).
CHUNK = 256


def _solve(
    hm: Heightmap, c: FloatArray, com: FloatArray, p: FloatArray, settings: RestSettings
) -> tuple[Any, ...]:
    """One chunk: attitudes (n, 2), f at them (n, K) and the per-pose flags."""
    n, K = p.shape[0], c.shape[0]
    xy, yaw = p[:, :2], p[:, 2]
    att = np.zeros((n, 2))  # (roll, pitch): lowered level
    f_last = np.full((n, K), np.nan)
    basis: NDArray[np.int_] = np.tile(np.arange(K, K + 3), (n, 1))
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
        f, J, grad, ok = _lift(hm, c, com[idx], xy[idx], yaw[idx], att[idx])
        if not ok.all():
            valid[idx[~ok]] = False
            active[idx[~ok]] = False
            idx, f, J, grad = idx[ok], f[ok], J[ok], grad[ok]
            if idx.size == 0:
                break
        f_last[idx] = f
        if it == settings.max_iterations:
            break  # f_last now belongs to the final attitude
        warm = basis[idx] if it else None
        _, step, basis[idx], bounded = support_lp(J, f, -grad, warm, corners)
        norm = np.linalg.norm(step, axis=1)
        done = bounded & (norm <= settings.tol_step)
        over = ~done & (np.abs(att[idx]) > settings.max_tilt).any(axis=1)
        limit = settings.max_step * (0.5 ** max(0, it - 20))  # damp a late limit cycle
        step *= np.minimum(1.0, limit / np.maximum(norm, 1e-300))[:, None]
        step[done | over] = 0.0  # f_last is at the final attitude
        att[idx] += step
        iterations[idx] = it + 1
        tips[idx[over]] = True
        converged[idx[done]] = True
        active[idx[done | over]] = False
    return att, f_last, valid, converged, tips, iterations


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
    m = (R.reshape(n * 3, 3) @ c.T).reshape(n, 3, K)
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
