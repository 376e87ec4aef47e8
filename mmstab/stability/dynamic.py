"""The dynamic force-angle measure (Papadopoulos & Rey's full form; ``docs/design.md``).

The static measure (:mod:`mmstab.stability.static`) takes the net force ``f_r = m g`` through the
overall CoM. With accelerating bodies and external loads the net force and moment about
the CoM are (d'Alembert: the inertial force of a body is ``-m a``, not ``+m a``)::

    f_r = sum_i m_i g - sum_i m_i a_i + f_ext
    n_r = sum_i (r_i - g_o) x (m_i g - m_i a_i) - sum_i (I_i alpha_i + w_i x I_i w_i)
          + n_ext + (r_ext - g_o) x f_ext

(the gravity terms of ``n_r`` cancel about ``g_o``). Per tip-over axis ``a_j`` the
component of ``n_r`` along the axis, ``n_j = (a_j . n_r) a_j``, is replaced by the
equivalent force couple through the CoM, added to the axis-normal force::

    f_j* = Phi_j f_r + (l_j/|l_j| x n_j) / |l_j|

and ``theta_j`` is the signed angle between ``f_j*`` and ``l_j`` (the same ``atan2`` as the
static measure). The scaling is the project's static one: ``mu = min_j theta_j |f_r|``
[N rad], so zero accelerations and no external load give the static measure exactly.
A positive moment about an axis (right-handed about ``a_j``, vertices counter-clockwise)
tips the robot over that axis and lowers ``theta_j``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import FloatArray, Robot
from mmstab.stability.static import ForceAngle, base_polygon, robot_force_angle


class Wrench(NamedTuple):
    """Net force [N] and net moment about the overall CoM [N m], and that CoM [m]."""

    force: FloatArray
    moment: FloatArray
    com: FloatArray


def net_wrench(
    masses: ArrayLike,
    positions: ArrayLike,
    accelerations: ArrayLike,
    gravity: ArrayLike,
    inertial_moments: ArrayLike | None = None,
    force_ext: ArrayLike | None = None,
    point_ext: ArrayLike | None = None,
    moment_ext: ArrayLike | None = None,
) -> Wrench:
    """Net force and moment about the overall CoM of a set of bodies (d'Alembert), batched.

    Args:
        masses: body masses (k,) [kg].
        positions: body CoMs (k, 3) [m], in the frame of ``gravity``; or (B, k, 3) for B
            instants at once.
        accelerations: body CoM accelerations, the shape of ``positions`` [m/s^2], same frame.
        gravity: gravity acceleration (3,) or (B, 3) [m/s^2], same frame.
        inertial_moments: the bodies' rate of angular momentum about their own CoMs,
            ``I alpha + w x I w``, the shape of ``positions`` [N m]; ``None`` = point masses.
        force_ext: external force (3,) or (B, 3) [N] (e.g. a pull on the tool), or ``None``.
        point_ext: where ``force_ext`` acts (3,) or (B, 3) [m]; required with ``force_ext``.
        moment_ext: external pure moment (3,) or (B, 3) [N m], or ``None``.

    Returns:
        :class:`Wrench` of ``f_r``, ``n_r`` about ``g_o``, and ``g_o``: (3,) each, or (B, 3).

    Raises:
        ValueError: shapes that do not match, a non-positive total mass.
    """
    m = np.asarray(masses, dtype=float).reshape(-1)
    r = np.asarray(positions, dtype=float)
    a = np.asarray(accelerations, dtype=float)
    r, a = (x.reshape(-1, 3) if x.ndim <= 2 else x for x in (r, a))  # one instant: (k, 3)
    g = np.asarray(gravity, dtype=float)
    if not (len(m) == r.shape[-2] == a.shape[-2]) or r.shape != a.shape or g.shape[-1] != 3:
        raise ValueError(
            f"masses {m.shape}, positions {r.shape}, accelerations {a.shape}, "
            f"gravity {g.shape} differ"
        )
    if m.sum() <= 0:
        raise ValueError("total mass must be positive")
    com = (m[:, None] * r).sum(axis=-2) / m.sum()
    forces = m[:, None] * (g[..., None, :] - a)  # gravity + d'Alembert inertial force of each
    force = forces.sum(axis=-2)
    moment = np.cross(r - com[..., None, :], forces).sum(axis=-2)
    if inertial_moments is not None:
        moment = moment - np.asarray(inertial_moments, dtype=float).reshape(a.shape).sum(axis=-2)
    if force_ext is not None:
        if point_ext is None:
            raise ValueError("force_ext needs point_ext, the point it acts at")
        f_ext = np.asarray(force_ext, dtype=float)
        force = force + f_ext
        moment = moment + np.cross(np.asarray(point_ext, dtype=float) - com, f_ext)
    if moment_ext is not None:
        moment = moment + np.asarray(moment_ext, dtype=float)
    return Wrench(force=force, moment=moment, com=com)


def dynamic_axis_angles(
    vertices: ArrayLike, com: ArrayLike, net_force: ArrayLike, net_moment: ArrayLike
) -> FloatArray:
    """Signed angles theta_j of the equivalent forces f_j* against one ordered polygon.

    Args:
        vertices: ordered polygon (n, 3) [m], as from ``stability.support_polygon``.
        com: overall CoM (B, 3) or (3,) [m].
        net_force: f_r (B, 3) or (3,) [N].
        net_moment: n_r about the CoM (B, 3) or (3,) [N m].

    Returns:
        (B, n) or (n,) angles [rad]; column j is the axis from vertex j to vertex j+1.
    """
    p = np.asarray(vertices, dtype=float)
    g0, f0, n0 = (np.asarray(v, dtype=float) for v in (com, net_force, net_moment))
    single = g0.ndim == 1 and f0.ndim == 1 and n0.ndim == 1
    g, f, n = (np.atleast_2d(v)[:, None, :] for v in (g0, f0, n0))  # (B, 1, 3)
    p_next = np.roll(p, -1, axis=0)
    a_hat = (p_next - p) / np.linalg.norm(p_next - p, axis=1, keepdims=True)  # (n, 3)
    d = p_next - g
    l_j = d - np.sum(d * a_hat, axis=-1, keepdims=True) * a_hat  # (B, n, 3)
    f_j = f - np.sum(f * a_hat, axis=-1, keepdims=True) * a_hat
    n_j = np.sum(n * a_hat, axis=-1, keepdims=True) * a_hat  # moment along each axis
    l_norm = np.linalg.norm(l_j, axis=-1, keepdims=True)
    f_star = f_j + np.cross(l_j / l_norm, n_j) / l_norm
    sin_part = np.sum(np.cross(l_j, f_star) * a_hat, axis=-1)
    cos_part = np.sum(l_j * f_star, axis=-1)
    out = np.arctan2(sin_part, cos_part)
    return out[0] if single else out


def dynamic_force_angle(
    vertices: ArrayLike, com: ArrayLike, net_force: ArrayLike, net_moment: ArrayLike
) -> ForceAngle:
    """Dynamic force-angle measure ``mu = min_j theta_j* |f_r|`` [N rad], batched.

    Args:
        vertices: ordered polygon (n, 3) [m].
        com: overall CoM (B, 3) or (3,) [m].
        net_force: f_r (B, 3) or (3,) [N].
        net_moment: n_r about the CoM (B, 3) or (3,) [N m].

    Returns:
        ``ForceAngle(mu (B,), angles (B, n))``; equal to the static measure when
        ``net_moment`` is zero and ``net_force`` is ``m g``.
    """
    angles = np.atleast_2d(dynamic_axis_angles(vertices, com, net_force, net_moment))
    magnitude = np.linalg.norm(np.atleast_2d(np.asarray(net_force, dtype=float)), axis=1)
    return ForceAngle(mu=angles.min(axis=1) * magnitude, angles=angles)


def robot_force_angle_wrench(
    robot: Robot,
    gravity_body: ArrayLike,
    arm_com_body: ArrayLike,
    tool_body: ArrayLike,
    wrench_body: ArrayLike,
) -> ForceAngle:
    """Quasi-static measure of the robot with an external wrench at the tool, body frame.

    The wrench (e.g. the gripper pulling a handle) adds its force to ``f_r = m g`` and its
    moment about the overall CoM to ``n_r``; the measure is then the dynamic form above.

    Args:
        robot: the robot (payload already attached, see ``mmstab.model.payload``).
        gravity_body: gravity in B (B, 3) or (3,) [m/s^2].
        arm_com_body: arm CoM g_a in B (B, 3) or (3,) [m].
        tool_body: where the wrench acts, in B (B, 3) or (3,) [m].
        wrench_body: ``[f (3) [N], n (3) [N m]]`` in B, (B, 6) or (6,).

    Returns:
        ``ForceAngle`` with mu (B,) [N rad]; equal to ``robot_force_angle`` for a zero wrench.

    Raises:
        ValueError: a wrench that is not 6 numbers per state.
    """
    w = np.atleast_2d(np.asarray(wrench_body, dtype=float))
    if w.shape[-1] != 6:
        raise ValueError(f"a wrench is [fx, fy, fz, nx, ny, nz], got shape {w.shape}")
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    com = robot.overall_com(np.atleast_2d(np.asarray(arm_com_body, dtype=float)))
    force = robot.total_mass * g + w[:, :3]
    moment = np.cross(np.atleast_2d(np.asarray(tool_body, dtype=float)) - com, w[:, :3]) + w[:, 3:]
    return dynamic_force_angle(base_polygon(robot).vertices, com, force, moment)


def robot_mu(robot: Robot, gravity_body: ArrayLike, q: ArrayLike) -> FloatArray:
    """μ [N rad] (N,) of the robot at postures ``q`` (N, 4) [rad], with its tool wrench.

    Without a wrench (``Robot.tool_wrench`` None) this is ``robot_force_angle`` of the
    postures' arm CoMs; with one, :func:`robot_force_angle_wrench` at the postures' tool
    points (the wrist frame's origin). What the verdicts of a plan and of a tracking run
    use, so that a problem's ``payload.wrench`` reaches them.

    Args:
        robot: the robot (payload attached).
        gravity_body: gravity in B (N, 3) or (3,) [m/s^2].
        q: arm postures (N, 4) or (4,) [rad].
    """
    qa = np.atleast_2d(np.asarray(q, dtype=float))
    com = np.atleast_2d(robot.arm_com(qa))
    if robot.tool_wrench is None:
        return robot_force_angle(robot, gravity_body, com).mu
    tool = robot.kinematics.link_frames(qa)[:, -1, :3, 3]
    wrench = np.broadcast_to(np.asarray(robot.tool_wrench, dtype=float), (len(qa), 6))
    g = np.broadcast_to(np.asarray(gravity_body, dtype=float), (len(qa), 3))
    return robot_force_angle_wrench(robot, g, com, tool, wrench).mu
