"""One μ for one state: the force-angle measure on the contacts that carry the load.

Every number mmstab reports as "μ at this pose with this arm" comes from
:func:`loaded_support`: the planner's summary and verdicts, ``mmstab rest``
(:func:`mmstab.stability.stance.stance`), the tracking run, the stability map, the online
loop and the prediction beside a physics run. The support is the one the resting pose
finds for *that* state:

- on a heightmap the rigid base is rested with the state's overall CoM (base plus the arm
  where it is), and the support is the hull of the contacts that carry load: the touching
  ones and the tracks' bottom run within the compliance the robot model states
  (:class:`mmstab.terrain.rest.RestSettings`, ``compliance``). The arm's CoM moves the
  rest itself (which edge of a bump the robot leans on), so the rest is not the stowed
  arm's;
- on a plane (the ramp) every bottom-run contact touches whatever the load, so the
  support is the tracks' rectangle, and μ is computed on it in the body frame in one batch
  (:func:`mmstab.stability.static.robot_force_angle`): the same number as the contacts in G
  give (a heightmap that is a plane gives the ramp's μ; ``tests``).

The planner's inner loop keeps the cheaper track rectangle under the stowed arm's rest to
rank arm CoMs; what it reports is recomputed here (``docs/stability.md``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.model.robot import FloatArray, Robot
from mmstab.stability.dynamic import dynamic_force_angle
from mmstab.stability.static import (
    axis_angles,
    base_polygon,
    force_angle_batch,
    padded_axis_angles,
)
from mmstab.stability.support_kernel import support_mu_c
from mmstab.terrain.base import GRAVITY_G, Terrain, as_poses
from mmstab.terrain.polygon import support_vertices
from mmstab.terrain.polygon_batch import hulls_along_batch
from mmstab.terrain.rest.types import RestPoses


class LoadedSupport(NamedTuple):
    """The support of N states and the force-angle measure on it.

    Attributes:
        mu: force-angle measure [N rad] (N,); NaN where the ground is unknown (a rest
            off the map, asked for with ``strict=False``).
        gravity_body: gravity in B at the states' resting poses (N, 3) [m/s^2].
        line: (N,) the loaded contacts lie on one line seen along gravity (μ <= 0).
        tips_over: (N,) the rest found no attitude that holds the CoM.
        high_centred: (N,) the chassis touches the ground.
        converged: (N,) the rest settled (always on a plane).
    """

    mu: FloatArray
    gravity_body: FloatArray
    line: np.ndarray
    tips_over: np.ndarray
    high_centred: np.ndarray
    converged: np.ndarray


def is_heightmap(terrain: Terrain) -> bool:
    """Whether the rest (and so the loaded contacts) depends on the load: a heightmap."""
    return terrain.kind == "heightmap"


def _mass_com(robot: Robot, arm_com_body: ArrayLike | None, n: int) -> tuple[float, FloatArray]:
    if arm_com_body is None:  # the arm removed: the base alone
        return robot.base.mass, np.broadcast_to(np.asarray(robot.base.com, dtype=float), (n, 3))
    arm = np.broadcast_to(np.asarray(arm_com_body, dtype=float), (n, 3))
    return robot.total_mass, np.asarray(robot.overall_com(arm), dtype=float)


def _wrench_body(robot: Robot, q: ArrayLike | None, n: int) -> tuple[FloatArray, FloatArray] | None:
    """The tool's point in B (n, 3) [m] and wrench (n, 6) [N, N m], or None without one."""
    if robot.tool_wrench is None or q is None:
        return None
    qa = np.atleast_2d(np.asarray(q, dtype=float))
    tool = np.broadcast_to(robot.kinematics.link_frames(qa)[:, -1, :3, 3], (n, 3))
    wrench = np.broadcast_to(np.asarray(robot.tool_wrench, dtype=float), (n, 6))
    return tool, wrench


def state_load(
    robot: Robot, arm_com_body: ArrayLike | None, q: ArrayLike | None, n: int
) -> tuple[float, FloatArray, tuple[FloatArray, FloatArray] | None]:
    """N states' mass [kg], overall CoM in B (N, 3) [m] and tool wrench (or None).

    As :func:`loaded_support` takes them: ``arm_com_body`` None is the arm removed; the
    wrench (the tool's points (N, 3) [m], wrenches (N, 6) [N, N m]) needs ``q`` [rad].
    """
    mass, com_B = _mass_com(robot, arm_com_body, n)
    wrench = _wrench_body(robot, q, n) if arm_com_body is not None else None
    return mass, com_B, wrench


def loaded_support(
    robot: Robot,
    terrain: Terrain,
    poses: ArrayLike,
    arm_com_body: ArrayLike | None,
    q: ArrayLike | None = None,
    strict: bool = True,
) -> LoadedSupport:
    """μ of N states on the contacts that carry their load (the one μ mmstab reports).

    Args:
        robot: the robot (payload attached).
        terrain: the ground.
        poses: base poses (3,) or (N, 3) of (x, y, yaw) in the map frame M [m, m, rad].
        arm_com_body: arm CoM in B per state (N, 3) or (3,) [m]; ``None``: the arm removed.
        q: the arm postures (N, n) [rad], needed only for a tool wrench
            (``Robot.tool_wrench``): the wrench acts at the postures' tool points.
        strict: raise for a pose whose ground is off the map or unknown; otherwise its μ
            is NaN (heightmaps only).

    Returns:
        :class:`LoadedSupport`.
    """
    P = as_poses(poses)
    n = len(P)
    mass, com_B, wrench = state_load(robot, arm_com_body, q, n)
    false = np.zeros(n, dtype=bool)
    if not is_heightmap(terrain):
        g = np.asarray(terrain.gravity_body(P), dtype=float)
        force = mass * g
        if wrench is None:
            mu = force_angle_batch(base_polygon(robot).vertices, com_B, force).mu
        else:
            tool, w = wrench
            moment = np.cross(tool - com_B, w[:, :3]) + w[:, 3:]
            mu = dynamic_force_angle(
                base_polygon(robot).vertices, com_B, force + w[:, :3], moment
            ).mu
        return LoadedSupport(np.asarray(mu, dtype=float), g, false, false, false, ~false)
    ground = terrain
    if getattr(terrain, "robot", None) is not robot:
        ground = terrain.with_robot(robot, getattr(terrain, "flipper_angle", None))
    known = np.isfinite(com_B).all(axis=1)  # a posture not found (NaN) has no state
    rests = ground.rest(P[known], strict=strict, com_body=com_B[known])  # type: ignore[attr-defined]
    index = np.full(n, -1)
    index[known] = np.arange(int(known.sum()))
    return support_on_rests(ground, rests, index, mass, com_B, wrench)


def support_on_rests(
    ground: Terrain,
    rests: RestPoses,
    index: NDArray[np.intp],
    mass: float,
    com_body: FloatArray,
    wrench: tuple[FloatArray, FloatArray] | None = None,
) -> LoadedSupport:
    """:func:`loaded_support` of N states on a heightmap from their rests, made elsewhere.

    A caller that rests other poses on the same map rests the states in the same batch
    (each pose's rest is its own: the rows are those of a rest alone) and gives them here.

    Args:
        ground: the heightmap bound to the robot (its contact candidates).
        rests: the rests, each state's under its own overall CoM (``com_body``).
        index: each state's row in ``rests`` (N,) (-1: no state, μ NaN).
        mass: the states' mass [kg] (:func:`state_load`).
        com_body: the states' overall CoM in B (N, 3) [m] (:func:`state_load`).
        wrench: the tool's points in B (N, 3) [m] and wrenches (N, 6) [N, N m], or None
            (:func:`state_load`).
    """
    n = len(index)
    known = index >= 0
    points = ground.candidates.points  # type: ignore[attr-defined]
    G_T_B = np.full((n, 4, 4), np.nan)
    G_T_B[known] = rests.G_T_B[index[known]]
    gravity = np.einsum("nji,j->ni", G_T_B[:, :3, :3], GRAVITY_G)
    mu = np.full(n, np.nan)
    line = np.zeros(n, dtype=bool)
    tips, high, settled = (np.zeros(n, dtype=bool) for _ in range(3))
    at = index[known]
    tips[known], high[known], settled[known] = (
        rests.tips_over[at],
        rests.high_centred[at],
        rests.converged[at],
    )
    line[known] = rests.line_contact[at]
    rows = np.flatnonzero(known & np.isfinite(G_T_B[:, 2, 3]))
    force_G = mass * GRAVITY_G
    # μ from the polygon alone (gravity, or a line): the C kernel, state by state
    plain = rows[(wrench is None) | line[rows]]
    kernel = support_mu_c(points, rests.bearing[index[plain]], G_T_B[plain], com_body[plain],
                          force_G) if len(plain) else None  # fmt: skip
    if kernel is not None:
        mu[plain[kernel[1]]] = kernel[0][kernel[1]]
        rows = np.setdiff1d(rows, plain[kernel[1]], assume_unique=True)
    R, t = G_T_B[rows, :3, :3], G_T_B[rows, :3, 3]  # the per-state code's products, stacked
    coms_G = (R @ com_body[rows][..., None])[..., 0] + t
    bearing = rests.bearing[index[rows]]  # each state's bearing candidates, first
    m = bearing.sum(axis=1)
    order = np.argsort(~bearing, axis=1, kind="stable")[:, : int(m.max(initial=0))]
    body = np.asarray(points, dtype=float)[order]
    hulls = hulls_along_batch(
        body @ np.swapaxes(R, 1, 2) + t[:, None, :],
        np.arange(order.shape[1])[None, :] < m[:, None],
        force_G,
    )
    # a polygon found at once and a plain gravity load (or a line): μ for all of them
    fast = hulls.ok & ((wrench is None) | line[rows])
    theta = padded_axis_angles(hulls.vertices[fast], hulls.n_vertices[fast], coms_G[fast], force_G)
    mu[rows[fast]] = np.min(theta, axis=1) * np.linalg.norm(force_G)
    for r in np.flatnonzero(~fast):  # per state: the batch's polygon where it has one
        i = int(rows[r])
        j = int(index[i])
        T = G_T_B[i]
        com_G = T[:3, :3] @ com_body[i] + T[:3, 3]
        if hulls.ok[r]:
            poly, on_line = hulls.vertices[r, : hulls.n_vertices[r]], False
        else:
            poly, on_line = support_vertices(rests.bearing_G(points, j), force_G)
        line[i] |= on_line
        if len(poly) == 0:
            continue
        if len(poly) == 1:
            mu[i] = 0.0
            continue
        if wrench is None or line[i]:
            theta = axis_angles(poly, com_G, force_G)
            mu[i] = float(np.min(theta) * np.linalg.norm(force_G))
            continue
        tool, w = wrench
        f_G, n_G = T[:3, :3] @ w[i, :3], T[:3, :3] @ w[i, 3:]
        tool_G = T[:3, :3] @ tool[i] + T[:3, 3]
        moment = np.cross(tool_G - com_G, f_G) + n_G
        mu[i] = float(
            dynamic_force_angle(poly, com_G[None], (force_G + f_G)[None], moment[None]).mu[0]
        )
    return LoadedSupport(mu, gravity, line, tips, high, settled)


def loaded_mu(
    robot: Robot,
    terrain: Terrain,
    poses: ArrayLike,
    arm_com_body: ArrayLike | None,
    q: ArrayLike | None = None,
    strict: bool = True,
) -> FloatArray:
    """The μ [N rad] (N,) of :func:`loaded_support`."""
    return loaded_support(robot, terrain, poses, arm_com_body, q, strict).mu


def posture_mu(robot: Robot, terrain: Terrain, poses: ArrayLike, q: ArrayLike) -> FloatArray:
    """μ [N rad] (N,) of the robot at base poses (N, 3) with arm postures ``q`` (N, n) [rad].

    The postures' arm CoMs, and their tool wrench when the robot has one.
    """
    qa = np.atleast_2d(np.asarray(q, dtype=float))
    return loaded_mu(robot, terrain, poses, np.atleast_2d(robot.arm_com(qa)), qa)


# ------------------------------------------------------------- the three cases along a run
class StabilityCases(NamedTuple):
    """Force-angle μ [N rad] along a sequence of base poses, per sample (N,).

    Attributes:
        reconfigured: with the arm as it is (moved, planned or swept).
        arm_removed: the base alone.
        stowed: with the arm held stowed on the same base poses.
    """

    reconfigured: FloatArray
    arm_removed: FloatArray
    stowed: FloatArray


def stability_along(
    robot: Robot, terrain: Terrain, poses: ArrayLike, arm_com_body: ArrayLike
) -> StabilityCases:
    """μ along base poses: with the given arm CoMs, with the arm removed, with it stowed.

    The one place the planned/reconfigured, stowed and arm-removed cases are computed (the
    tracking run, the plan's summary and the sweeps use it), each on its own loaded
    support (:func:`loaded_support`).

    Args:
        robot: the robot.
        terrain: the ground.
        poses: base poses (N, 3) in the map frame M [m, m, rad].
        arm_com_body: arm CoM in the body frame per pose (N, 3) or (3,) [m].
    """
    P = as_poses(poses)
    stowed = robot.arm_com(robot.stowed)
    return StabilityCases(
        reconfigured=loaded_mu(robot, terrain, P, arm_com_body),
        arm_removed=loaded_mu(robot, terrain, P, None),
        stowed=loaded_mu(robot, terrain, P, stowed),
    )
