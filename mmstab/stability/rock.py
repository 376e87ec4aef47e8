"""Rocking onto the next support, or tipping over: a push across a support edge.

On rough ground a rigid base rests on few contacts: often three, or two diagonal corners
of the tracks with the other two a few millimetres up (a table with a short leg). The
force-angle measure on that support (:mod:`mmstab.stability.support`) can be near zero
about an edge that runs *inside* the tracks' footprint, a diagonal. A push of the net
force across such an edge does not overturn the robot: it turns about the edge until a
lifted corner meets the ground, a fraction of a degree to a few degrees later, and rests
there. Only a push across an edge of the support it rocks onto can overturn it.

:func:`rock_over` checks that directly. A horizontal acceleration ``a`` of the base tilts
the net force by ``atan(a / g)``: its line through the CoM meets the ground ``h a / g``
beyond the CoM's vertical (``h``: the CoM's height above the edge), as if the CoM stood
that far out under plain gravity (the zero-moment point). For each edge whose share
``theta_j |f|`` of μ is at or below ``threshold``, the rested base is turned about that
edge, outward, until the first contact candidate beyond it meets the ground (the catch,
in steps of :data:`STEP`, at most :data:`MAX_ROCK`); the support there is the edge's two
ends, the candidates touching and the tracks' bottom run within the ground's compliance
(as at a rest). The state holds if

- a catch is found, and μ of the pushed CoM on the caught support exceeds ``margin``; and
- the rock's drop of the CoM is below the energy the caught support needs to overturn:
  the normalised energy stability margin ``min_j |R_j| (1 - cos theta_j) cos psi_j``
  (Hirose, Tsukagoshi and Yoneda 2001; ``R_j`` the CoM's distance from edge j, ``psi_j``
  the edge's inclination), so the rock's kinetic energy ``m g drop`` cannot carry the
  robot over.

The turn about the edge is explicit (not a new rest), so a rest that did not settle (its
steps cycling between two triangles on a rim) is rocked the same way.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import FloatArray, Robot
from mmstab.stability.static import axis_angles
from mmstab.terrain.base import GRAVITY_G, Terrain, as_poses
from mmstab.terrain.polygon import support_vertices

_UP = np.array([0.0, 0.0, 1.0])

#: The turn about an edge is found in steps of this [rad] (0.1 deg: 0.7 mm at 0.4 m) ...
STEP = float(np.radians(0.1))
#: ... up to this [rad]: a base that turns farther about an edge is not caught (it tips).
MAX_ROCK = float(np.radians(30.0))
#: Candidates this far outside an edge [m] are the ones its turn lowers onto the ground.
BEYOND = 0.005


class Rock(NamedTuple):
    """What a push across the weak support edges does to N states.

    Attributes:
        holds: (N,) every pushed edge rocks onto a support that holds (True where no edge
            is at or below the threshold).
        pushed: (N,) edges pushed across.
        mu: (N,) the lowest μ of the pushed CoM on the support it rocks onto [N rad]
            (NaN: no edge pushed; -inf: it tips over).
        rock: (N,) the largest turn about an edge to its catch [rad].
        drop: (N,) the largest drop of the CoM in a rock [m] (negative: it rises).
        barrier: (N,) the lowest energy stability margin of a rocked rest [m].
    """

    holds: np.ndarray
    pushed: np.ndarray
    mu: FloatArray
    rock: FloatArray
    drop: FloatArray
    barrier: FloatArray


class _Support(NamedTuple):
    T: FloatArray  # G_T_B (4, 4)
    poly: FloatArray  # ordered support vertices in G (m, 3) [m]
    com_G: FloatArray  # (3,) [m]
    theta: FloatArray  # (m,) force angles of the edges [rad]


def _support(ground: Terrain, pose: FloatArray, com_body: FloatArray) -> _Support | None:
    """The rest of one state and its loaded support, or None (tips over, off the map, a line)."""
    r = ground.rest(pose[None], strict=False, com_body=com_body[None])  # type: ignore[attr-defined]
    T = r.G_T_B[0]
    if r.tips_over[0] or not np.isfinite(T).all():
        return None
    bearing = r.bearing_G(ground.candidates.points, 0)  # type: ignore[attr-defined]
    poly, line = support_vertices(bearing, GRAVITY_G)
    if line or len(poly) < 3:
        return None
    com_G = T[:3, :3] @ com_body + T[:3, 3]
    return _Support(T, poly, com_G, np.asarray(axis_angles(poly, com_G, GRAVITY_G)))


def energy_margin(poly: ArrayLike, com_G: ArrayLike, rocked: ArrayLike | None = None) -> float:
    """The normalised energy stability margin [m]: the least CoM rise that overturns the base.

    ``min_j |R_j| (1 - cos theta_j) cos psi_j`` over the edges of the support polygon
    (Hirose, Tsukagoshi and Yoneda 2001): ``R_j`` the CoM's perpendicular from edge j,
    ``theta_j`` its angle from the vertical plane through the edge (the force angle under
    gravity), ``psi_j`` the edge's inclination from the horizontal; 0 where ``theta_j <= 0``.

    Args:
        poly: ordered support vertices in G (m, 3) [m] (CCW seen from above).
        com_G: the CoM in G (3,) [m].
        rocked: the edge the base rocked about onto this support, its two ends (2, 3) [m]:
            not counted (turned back over it, the base is back on the support it left).
    """
    p = np.asarray(poly, dtype=float)
    g = np.asarray(com_G, dtype=float)
    a = np.roll(p, -1, axis=0) - p
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    d = p - g
    r = np.linalg.norm(d - np.sum(d * a, axis=1, keepdims=True) * a, axis=1)
    theta = np.asarray(axis_angles(p, g, GRAVITY_G))
    cos_psi = np.sqrt(np.clip(1.0 - a[:, 2] ** 2, 0.0, 1.0))
    h = r * (1.0 - np.cos(np.clip(theta, 0.0, None))) * cos_psi
    if rocked is not None:
        ends = np.asarray(rocked, dtype=float)
        q = np.roll(p, -1, axis=0)
        same = np.isclose(p, ends[0], atol=1e-9).all(axis=1) & np.isclose(
            q, ends[1], atol=1e-9
        ).all(axis=1)
        same |= np.isclose(p, ends[1], atol=1e-9).all(axis=1) & np.isclose(
            q, ends[0], atol=1e-9
        ).all(axis=1)
        h = np.where(same, np.inf, h)
    return float(np.min(h))


def axis_rotation(axis: ArrayLike, angle: float) -> FloatArray:
    """Rotation matrix (3, 3) by ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


class Catch(NamedTuple):
    """The base turned about a support edge until a candidate beyond it meets the ground.

    Attributes:
        angle: the turn [rad].
        R: the turn as a rotation in G about the edge (3, 3).
        poly: the caught support, ordered vertices in G (m, 3) [m].
    """

    angle: float
    R: FloatArray
    poly: FloatArray


def catch(ground: Terrain, T: ArrayLike, p0: ArrayLike, p1: ArrayLike) -> Catch | None:
    """Turn the base at pose ``T`` outward about its support edge ``p0 -> p1`` until caught.

    The edge is one of the support polygon's, counter-clockwise seen from above, so the
    outside is on its right and a positive turn about ``p1 - p0`` lowers it. Candidates
    more than :data:`BEYOND` outside the edge are lowered in steps of :data:`STEP` up to
    :data:`MAX_ROCK`; the first step where one reaches the ground is the catch.

    Args:
        ground: a heightmap ground bound to the robot.
        T: G_T_B of the rested base (4, 4).
        p0: the edge's first end in G (3,) [m].
        p1: its second end in G (3,) [m].

    Returns:
        The catch, or None: nothing meets the ground within :data:`MAX_ROCK` (it tips over).
    """
    T = np.asarray(T, dtype=float)
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    c = ground.candidates  # type: ignore[attr-defined]
    settings = ground.settings  # type: ignore[attr-defined]
    hm = ground.heightmap  # type: ignore[attr-defined]
    X = c.points @ T[:3, :3].T + T[:3, 3]
    axis = (p1 - p0) / np.linalg.norm(p1 - p0)
    outward = np.cross(axis, _UP)
    outward /= np.linalg.norm(outward)
    beyond = (X - p0) @ outward > BEYOND
    if not beyond.any():
        return None
    angles = np.arange(1, int(np.ceil(MAX_ROCK / STEP)) + 1) * STEP
    rel = X[beyond] - p0
    for angle in angles:
        R = axis_rotation(axis, float(angle))
        Y = rel @ R.T + p0
        gap = Y[:, 2] - hm.sample(Y[:, :2]).height
        if np.nanmin(gap, initial=np.inf) > 0:
            continue
        Z = (X - p0) @ R.T + p0
        gap_all = Z[:, 2] - hm.sample(Z[:, :2]).height
        tol = max(settings.contact_tol, np.linalg.norm(rel, axis=1).max() * STEP)
        bearing = (gap_all <= tol) | (c.compliant & (gap_all <= settings.compliance))
        points = np.vstack([Z[bearing & np.isfinite(gap_all)], p0, p1])
        poly, line = support_vertices(points, GRAVITY_G)
        return None if line else Catch(float(angle), R, poly)
    return None


def rock_over(
    robot: Robot,
    terrain: Terrain,
    poses: ArrayLike,
    arm_com_body: ArrayLike,
    push: float,
    threshold: float,
    margin: float,
) -> Rock:
    """Push N states across their weak support edges; rock onto the next support or tip.

    Args:
        robot: the robot.
        terrain: a heightmap ground (on a plane the support does not change: use μ).
        poses: base poses (N, 3) of (x, y, yaw) in M [m, m, rad].
        arm_com_body: the arm CoM per state in B (N, 3) [m].
        push: the push as a ratio of gravity, ``a / g`` [-] (the route's acceleration).
        threshold: an edge whose share ``theta_j |f|`` is at or below this [N rad] is
            pushed across (the margin plus what the acceleration takes off μ).
        margin: μ of the pushed CoM on the rocked support must exceed this [N rad].
    """
    P = as_poses(poses)
    n = len(P)
    com_B = np.atleast_2d(np.asarray(robot.overall_com(np.atleast_2d(arm_com_body)), dtype=float))
    com_B = np.broadcast_to(com_B, (n, 3))
    ground = terrain
    if getattr(terrain, "robot", None) is not robot:
        ground = terrain.with_robot(robot, getattr(terrain, "flipper_angle", None))
    weight = robot.total_mass * float(np.linalg.norm(GRAVITY_G))
    holds = np.ones(n, dtype=bool)
    pushed = np.zeros(n, dtype=int)
    mu, rock, drop, barrier = (np.full(n, np.nan) for _ in range(4))
    for i in range(n):
        first = _support(ground, P[i], com_B[i])
        if first is None:  # tips over (or a line) at rest already: no rock to find
            holds[i], mu[i] = False, -np.inf
            continue
        T1, poly = first.T, first.poly
        for j in np.flatnonzero(first.theta * weight <= threshold):
            p0, p1 = poly[j], poly[(j + 1) % len(poly)]
            outward = np.cross(p1 - p0, _UP)
            outward /= np.linalg.norm(outward)
            height = max(float(first.com_G[2] - (p0[2] + p1[2]) / 2), 0.0)
            pushed[i] += 1
            caught = catch(ground, T1, p0, p1)
            if caught is None:
                holds[i], mu[i] = False, -np.inf
                break
            real_G = caught.R @ (first.com_G - p0) + p0
            pushed_G = real_G + height * push * outward  # the push: horizontal, in G
            mu_j = float(np.min(axis_angles(caught.poly, pushed_G, GRAVITY_G)) * weight)
            drop_j = float(first.com_G[2] - real_G[2])
            barrier_j = energy_margin(caught.poly, real_G, (p0, p1))
            mu[i] = np.fmin(mu[i], mu_j)
            rock[i] = np.fmax(rock[i], caught.angle)
            drop[i] = np.fmax(drop[i], drop_j)
            barrier[i] = np.fmin(barrier[i], barrier_j)
            if not (mu_j > margin and drop_j < barrier_j):
                holds[i] = False
    return Rock(holds, pushed, mu, rock, drop, barrier)
