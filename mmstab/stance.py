"""How the robot stands at a base pose on any terrain, with its stability; stability maps.

:func:`stance` is what ``mmstab rest`` prints: roll, pitch, height, the resting pose,
the touching contacts and their support polygon in G, the force-angle measure mu of the
overall CoM under gravity (``m_T g``) and the operator flags. On the ramp the pose is the
ramp's ``(x, y, heading)`` in S; on a heightmap ``(x, y, yaw)`` in G.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.config import MmstabError
from mmstab.robot import FLIPPER_CONTACT_TOL, Robot
from mmstab.stability import contact_force_angle
from mmstab.terrain.base import GRAVITY_G
from mmstab.terrain.heightmap import FloatArray
from mmstab.terrain.heightmap_terrain import HeightmapTerrain, with_flipper_angle
from mmstab.terrain.ramp import Ramp


class Stance(NamedTuple):
    """The robot at rest at one base pose (``mmstab rest``).

    Attributes:
        roll: [rad], positive lifts the left side.
        pitch: [rad], positive lifts the nose.
        z: G height of the body origin [m].
        G_T_B: resting pose (4, 4).
        contacts: touching contact points in G (n, 3) [m].
        support_polygon: ordered polygon vertices in G (m, 3) [m].
        mu: force-angle measure [N rad] (> 0: statically stable).
        flags: operator flags (``high_centred``, ``line_contact``, ``tips_over``, ...).
    """

    roll: float
    pitch: float
    z: float
    G_T_B: FloatArray
    contacts: FloatArray
    support_polygon: FloatArray
    mu: float
    flags: tuple[str, ...]

    def to_json(self) -> dict[str, Any]:
        """Exactly the keys of ``mmstab rest --json``."""
        return {
            "roll": self.roll,
            "pitch": self.pitch,
            "z": self.z,
            "G_T_B": self.G_T_B.tolist(),
            "contacts": self.contacts.tolist(),
            "support_polygon": self.support_polygon.tolist(),
            "mu": self.mu,
            "flags": list(self.flags),
        }


def _overall_com(robot: Robot, arm_q: ArrayLike | None) -> FloatArray:
    q = robot.stowed if arm_q is None else np.asarray(arm_q, dtype=float)
    return np.asarray(robot.overall_com(robot.arm_com(q)), dtype=float)


def ramp_stance(
    ramp: Ramp,
    robot: Robot,
    pose: ArrayLike,
    flipper_angle: float | None = None,
    arm_q: ArrayLike | None = None,
) -> Stance:
    """The stance on the ramp: the body on the plane, contacts = the base's support points.

    Raises:
        MmstabError: the flipper angle puts the flippers into the plane.
    """
    r = with_flipper_angle(robot, flipper_angle)
    lowest = min(r.base.flippers.box(s).corners()[:, 2].min() for s in ("left", "right"))
    if lowest < -FLIPPER_CONTACT_TOL:
        raise MmstabError(
            f"--flipper {flipper_angle}: the flippers reach {-lowest:.3f} m into the ramp; "
            "raise them"
        )
    T = ramp.G_T_B(pose)
    contacts = r.base.support_points() @ T[:3, :3].T + T[:3, 3]
    com_G = T[:3, :3] @ _overall_com(r, arm_q) + T[:3, 3]
    poly, mu, line = contact_force_angle(contacts, com_G, r.total_mass * GRAVITY_G)
    roll, pitch = ramp.roll_pitch(float(np.asarray(pose, dtype=float)[2]))
    flags = ("line_contact",) if line else ()
    return Stance(roll, pitch, float(T[2, 3]), T, contacts, poly, mu, flags)


def heightmap_stance(
    terrain: HeightmapTerrain,
    robot: Robot,
    pose: ArrayLike,
    flipper_angle: float | None = None,
    arm_q: ArrayLike | None = None,
) -> Stance:
    """The stance on a heightmap (resting pose of :mod:`mmstab.terrain.rest`).

    Raises:
        OffMapError: the pose needs ground off the map or on unknown cells.
    """
    t = terrain.with_robot(robot, flipper_angle, arm_q)
    r = t.rest(np.asarray(pose, dtype=float))
    T = r.G_T_B[0]
    contacts = r.contacts_G(t.candidates.points, 0)
    com_G = T[:3, :3] @ t.com_body + T[:3, 3]
    poly, mu, line = contact_force_angle(contacts, com_G, robot.total_mass * GRAVITY_G)
    flags = r.flags(0)
    if line and "line_contact" not in flags:
        flags = (*flags, "line_contact")
    return Stance(float(r.roll[0]), float(r.pitch[0]), float(r.z[0]), T, contacts, poly, mu, flags)


def stance(
    terrain: Ramp | HeightmapTerrain,
    robot: Robot,
    pose: ArrayLike,
    flipper_angle: float | None = None,
    arm_q: ArrayLike | None = None,
) -> Stance:
    """The stance on any terrain (pose in the terrain's map frame)."""
    if isinstance(terrain, Ramp):
        return ramp_stance(terrain, robot, pose, flipper_angle, arm_q)
    return heightmap_stance(terrain, robot, pose, flipper_angle, arm_q)


# ------------------------------------------------------------------------ stability maps
class StabilityMap(NamedTuple):
    """mu of the robot over a grid of positions x headings.

    Attributes:
        x: (nx,) G x of the grid columns [m].
        y: (ny,) G y of the grid rows [m].
        headings: (nh,) yaws [rad].
        mu: (ny, nx, nh) [N rad]; NaN off the map / on unknown cells, or where the rest
            did not converge (flag 8).
        flags: (ny, nx, nh) bit set: 1 high-centred, 2 line contact, 4 tips over,
            8 not converged (mu left NaN).
        worst: (ny, nx) min over headings [N rad]; best: (ny, nx) max over headings.
        worst_heading: (ny, nx) [rad]; best_heading: (ny, nx) [rad].
        seconds_rest: wall time of the batched resting poses [s].
    """

    x: FloatArray
    y: FloatArray
    headings: FloatArray
    mu: FloatArray
    flags: np.ndarray
    worst: FloatArray
    best: FloatArray
    worst_heading: FloatArray
    best_heading: FloatArray
    seconds_rest: float


def stability_map(
    terrain: HeightmapTerrain, spacing: float, n_headings: int, margin: float | None = None
) -> StabilityMap:
    """Force-angle mu of the bound robot at rest, every ``spacing`` [m] x ``n_headings`` yaws.

    Args:
        terrain: a heightmap terrain bound to a robot (arm posture as bound).
        spacing: grid spacing [m].
        n_headings: headings evenly over a full turn.
        margin: keep this far inside the map edge [m] (``None``: the robot's reach).
    """
    import time

    hm = terrain.heightmap
    c = terrain.candidates.points
    # any rotation keeps the candidates within their 3-D reach of the body origin
    reach = float(np.max(np.linalg.norm(c, axis=1))) if margin is None else margin
    x0, x1, y0, y1 = hm.bounds
    xs = np.arange(x0 + reach, x1 - reach + 1e-9, spacing)
    ys = np.arange(y0 + reach, y1 - reach + 1e-9, spacing)
    if xs.size == 0 or ys.size == 0:
        raise MmstabError(f"{hm.source}: the map is smaller than the robot (reach {reach:.2f} m)")
    hs = 2 * np.pi * np.arange(n_headings) / n_headings
    X, Y, H = np.meshgrid(xs, ys, hs, indexing="ij")
    poses = np.stack([X.ravel(), Y.ravel(), H.ravel()], axis=1)
    t0 = time.perf_counter()
    r = terrain.rest(poses, strict=False)
    seconds = time.perf_counter() - t0
    mu = np.full(len(poses), np.nan)
    flags = np.zeros(len(poses), dtype=np.int_)
    com = terrain.com_body
    mass = terrain._robot().total_mass
    unsettled = ~r.converged & ~r.tips_over & np.isfinite(r.z)
    flags[unsettled] = 8
    for i in np.flatnonzero(np.isfinite(r.z) & ~unsettled):
        T = r.G_T_B[i]
        contacts = r.contacts_G(c, int(i))
        _, mu[i], line = contact_force_angle(contacts, T[:3, :3] @ com + T[:3, 3], mass * GRAVITY_G)
        flags[i] = (
            1 * bool(r.high_centred[i])
            + 2 * (line or bool(r.line_contact[i]))
            + 4 * bool(r.tips_over[i])
        )
    shape = (xs.size, ys.size, n_headings)
    mu3 = np.transpose(mu.reshape(shape), (1, 0, 2))
    fl3 = np.transpose(flags.reshape(shape), (1, 0, 2))
    known = np.isfinite(mu3).all(axis=2)
    filled = np.where(np.isfinite(mu3), mu3, 0.0)
    worst = np.where(known, mu3.min(axis=2, initial=np.inf, where=np.isfinite(mu3)), np.nan)
    best = np.where(known, mu3.max(axis=2, initial=-np.inf, where=np.isfinite(mu3)), np.nan)
    worst_h = np.where(known, hs[np.argmin(np.where(np.isfinite(mu3), filled, np.inf), 2)], np.nan)
    best_h = np.where(known, hs[np.argmax(np.where(np.isfinite(mu3), filled, -np.inf), 2)], np.nan)
    return StabilityMap(xs, ys, hs, mu3, fl3, worst, best, worst_h, best_h, seconds)
