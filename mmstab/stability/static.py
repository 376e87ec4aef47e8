"""Force-angle tip-over stability (Papadopoulos & Rey 1996; paper Eq. 2-5).

Conventions and errata: ``docs/design.md``, "Force-angle".

For each tip-over axis ``a_j = p_{j+1} - p_j`` of the support polygon (vertices ordered
counter-clockwise about the polygon's normal, which points to the CoM's side):

    l_j = Phi_j (p_{j+1} - g_o),   f_j = Phi_j f_r,   Phi_j = I - a_j a_j^T / |a_j|^2
    theta_j = atan2((l_j x f_j) . a_j/|a_j|,  l_j . f_j)
    mu = min_j theta_j |f_r|                      [N rad]

``atan2`` of the cross and dot products is the signed angle between the *unit* vectors
f_j/|f_j| and l_j/|l_j| (the paper's Eq. 4 forgets to normalise; see the errata),
smooth where ``sigma_j acos(.)`` is not. theta_j > 0 when the force line passes inside
axis j, so mu > 0 exactly when the robot is statically stable.

The μ mmstab reports for a state is this measure on the contacts that carry its load
(:mod:`mmstab.stability.support`); on a plane they are the tracks' rectangle
(:func:`robot_force_angle`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import ConvexHull, QhullError

from mmstab.model.robot import FloatArray, Robot
from mmstab.terrain.polygon import hull_along, support_vertices


class SupportPolygon(NamedTuple):
    """Support polygon: hull vertices (n, 3) [m] ordered CCW about ``normal`` (unit, (3,))."""

    vertices: FloatArray
    normal: FloatArray


class ForceAngle(NamedTuple):
    """Force-angle result: ``mu`` [N rad] and the per-axis signed angles ``angles`` [rad].

    ``mu`` is (B,) for B states, a float for one (:func:`robot_force_angle` of a (3,)
    gravity); ``angles`` (B, k) or (k,).
    """

    mu: Any
    angles: FloatArray


def support_polygon(points: ArrayLike, com: ArrayLike, net_force: ArrayLike) -> SupportPolygon:
    """Order ground contact points into a convex support polygon, whatever their order.

    Args:
        points: contact points (n, 3), n >= 3, on (or near) a plane [m].
        com: overall CoM (3,) [m]; the normal is turned toward its side of the plane.
        net_force: net force (3,) [N]; orients the normal when the CoM lies in the plane.

    Raises:
        ValueError: fewer than 3 points, or all on one line.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 3:
        raise ValueError(f"support points must be (n>=3, 3), got {pts.shape}")
    centroid = pts.mean(axis=0)
    _, sing, vt = np.linalg.svd(pts - centroid)
    if sing[1] < 1e-9 * max(sing[0], 1e-300):
        raise ValueError("support points are collinear: no support polygon")
    normal = vt[2]
    side = float(normal @ (np.asarray(com, dtype=float) - centroid))
    if abs(side) < 1e-12:
        side = -float(normal @ np.asarray(net_force, dtype=float))
    if side < 0:
        normal = -normal
    u = vt[0]
    v = np.cross(normal, u)
    try:
        hull = ConvexHull(np.stack([(pts - centroid) @ u, (pts - centroid) @ v], axis=1))
    except QhullError as exc:
        raise ValueError(f"degenerate support polygon: {exc}") from None
    return SupportPolygon(vertices=pts[hull.vertices], normal=normal)  # 2-D hull is CCW


def support_polygon_3d(points: ArrayLike, net_force: ArrayLike) -> SupportPolygon:
    """Order 3-D contact points, not necessarily coplanar, into the support polygon.

    The polygon is the convex hull of the points seen along the net force: its vertices
    are the contacts on the hull of their projection onto the plane normal to ``f_r``,
    kept at their 3-D positions and ordered counter-clockwise about ``-f_r``. Consecutive
    vertices join the tip-over axes of :func:`axis_angles`, whose angles need no common
    plane: each is measured about its own axis. For coplanar points it is the polygon of
    :func:`support_polygon` (the same vertices, in the same turning sense).

    Args:
        points: contact points (n, 3), n >= 3 [m].
        net_force: net force f_r (3,) [N] (gravity: m g).

    Returns:
        ``SupportPolygon`` with ``normal`` = -f_r / |f_r| (the "up" it is ordered about).

    Raises:
        ValueError: fewer than 3 points, or all on one line seen along ``f_r``.
    """
    f = np.asarray(net_force, dtype=float)
    return SupportPolygon(vertices=hull_along(points, f), normal=-f / np.linalg.norm(f))


class ContactStability(NamedTuple):
    """Force-angle on touching contacts: ordered polygon (m, 3) [m], mu [N rad], line flag."""

    polygon: FloatArray
    mu: float
    line: bool


def contact_force_angle(
    contacts: ArrayLike, com: ArrayLike, net_force: ArrayLike
) -> ContactStability:
    """Force-angle measure on 3-D contacts (any order, not necessarily coplanar).

    With fewer than three contacts off one line (seen along the force) the "polygon" is the
    segment between the two extreme contacts and mu <= 0: balanced at best; one point
    gives mu = 0; none gives NaN.

    Args:
        contacts: touching contact points (n, 3) [m].
        com: overall CoM (3,) [m].
        net_force: net force (3,) [N].
    """
    f = np.asarray(net_force, dtype=float)
    poly, line = support_vertices(contacts, f)
    if len(poly) == 0:
        return ContactStability(poly, float("nan"), True)
    if len(poly) == 1:
        return ContactStability(poly, 0.0, True)
    theta = axis_angles(poly, com, f)
    return ContactStability(poly, float(np.min(theta) * np.linalg.norm(f)), line)


def _cross_last(a: FloatArray, b: FloatArray) -> FloatArray:
    """``np.cross(a, b)`` along the last axis (3), the same floats without its axis moves."""
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def axis_angles(vertices: ArrayLike, coms: ArrayLike, net_forces: ArrayLike) -> FloatArray:
    """Signed angles theta_j for many CoMs/forces against one ordered polygon.

    Args:
        vertices: ordered polygon (n, 3) [m], as from :func:`support_polygon`.
        coms: overall CoMs (B, 3) or (3,) [m].
        net_forces: net forces (B, 3) or (3,) [N].

    Returns:
        (B, n) or (n,) angles [rad]; column j is the axis from vertex j to vertex j+1.
    """
    p = np.asarray(vertices, dtype=float)
    g = np.asarray(coms, dtype=float)
    f = np.asarray(net_forces, dtype=float)
    single = g.ndim == 1 and f.ndim == 1
    g, f = np.atleast_2d(g)[:, None, :], np.atleast_2d(f)[:, None, :]  # (B, 1, 3)
    p_next = np.roll(p, -1, axis=0)
    a_hat = (p_next - p) / np.linalg.norm(p_next - p, axis=1, keepdims=True)  # (n, 3)
    d = p_next - g  # (B, n, 3)
    l_j = d - np.sum(d * a_hat, axis=-1, keepdims=True) * a_hat
    f_j = f - np.sum(f * a_hat, axis=-1, keepdims=True) * a_hat
    sin_part = np.sum(_cross_last(l_j, f_j) * a_hat, axis=-1)
    cos_part = np.sum(l_j * f_j, axis=-1)
    out = np.arctan2(sin_part, cos_part)
    return out[0] if single else out


def padded_axis_angles(
    vertices: FloatArray, count: ArrayLike, coms: FloatArray, net_force: ArrayLike
) -> FloatArray:
    """:func:`axis_angles` of N polygons at once, each against its own CoM.

    Args:
        vertices: (N, H, 3) [m] ordered polygons, the first ``count[i]`` rows of row i.
        count: (N,) vertices per polygon (>= 2).
        coms: (N, 3) [m] overall CoMs.
        net_force: (3,) [N] the net force of all of them.

    Returns:
        (N, H) angles [rad], column j the axis from vertex j to vertex j+1 (cyclic within
        ``count``); +inf past ``count`` (so a row's minimum is its polygon's).
    """
    p = np.asarray(vertices, dtype=float)
    cnt = np.asarray(count, dtype=np.intp)
    h = p.shape[1]
    col = np.arange(h)[None, :]
    inside = col < cnt[:, None]
    nxt = np.where(col + 1 < cnt[:, None], col + 1, 0)
    p_next = np.take_along_axis(p, nxt[..., None], axis=1)
    f = np.asarray(net_force, dtype=float)
    with np.errstate(invalid="ignore"):  # the padding (NaN) rows
        a_hat = (p_next - p) / np.linalg.norm(p_next - p, axis=-1, keepdims=True)
        d = p_next - np.asarray(coms, dtype=float)[:, None, :]
        l_j = d - np.sum(d * a_hat, axis=-1, keepdims=True) * a_hat
        f_j = f - np.sum(f * a_hat, axis=-1, keepdims=True) * a_hat
        sin_part = np.sum(_cross_last(l_j, f_j) * a_hat, axis=-1)
        cos_part = np.sum(l_j * f_j, axis=-1)
        out = np.arctan2(sin_part, cos_part)
    return np.where(inside, out, np.inf)


def force_angle_batch(vertices: ArrayLike, coms: ArrayLike, net_forces: ArrayLike) -> ForceAngle:
    """Vectorised force-angle measure against one ordered polygon.

    Args:
        vertices: ordered polygon (n, 3) [m], as from :func:`support_polygon`.
        coms: overall CoMs (B, 3) [m].
        net_forces: net forces (B, 3) or (3,) [N].

    Returns:
        ``ForceAngle(mu (B,) [N rad], angles (B, n) [rad])``.
    """
    angles = axis_angles(vertices, np.atleast_2d(coms), np.atleast_2d(net_forces))
    magnitude = np.linalg.norm(np.atleast_2d(np.asarray(net_forces, dtype=float)), axis=1)
    return ForceAngle(mu=angles.min(axis=1) * magnitude, angles=angles)


def force_angle(support_points: ArrayLike, com: ArrayLike, net_force: ArrayLike) -> float:
    """Force-angle stability measure mu = min_j theta_j |f_r| (paper Eq. 2).

    Args:
        support_points: ground contact points (n, 3), any order [m].
        com: overall CoM g_o (3,) [m].
        net_force: net force f_r (3,) [N], e.g. m_T g.

    Returns:
        mu [N rad]: positive exactly when the robot is statically stable.
    """
    poly = support_polygon(support_points, com, net_force)
    theta = axis_angles(poly.vertices, com, net_force)
    return float(theta.min() * np.linalg.norm(np.asarray(net_force, dtype=float)))


def force_angle_sx(vertices: ArrayLike, com: ca.SX, net_force: ArrayLike | ca.SX) -> ca.SX:
    """Symbolic force-angle measure for a fixed ordered polygon (CasADi).

    Args:
        vertices: ordered polygon (n, 3) [m] (numeric).
        com: overall CoM, (3,) SX [m].
        net_force: net force, (3,) numeric or SX [N].

    Returns:
        scalar SX mu [N rad].
    """
    p = np.asarray(vertices, dtype=float)
    f = net_force if isinstance(net_force, ca.SX) else ca.SX(ca.DM(np.asarray(net_force, float)))
    thetas = []
    for j in range(p.shape[0]):
        p_next = p[(j + 1) % p.shape[0]]
        a_hat = (p_next - p[j]) / np.linalg.norm(p_next - p[j])
        d = ca.DM(p_next) - com
        l_j = d - ca.dot(d, ca.DM(a_hat)) * ca.DM(a_hat)
        f_j = f - ca.dot(f, ca.DM(a_hat)) * ca.DM(a_hat)
        thetas.append(ca.atan2(ca.dot(ca.cross(l_j, f_j), ca.DM(a_hat)), ca.dot(l_j, f_j)))
    return ca.mmin(ca.vertcat(*thetas)) * ca.norm_2(f)


# ------------------------------------------------------------------------ the tracked robot
def base_polygon(robot: Robot) -> SupportPolygon:
    """The base's support polygon in the body frame (normal +z_B)."""
    pts = robot.base.support_points()
    return support_polygon(pts, robot.base.com, np.array([0.0, 0.0, -1.0]))


def robot_force_angle(
    robot: Robot, gravity_body: ArrayLike, arm_com_body: ArrayLike | None
) -> ForceAngle:
    """Quasi-static force-angle measure of the robot for many states, in the body frame.

    Args:
        robot: the robot.
        gravity_body: gravity in B (B, 3) or (3,) [m/s^2] (see ``Terrain.gravity_body``).
        arm_com_body: arm CoM g_a in B (B, 3) or (3,) [m]; ``None`` = the arm removed.

    Returns:
        ``ForceAngle`` with mu (B,) [N rad], f_r = m g with m the mass on the base; for one
        state (gravity (3,), arm CoM (3,) or None) mu is a float and angles (k,).
    """
    one = np.ndim(gravity_body) == 1 and (arm_com_body is None or np.ndim(arm_com_body) == 1)
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    if arm_com_body is None:
        mass, com = robot.base.mass, np.broadcast_to(robot.base.com, g.shape)
    else:
        mass, com = robot.total_mass, robot.overall_com(np.atleast_2d(arm_com_body))
    out = force_angle_batch(base_polygon(robot).vertices, com, mass * g)
    return ForceAngle(float(out.mu[0]), out.angles[0]) if one else out


def mu_max(robot: Robot) -> float:
    """The measure on flat ground with the arm stowed: the normaliser of Eq. 6 [N rad]."""
    flat = np.array([0.0, 0.0, -9.81])
    return float(robot_force_angle(robot, flat, robot.arm_com(robot.stowed)).mu)
