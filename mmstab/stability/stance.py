"""How the robot stands at a base pose on any terrain, with its stability; stability maps.

:func:`stance` is what ``mmstab rest`` prints: roll, pitch, height, the resting pose,
the touching contacts and the support polygon in G, the force-angle measure mu of the
overall CoM under gravity (``m_T g``) on it, the slip limit (:mod:`mmstab.stability.slip`:
the support's tilt against ``atan(terrain.friction)``), which of the two binds, and the
operator flags. The polygon is the hull
of the contacts that carry load: the touching ones and, on a heightmap, the tracks' bottom
run within the compliance of the ground (:class:`mmstab.terrain.rest.RestSettings`). On
the ramp the pose is the ramp's ``(x, y, heading)`` in S; on a heightmap ``(x, y, yaw)``
in G.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.robot import Robot
from mmstab.stability.slip import slip_limit, terrain_friction
from mmstab.stability.static import contact_force_angle
from mmstab.terrain.base import GRAVITY_G, Terrain, roll_pitch
from mmstab.terrain.heightmap import FloatArray
from mmstab.terrain.heightmap_terrain import HeightmapTerrain, with_flipper_angle


class Stance(NamedTuple):
    """The robot at rest at one base pose (``mmstab rest``).

    Attributes:
        roll: [rad], positive lifts the left side.
        pitch: [rad], positive lifts the nose.
        z: G height of the body origin [m].
        G_T_B: resting pose (4, 4).
        contacts: touching contact points in G (n, 3) [m].
        support_polygon: ordered polygon vertices in G (m, 3) [m]: the hull of the contacts
            that carry load.
        mu: force-angle measure on it [N rad] (> 0: statically stable).
        flags: operator flags (``high_centred``, ``line_contact``, ``tips_over``,
            ``slides``, ...).
        tilt: angle between gravity and -z_B at the resting pose [rad].
        friction: the terrain's friction coefficient [-].
        slip_margin: ``atan(friction) - tilt`` [rad] (> 0: the tracks hold).
        binding: the limit crossed (``tip``, ``slip``, ``both``) or, when none is, ``none``.
    """

    roll: float
    pitch: float
    z: float
    G_T_B: FloatArray
    contacts: FloatArray
    support_polygon: FloatArray
    mu: float
    flags: tuple[str, ...]
    tilt: float
    friction: float
    slip_margin: float
    binding: str

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
            "tilt": self.tilt,
            "friction": self.friction,
            "slip_margin": self.slip_margin,
            "binding": self.binding,
        }


def stance(
    terrain: Terrain,
    robot: Robot,
    pose: ArrayLike,
    flipper_angle: float | None = None,
    arm_q: ArrayLike | None = None,
) -> Stance:
    """The stance on any terrain (pose in the terrain's map frame).

    Args:
        terrain: the ground.
        robot: the robot.
        pose: base pose (x [m], y [m], yaw [rad]) in the map frame.
        flipper_angle: flipper angle [rad] (``None``: the robot's).
        arm_q: arm posture (4,) [rad] (``None``: stowed).

    Raises:
        MmstabError: a load the ground cannot take (flippers into a plane), a pose off the map.
    """
    r = with_flipper_angle(robot, flipper_angle)
    q = r.stowed if arm_q is None else np.asarray(arm_q, dtype=float)
    ground = terrain.with_robot(r, None, q)
    stand = ground.support(r, pose)
    T = stand.G_T_B
    com_G = T[:3, :3] @ np.asarray(r.overall_com(r.arm_com(q)), dtype=float) + T[:3, 3]
    poly, mu, line = contact_force_angle(stand.bearing(), com_G, r.total_mass * GRAVITY_G)
    roll, pitch = roll_pitch(ground, np.asarray(pose, dtype=float))
    flags = stand.flags
    if line and "line_contact" not in flags:
        flags = (*flags, "line_contact")
    slip = slip_limit(T[:3, :3].T @ GRAVITY_G, terrain_friction(terrain))
    slides = bool(slip.slides[0])
    if slides:
        flags = (*flags, "slides")
    tips = not mu > 0 or "tips_over" in flags
    binding = {(False, False): "none", (True, False): "tip", (False, True): "slip"}.get(
        (tips, slides), "both"
    )
    return Stance(
        roll, pitch, float(T[2, 3]), T, stand.contacts_G, poly, mu, flags,
        float(slip.tilt[0]), slip.friction, float(slip.margin[0]), binding,
    )  # fmt: skip


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
        bearing = r.bearing_G(c, int(i))
        _, mu[i], line = contact_force_angle(bearing, T[:3, :3] @ com + T[:3, 3], mass * GRAVITY_G)
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
