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
from mmstab.stability.support import loaded_support
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
        """The stance's keys of ``mmstab rest --json`` (the command adds the inputs, with units)."""
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
    robot: Robot | Terrain,
    terrain: Terrain | Robot,
    pose: ArrayLike,
    flipper_angle: float | None = None,
    arm_q: ArrayLike | None = None,
    *,
    arm: ArrayLike | None = None,
) -> Stance:
    """The robot at rest at one pose on any terrain, its μ, tilt and flags.

    ``stance(robot, terrain, pose, arm=q)``; the older order ``stance(terrain, robot, pose,
    flipper_angle, arm_q)`` gives the same.

    Args:
        robot: the robot.
        terrain: the ground.
        pose: base pose (x [m], y [m], yaw [rad]) in the terrain's map frame.
        flipper_angle: flipper angle [rad] (``None``: the robot's).
        arm_q: the older name of ``arm``.
        arm: arm posture (``robot.arm_joints``,) [rad]; ``None``: the robot's stowed
            posture (``robot.stowed``).

    Raises:
        MmstabError: a load the ground cannot take (flippers into a plane), a pose off the map.
        ValueError: ``arm`` and ``arm_q`` both given, or a posture of another shape.
    """
    if not isinstance(robot, Robot):  # the older order: (terrain, robot, ...)
        robot, terrain = terrain, robot
    if not isinstance(robot, Robot) or isinstance(terrain, Robot):
        raise TypeError("stance(robot, terrain, pose): give one robot and one terrain")
    if arm is not None and arm_q is not None:
        raise ValueError("stance: give the posture once (arm=...)")
    arm_q = arm if arm is not None else arm_q
    if arm_q is not None and np.shape(arm_q) != (robot.arm_joints,):
        raise ValueError(
            f"stance: arm must have shape ({robot.arm_joints},) [rad], got {np.shape(arm_q)}"
        )
    r = with_flipper_angle(robot, flipper_angle)
    q = r.stowed if arm_q is None else np.asarray(arm_q, dtype=float)
    ground = terrain.with_robot(r, None, q)
    stand = ground.support(r, pose)
    T = stand.G_T_B
    com_G = T[:3, :3] @ np.asarray(r.overall_com(r.arm_com(q)), dtype=float) + T[:3, 3]
    poly, _, line = contact_force_angle(stand.bearing(), com_G, r.total_mass * GRAVITY_G)
    # the one μ (plan, track, map, online loop): the loaded support of this state
    loaded = loaded_support(r, ground, np.asarray(pose, dtype=float), r.arm_com(q), q[None])
    mu = float(loaded.mu[0])
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
    """mu and the slip margin of the robot over a grid of positions x headings.

    Attributes:
        x: (nx,) G x of the grid columns [m].
        y: (ny,) G y of the grid rows [m].
        headings: (nh,) yaws [rad].
        mu: (ny, nx, nh) [N rad]; NaN off the map / on unknown cells, or where the rest
            did not converge (flag 8).
        flags: (ny, nx, nh) bit set: 1 high-centred, 2 line contact, 4 tips over,
            8 not converged (mu left NaN), 16 slides (the support's tilt is beyond
            ``atan(friction)``).
        worst: (ny, nx) min over headings [N rad]; best: (ny, nx) max over headings.
        worst_heading: (ny, nx) [rad]; best_heading: (ny, nx) [rad].
        seconds_rest: wall time of the batched resting poses [s].
        slip_margin: (ny, nx, nh) ``atan(friction) - tilt`` [rad] (> 0: the tracks hold);
            NaN where mu is.
        worst_slip_margin: (ny, nx) min over headings [rad].
        friction: the terrain's friction coefficient [-].
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
    slip_margin: FloatArray
    worst_slip_margin: FloatArray
    friction: float

    def holds(self) -> np.ndarray:
        """(ny, nx, nh) neither tips (mu > 0) nor slides; False where unknown."""
        with np.errstate(invalid="ignore"):
            return (self.mu > 0) & (self.slip_margin >= 0)


def stability_map(
    terrain: HeightmapTerrain, spacing: float, n_headings: int, margin: float | None = None
) -> StabilityMap:
    """Force-angle mu and the slip margin of the bound robot at rest on a grid.

    Every ``spacing`` [m] x ``n_headings`` yaws, mmstab's one μ of each state (the arm at
    the terrain's bound posture; :func:`mmstab.stability.support.loaded_support`) and the
    friction cone of its support (:func:`mmstab.stability.slip.slip_limit`).

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
    robot = terrain._robot()
    q = robot.stowed if terrain.arm_q is None else terrain.arm_q
    t0 = time.perf_counter()
    r = loaded_support(robot, terrain, poses, robot.arm_com(q), q[None], strict=False)
    seconds = time.perf_counter() - t0
    rested = np.isfinite(r.gravity_body).all(axis=1)
    unsettled = ~r.converged & ~r.tips_over & rested
    mu = np.where(unsettled, np.nan, r.mu)
    slip = slip_limit(np.nan_to_num(r.gravity_body), terrain_friction(terrain))
    known = rested & ~unsettled
    slip_margin = np.where(known, slip.margin, np.nan)
    flags = (1 * r.high_centred + 2 * r.line + 4 * r.tips_over + 16 * (known & slip.slides)).astype(
        np.int_
    )
    flags = np.where(known, flags, 0)
    flags[unsettled] = 8
    shape = (xs.size, ys.size, n_headings)

    def grid(values: np.ndarray) -> np.ndarray:
        return np.transpose(values.reshape(shape), (1, 0, 2))

    mu3, fl3, slip3 = grid(mu), grid(flags), grid(slip_margin)
    known3 = np.isfinite(mu3).all(axis=2)
    filled = np.where(np.isfinite(mu3), mu3, 0.0)
    worst = np.where(known3, mu3.min(axis=2, initial=np.inf, where=np.isfinite(mu3)), np.nan)
    best = np.where(known3, mu3.max(axis=2, initial=-np.inf, where=np.isfinite(mu3)), np.nan)
    worst_h = np.where(known3, hs[np.argmin(np.where(np.isfinite(mu3), filled, np.inf), 2)], np.nan)
    best_h = np.where(known3, hs[np.argmax(np.where(np.isfinite(mu3), filled, -np.inf), 2)], np.nan)
    worst_slip = np.where(
        known3, slip3.min(axis=2, initial=np.inf, where=np.isfinite(slip3)), np.nan
    )
    return StabilityMap(
        xs, ys, hs, mu3, fl3, worst, best, worst_h, best_h, seconds, slip3, worst_slip,
        slip.friction,
    )  # fmt: skip
