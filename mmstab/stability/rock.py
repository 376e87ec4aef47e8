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
``theta_j |f|`` of μ is at or below ``threshold`` and that the push moves the CoM across
(where it does not, the base stays and μ of the pushed CoM about that edge must exceed
``margin``), the rested base is turned about that edge, outward, until the first contact
candidate beyond it meets the ground (the catch, in steps of :data:`STEP`, at most
:data:`MAX_ROCK`); the support there is the edge's two ends, the candidates touching and
the tracks' bottom run within the ground's compliance (as at a rest). The state holds if

- a catch is found where the pushed CoM is inside the caught support, and the turn's work
  (the CoM's fall under the tilted net force, ``drop + (a / g) . travel`` in metres of
  height) is below the energy the caught support needs to overturn about any edge but the
  one it came over: ``|R_j| (1 - cos theta_j) cos psi_j`` (Hirose, Tsukagoshi and Yoneda
  2001's normalised energy stability margin; ``R_j`` the CoM's distance from edge j,
  ``psi_j`` the edge's inclination). Where either fails the base turns on about that
  edge, to the next catch (:func:`rock`), up to :data:`MAX_ROCK` in all;
- μ of the pushed CoM on the support that holds it exceeds ``margin``.

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
#: The turn's steps are tried this many at a time, from the smallest, up to the first that
#: meets the ground (each step's test is the same whichever batch it is in).
CATCH_CHUNK = 16


class Rock(NamedTuple):
    """What a push across the weak support edges does to N states.

    Attributes:
        holds: (N,) every pushed edge rocks onto a support that holds (True where no edge
            is at or below the threshold).
        pushed: (N,) edges pushed across.
        mu: (N,) the lowest μ of the pushed CoM on the support it rocks onto [N rad]
            (NaN: no edge pushed; -inf: it tips over).
        rock: (N,) the largest turn about an edge to its catch [rad] (0: pushed, the CoM
            stays inside; NaN: nothing pushed).
        drop: (N,) the largest work of a rock: the CoM's fall under the tilted net force
            [m of height] (negative: it rises).
        barrier: (N,) the lowest energy margin of a caught support (but the edge it came
            over) [m] (NaN: no turn).
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


def rested_support(ground: Terrain, pose: FloatArray, com_body: FloatArray) -> _Support | None:
    """The rest of one state and its loaded support, or None (tips over, off the map, a line).

    Args:
        ground: a heightmap ground bound to the robot.
        pose: (x, y, yaw) in M [m, m, rad].
        com_body: the overall CoM in B (3,) [m].

    Returns:
        ``T`` (G_T_B), ``poly`` (the ordered support vertices in G [m]), ``com_G`` [m] and
        ``theta`` (the edges' force angles [rad]).
    """
    return rested_supports(ground, pose[None], com_body[None])[0]


def rested_supports(
    ground: Terrain, poses: FloatArray, com_body: FloatArray
) -> list[_Support | None]:
    """:func:`rested_support` of N states (N, 3) and CoMs (N, 3) [m], their rests in one batch.

    The rest solves each pose alone (the batch's rests are the single rests, bit for bit).
    """
    r = ground.rest(poses, strict=False, com_body=com_body)  # type: ignore[attr-defined]
    out: list[_Support | None] = []
    for i in range(len(poses)):
        T = r.G_T_B[i]
        if r.tips_over[i] or not np.isfinite(T).all():
            out.append(None)
            continue
        bearing = r.bearing_G(ground.candidates.points, i)  # type: ignore[attr-defined]
        poly, line = support_vertices(bearing, GRAVITY_G)
        if line or len(poly) < 3:
            out.append(None)
            continue
        com_G = T[:3, :3] @ com_body[i] + T[:3, 3]
        out.append(_Support(T, poly, com_G, np.asarray(axis_angles(poly, com_G, GRAVITY_G))))
    return out


def energy_margins(
    poly: ArrayLike, com_G: ArrayLike, rocked: ArrayLike | None = None
) -> FloatArray:
    """Per edge, the CoM's rise that overturns the base about it [m] (m,).

    ``|R_j| (1 - cos theta_j) cos psi_j`` for edge j (from vertex j to j + 1) of the
    support polygon (the normalised energy stability margin of Hirose, Tsukagoshi and
    Yoneda 2001 is their least): ``R_j`` the CoM's perpendicular from the edge,
    ``theta_j`` its angle from the vertical plane through the edge (the force angle under
    gravity), ``psi_j`` the edge's inclination from the horizontal; 0 where ``theta_j <= 0``.

    Args:
        poly: ordered support vertices in G (m, 3) [m] (CCW seen from above).
        com_G: the CoM in G (3,) [m].
        rocked: the edge the base rocked about onto this support, its two ends (2, 3) [m]:
            inf (turned back over it, the base is back on the support it left).
    """
    p = np.asarray(poly, dtype=float)
    g = np.asarray(com_G, dtype=float)
    q = np.roll(p, -1, axis=0)
    a = (q - p) / np.linalg.norm(q - p, axis=1, keepdims=True)
    d = p - g
    r = np.linalg.norm(d - np.sum(d * a, axis=1, keepdims=True) * a, axis=1)
    theta = np.asarray(axis_angles(p, g, GRAVITY_G))
    cos_psi = np.sqrt(np.clip(1.0 - a[:, 2] ** 2, 0.0, 1.0))
    h = r * (1.0 - np.cos(np.clip(theta, 0.0, None))) * cos_psi
    if rocked is not None:
        e0, e1 = np.asarray(rocked, dtype=float)

        def at(x: FloatArray, e: FloatArray) -> np.ndarray:
            return np.asarray(np.isclose(x, e, atol=1e-9).all(axis=1))

        h = np.where((at(p, e0) & at(q, e1)) | (at(p, e1) & at(q, e0)), np.inf, h)
    return h


def energy_margin(poly: ArrayLike, com_G: ArrayLike, rocked: ArrayLike | None = None) -> float:
    """The normalised energy stability margin [m]: the least of :func:`energy_margins`."""
    return float(np.min(energy_margins(poly, com_G, rocked)))


def axis_rotation(axis: ArrayLike, angle: float) -> FloatArray:
    """Rotation matrix (3, 3) by ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


class Catch(NamedTuple):
    """The base turned about a support edge until a candidate beyond it meets the ground.

    Attributes:
        angle: the turn [rad].
        T: the turned base's G_T_B (4, 4).
        poly: the caught support, ordered vertices in G (m, 3) [m].
    """

    angle: float
    T: FloatArray
    poly: FloatArray


def catch(ground: Terrain, T: ArrayLike, p0: ArrayLike, p1: ArrayLike) -> Catch | None:
    """Turn the base at pose ``T`` outward about its support edge ``p0 -> p1`` until caught.

    The edge is one of the support polygon's, counter-clockwise seen from above, so the
    outside is on its right and a positive turn about ``p1 - p0`` lowers it. Candidates
    more than :data:`BEYOND` outside the edge are lowered in steps of :data:`STEP` up to
    :data:`MAX_ROCK`; the first step where one reaches the ground is the catch, and the
    support there is the edge's ends, the candidates touching (within the step's travel)
    and the tracks' bottom run within the ground's compliance.

    Args:
        ground: a heightmap ground bound to the robot.
        T: G_T_B of the base (4, 4).
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
    rel = X[(X - p0) @ outward > BEYOND] - p0
    if len(rel) == 0:
        return None
    angles = np.arange(1, int(np.ceil(MAX_ROCK / STEP)) + 1) * STEP
    k, R = -1, np.eye(3)
    for lo in range(0, len(angles), CATCH_CHUNK):  # most catches come within a few steps
        Rs = np.stack([axis_rotation(axis, float(x)) for x in angles[lo : lo + CATCH_CHUNK]])
        Y = np.einsum("aij,kj->aki", Rs, rel) + p0
        gap = Y[..., 2] - hm.sample(Y[..., :2]).height
        met = np.flatnonzero((np.nan_to_num(gap, nan=np.inf) <= 0).any(axis=1))
        if met.size:
            k, R = lo + int(met[0]), Rs[int(met[0])]
            break
    if k < 0:
        return None
    turned = np.eye(4)
    turned[:3, :3] = R @ T[:3, :3]
    turned[:3, 3] = R @ (T[:3, 3] - p0) + p0
    Z = (X - p0) @ R.T + p0
    gap_all = Z[:, 2] - hm.sample(Z[:, :2]).height
    tol = max(settings.contact_tol, float(np.linalg.norm(rel, axis=1).max()) * STEP)
    bearing = np.isfinite(gap_all) & (
        (gap_all <= tol) | (c.compliant & (gap_all <= settings.compliance))
    )
    poly, line = support_vertices(np.vstack([Z[bearing], p0, p1]), GRAVITY_G)
    return None if line else Catch(float(angles[k]), turned, poly)


class Rocked(NamedTuple):
    """Where a push across an edge ends: the base caught by a support that holds the push.

    Attributes:
        angle: the turn from the rest [rad] (the turns about each edge in turn, summed).
        T: the caught base's G_T_B (4, 4).
        poly: its support, ordered vertices in G (m, 3) [m].
        com_G: the CoM there in G (3,) [m].
        shift: the push's move of the CoM, in G (3,) [m].
        edge: the last edge turned about, its two ends in G (2, 3) [m].
        work: the CoM's fall under the tilted net force in the turn [m of height].
        barrier: the caught support's least energy margin to overturn [m] (all edges but
            ``edge``; > ``work``).
    """

    angle: float
    T: FloatArray
    poly: FloatArray
    com_G: FloatArray
    shift: FloatArray
    edge: FloatArray
    work: float
    barrier: float


def rock(
    ground: Terrain, T: ArrayLike, com_G: ArrayLike, push_G: ArrayLike, p0: ArrayLike, p1: ArrayLike
) -> Rocked | None:
    """Push the base across its edge ``p0 -> p1``; let it turn until a support holds the push.

    The push ``push_G`` (``a / g`` along the base's horizontal acceleration, the edge's
    outward normal) tilts the net force: the CoM acts as if moved ``h push_G`` (``h``: its
    height above the edge). The base turns about the edge to its catch (:func:`catch`).
    There it holds if the moved CoM is inside the caught support and the turn's work,
    ``drop + push_G . travel`` of the CoM (its fall under the tilted net force, in metres
    of height), is below the support's :func:`energy_margins` about each edge but the one
    it came over; else it turns on about the edge it is outside of (or whose margin the
    work exceeds), up to :data:`MAX_ROCK` in all.

    Args:
        ground: a heightmap ground bound to the robot.
        T: G_T_B of the rested base (4, 4).
        com_G: the CoM in G (3,) [m].
        push_G: the push as a ratio of gravity, horizontal in G (3,) [-].
        p0: the edge's first end in G (3,) [m].
        p1: its second end in G (3,) [m].

    Returns:
        The caught state, or None: it turns past :data:`MAX_ROCK` (it tips over).
    """
    T = np.asarray(T, dtype=float)
    start = np.asarray(com_G, dtype=float)
    com = start.copy()
    push = np.asarray(push_G, dtype=float)
    edge = np.array([p0, p1], dtype=float)
    shift = max(float(start[2] - edge[:, 2].mean()), 0.0) * push  # the CoM's, in G [m]
    angle = 0.0
    while True:
        caught = catch(ground, T, edge[0], edge[1])
        if caught is None or angle + caught.angle > MAX_ROCK:
            return None
        R = caught.T[:3, :3] @ T[:3, :3].T
        com = R @ (com - edge[0]) + edge[0]
        T, angle = caught.T, angle + caught.angle
        theta = np.asarray(axis_angles(caught.poly, com + shift, GRAVITY_G))
        work = float(start[2] - com[2] + push @ (com - start))
        margins = energy_margins(caught.poly, com + shift, edge)
        if theta.min() > 0 and work < margins.min():
            return Rocked(angle, T, caught.poly, com, shift, edge, work, float(margins.min()))
        j = int(np.argmin(theta)) if theta.min() <= 0 else int(np.argmin(margins))
        edge = np.array([caught.poly[j], caught.poly[(j + 1) % len(caught.poly)]])


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
    mu, turn, drop, barrier = (np.full(n, np.nan) for _ in range(4))
    supports = rested_supports(ground, P, np.ascontiguousarray(com_B))
    for i in range(n):
        first = supports[i]
        if first is None:  # tips over (or a line) at rest already: no rock to find
            holds[i], mu[i] = False, -np.inf
            continue
        T1, poly = first.T, first.poly
        for j in np.flatnonzero(first.theta * weight <= threshold):
            p0, p1 = poly[j], poly[(j + 1) % len(poly)]
            outward = np.cross(p1 - p0, _UP)
            outward /= np.linalg.norm(outward)
            pushed[i] += 1
            height = max(float(first.com_G[2] - (p0[2] + p1[2]) / 2), 0.0)
            theta = axis_angles(poly, first.com_G + height * push * outward, GRAVITY_G)[j]
            if theta > 0:  # the pushed CoM stays inside: no rock, the margin is this edge's
                mu[i] = np.fmin(mu[i], float(theta) * weight)
                turn[i], drop[i] = np.fmax(turn[i], 0.0), np.fmax(drop[i], 0.0)
                holds[i] &= bool(theta * weight > margin)
                continue
            caught = rock(ground, T1, first.com_G, push * outward, p0, p1)
            if caught is None:
                holds[i], mu[i] = False, -np.inf
                break
            pushed_G = caught.com_G + caught.shift
            mu_j = float(np.min(axis_angles(caught.poly, pushed_G, GRAVITY_G)) * weight)
            mu[i] = np.fmin(mu[i], mu_j)
            turn[i] = np.fmax(turn[i], caught.angle)
            drop[i] = np.fmax(drop[i], caught.work)
            barrier[i] = np.fmin(barrier[i], caught.barrier)
            if not mu_j > margin:  # (rock holds the work below the barrier)
                holds[i] = False
    return Rock(holds, pushed, mu, turn, drop, barrier)
