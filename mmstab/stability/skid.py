"""Skid-steering on a slope: the twist the tracks actually give, and the slide a turn costs.

A tracked base turns by skidding: the belts' contact with the ground slides sideways at the
ends of the track while the body yaws. With Coulomb friction (coefficient μ, isotropic) every
sliding contact point pushes on the robot with ``μ n`` against its slip velocity, whatever
the speed, so a turn mobilises the whole friction budget of the tracks. On a slope that budget
also has to hold gravity's in-plane part: the centre of rotation shifts along the tracks until
the sliding contacts' net force balances it, and the body slides downhill while it turns. For
uniform pressure and gravity across the tracks the slide is ``(L / 2) tan(α) / μ`` per radian
of heading change (L: the tracks' contact length, α: the side slope); a pivot with the nose up
the slope does not hold the slope at all (the belts pull in opposite directions).

:func:`skid_twist` solves the steady state of that model: given the belts' surface speeds
(u_l, u_r) [m/s], gravity in B and the overall CoM in B, the body's twist (v_x, v_y, ω) in B
for which the sliding contacts' forces and yaw moment balance gravity's in-plane force and
its yaw moment about B's origin. The normal loads along the two belts are the rigid-plate
distribution (linear in x and y, the centre of pressure where the gravity line through the
CoM meets the support plane, negative loads dropped). Coulomb friction is regularised as
``μ n s / sqrt(|s|² + ε²)`` with ε = 10⁻⁴ of the belt speed, solved by Newton's method with
a continuation in ε. The model is homogeneous: the twist scales with the belt speeds.

Assumptions: quasi-static (no inertia: a steady turn at low speed), rigid planar support,
belts as line contacts at ``y = ±separation / 2`` over ``x ∈ [−L/2, L/2]``, isotropic
Coulomb friction, the arm still. Checked against the whole robot in MuJoCo in
``tests/physics/test_physics_skid.py`` (docs/skid.md).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.core.clib import BYTES, DOUBLE, DOUBLES, LONG, LONGS, optional_kernel
from mmstab.model.robot import FloatArray, Robot
from mmstab.stability.slip import slip_limit

#: contact samples per belt: 1.75 cm apart on the Cameleon's 0.7 m tracks
BELT_SAMPLES = 40
_EPS = (1e-1, 1e-2, 1e-3, 1e-4)  # continuation of the regularisation, relative to the belt speed
_TOL = 1e-9
_ITERATIONS, _BACKTRACKS = 60, 8  # Newton's steps per regularisation; halvings of a step
_CONVERGED = 1e-6  # the residual a twist must reach at the last regularisation
#: The Newton loop's C source (:func:`skid_twist`'s default; NumPy's loop without a compiler)
KERNEL_SOURCE = Path(__file__).with_name("skid.c")
#: the slide per radian divides by the model's yaw rate but at least this share of the path's:
#: up a grade with the load on the inner belt the rigid Coulomb model stops turning where
#: MuJoCo's sprung wheels still turn (a 1.5 m arc up 5.7°: 0.05 against 0.17 rad/s), and a
#: controller raises the belts' differential until the heading turns (flat: 0.52-0.62)
TURN_FLOOR = 0.5


class TrackPatch(NamedTuple):
    """The belts' contact with the ground, sampled (left belt first, then right).

    Attributes:
        x: sample positions along x_B (2K,) [m].
        y: lateral positions, +separation/2 left, −separation/2 right (2K,) [m].
        side: 0 for the left belt, 1 for the right (2K,).
        length: contact length L [m].
        separation: distance between the belts' centre lines b [m].
    """

    x: FloatArray
    y: FloatArray
    side: np.ndarray
    length: float
    separation: float


class SkidTwist(NamedTuple):
    """The steady twist of the skid-steered base (N samples).

    Attributes:
        velocity_body: (N, 2) velocity of B's origin along x_B, y_B [m/s].
        yaw_rate: (N,) [rad/s].
        holds: (N,) a steady twist exists (False: gravity's in-plane part exceeds the friction
            cone, the robot slides whatever the belts do; or the centre of pressure lies
            outside the belts, the robot tips). The twist is NaN where it does not
            hold (and where Newton's method did not converge to 10⁻⁶ of the weight).
        commanded: (N, 3) the kinematic twist the belts command (v, 0, (u_r − u_l)/b) [m/s, rad/s].
    """

    velocity_body: FloatArray
    yaw_rate: FloatArray
    holds: np.ndarray
    commanded: FloatArray


def track_patch(robot: Robot, samples: int = BELT_SAMPLES) -> TrackPatch:
    """The robot's belts sampled at ``samples`` midpoints each [-]."""
    t = robot.base.tracks
    x = (np.arange(samples) + 0.5) / samples * t.length - t.length / 2
    y = np.repeat([t.separation / 2, -t.separation / 2], samples)
    return TrackPatch(np.tile(x, 2), y, np.repeat([0, 1], samples), t.length, t.separation)


def centre_of_pressure(gravity_body: ArrayLike, com_body: ArrayLike) -> FloatArray:
    """Where the gravity line through the CoM meets the support plane z_B = 0 (N, 2) [m].

    Args:
        gravity_body: gravity in B (N, 3) [m/s^2].
        com_body: the overall CoM in B (N, 3) or (3,) [m].
    """
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    c = np.broadcast_to(np.asarray(com_body, dtype=float), g.shape)
    return np.asarray(c[:, :2] - c[:, 2:3] * g[:, :2] / g[:, 2:3])


def normal_loads(patch: TrackPatch, gravity_body: ArrayLike, com_body: ArrayLike) -> FloatArray:
    """Rigid-plate normal loads per unit weight at the samples (N, 2K) [-] (sum = cos tilt).

    Linear in (x, y) with the centre of pressure where the gravity line through the CoM
    meets z_B = 0; samples with a negative load are dropped and the rest refitted.

    Args:
        patch: the belts' samples.
        gravity_body: gravity in B (N, 3) [m/s^2].
        com_body: the overall CoM in B (N, 3) [m].
    """
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    g = g / np.linalg.norm(g, axis=1, keepdims=True)
    cop = centre_of_pressure(g, com_body)
    total = -g[:, 2]
    basis = np.stack([np.ones_like(patch.x), patch.x, patch.y])  # (3, 2K)
    active = np.ones((len(g), len(patch.x)))
    for _ in range(len(patch.x)):
        A = np.einsum("ik,nk,jk->nij", basis, active, basis)
        rhs = total[:, None] * np.c_[np.ones(len(g)), cop]
        # one belt left (the CoP on or past its line): y is not determined, fit 1 and x only
        one = (active[:, patch.side == 0].sum(1) == 0) | (active[:, patch.side == 1].sum(1) == 0)
        A[one, 2, :], A[one, :, 2], A[one, 2, 2], rhs[one, 2] = 0.0, 0.0, 1.0, 0.0
        coef = (np.linalg.pinv(A) @ rhs[:, :, None])[:, :, 0]  # pinv: a lone sample left
        loads = active * (coef @ basis)
        keep = (loads > 0) | (active == 0)
        if keep.all():
            break
        active = active * (loads > 0)
    return np.maximum(loads, 0.0)


def contact_time(patch: TrackPatch, belts: FloatArray) -> FloatArray:
    """How long each sample's belt element has been on the ground (N, 2K) [s per belt-speed unit].

    A belt running backward under the body at ``u > 0`` lays its elements down at the front
    (x = L/2) and lifts them at the rear: an element at x has been down ``(L/2 - x) / u``;
    running forward (u < 0), ``(x + L/2) / |u|``; a standing belt (braked, or the inner belt
    of a pivot about it) forever (``inf``).

    Args:
        patch: the belts' samples.
        belts: (N, 2) belt surface speeds (left, right) [m/s] (any common scale).
    """
    u = belts[:, patch.side]
    half = patch.length / 2
    entered = np.where(u >= 0, half - patch.x, patch.x + half)
    with np.errstate(divide="ignore"):
        return np.where(np.abs(u) > 1e-9, entered / np.abs(u), np.inf)


def _forces(
    patch: TrackPatch,
    loads: FloatArray,
    belts: FloatArray,
    z: FloatArray,
    eps: float,
    tau: FloatArray | None = None,
    shear: float = 0.0,
) -> tuple[FloatArray, FloatArray]:
    """(friction forces and yaw moment (N, 3), their Jacobian (N, 3, 3)) per unit weight/μ.

    ``tau``: :func:`contact_time`, ``shear``: the shear modulus K [m] (0: Coulomb).
    """
    u = belts[:, patch.side]
    sx = z[:, :1] - z[:, 2:3] * patch.y - u
    sy = z[:, 1:2] + z[:, 2:3] * patch.x
    sigma = np.sqrt(sx**2 + sy**2 + eps**2)
    if shear > 0 and tau is not None:  # Wong-Chiang: phi = 1 - exp(-j / K), j = sigma tau
        finite = np.isfinite(tau)
        decay = np.exp(-sigma * np.where(finite, tau, 0.0) / shear)
        phi = np.where(finite, 1.0 - decay, 1.0)
        c = np.where(finite, np.where(finite, tau, 0.0) / shear * decay, 0.0)
    else:
        phi, c = np.ones_like(sigma), np.zeros_like(sigma)
    fx, fy = -loads * phi * sx / sigma, -loads * phi * sy / sigma
    F = np.stack([fx.sum(1), fy.sum(1), (patch.x * fy - patch.y * fx).sum(1) / patch.length], 1)
    # d f / d s = -n (phi (I / σ - s sᵀ / σ³) + c s sᵀ / σ²); d s / d z = [[1, 0, -y], [0, 1, x]]
    s3, s2 = sigma**3, sigma**2
    dxx = -loads * (phi * (1 / sigma - sx**2 / s3) + c * sx**2 / s2)
    dyy = -loads * (phi * (1 / sigma - sy**2 / s3) + c * sy**2 / s2)
    dxy = -loads * (-phi * sx * sy / s3 + c * sx * sy / s2)
    ds = (
        (np.ones_like(patch.x), np.zeros_like(patch.x), -patch.y),
        (np.zeros_like(patch.x), np.ones_like(patch.x), patch.x),
    )
    J = np.zeros((len(z), 3, 3))
    for j in range(3):
        dfx = dxx * ds[0][j] + dxy * ds[1][j]
        dfy = dxy * ds[0][j] + dyy * ds[1][j]
        J[:, 0, j], J[:, 1, j] = dfx.sum(1), dfy.sum(1)
        J[:, 2, j] = (patch.x * dfy - patch.y * dfx).sum(1) / patch.length
    return F, J


def skid_twist(
    patch: TrackPatch,
    gravity_body: ArrayLike,
    com_body: ArrayLike,
    belt_speeds: ArrayLike,
    friction: float,
    shear_modulus: float = 0.0,
    backend: Literal["c", "numpy"] = "c",
) -> SkidTwist:
    """The steady twist for belt speeds on a plane (module docstring).

    Args:
        patch: the belts' samples (:func:`track_patch`).
        gravity_body: gravity in B (N, 3) or (3,) [m/s^2].
        com_body: the overall CoM in B (N, 3) or (3,) [m].
        belt_speeds: (N, 2) or (2,) belt surface speeds (left, right) [m/s], positive driving
            forward.
        friction: Coulomb coefficient of belts on ground [-] (> 0).
        shear_modulus: Wong-Chiang's shear deformation modulus K [m] (0: rigid Coulomb).
        backend: ``c``: Newton's loop in C (``skid.c``, row by row; NumPy's without a C
            compiler); ``numpy``: here, all rows at once (the twins agree to round-off).
    """
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    belts = np.atleast_2d(np.asarray(belt_speeds, dtype=float))
    n = max(len(g), len(belts))
    g, belts = np.broadcast_to(g, (n, 3)), np.broadcast_to(belts, (n, 2))
    com = np.broadcast_to(np.asarray(com_body, dtype=float), (n, 3))
    b = patch.separation
    commanded = np.c_[belts.mean(1), np.zeros(n), (belts[:, 1] - belts[:, 0]) / b]
    cop = centre_of_pressure(g, com)
    inside = (np.abs(cop[:, 0]) < patch.length / 2) & (np.abs(cop[:, 1]) < patch.separation / 2)
    holds = ~slip_limit(g, friction).slides & inside  # outside the belts: it tips
    scale = np.maximum(np.abs(belts).max(1), 1e-9)[:, None]
    unit = g / np.linalg.norm(g, axis=1, keepdims=True)
    loads = normal_loads(patch, g, com)
    # gravity's in-plane force and its yaw moment about B's origin, per unit weight / μ
    load = np.c_[unit[:, :2], (com[:, 0] * unit[:, 1] - com[:, 1] * unit[:, 0]) / patch.length]
    load = load / friction
    z = commanded * np.array([1.0, 1.0, 0.5]) / scale  # turns at about half the command
    u = belts / scale
    tau, K = contact_time(patch, u), float(shear_modulus)
    moving = np.abs(belts).max(1) > 1e-9
    solved = None
    if backend == "c":
        solved = _newton_c(patch, loads, u, z, load, tau, K, holds, moving)
    if solved is not None:
        z, converged = solved
    else:
        for eps in _EPS:
            for _ in range(_ITERATIONS):
                F, J = _forces(patch, loads, u, z, eps, tau, K)
                r = F + load
                if np.all(np.abs(r[holds]) < _TOL):
                    break
                step = np.linalg.solve(J + 1e-12 * np.eye(3), -r[:, :, None])[:, :, 0]
                z = z + _backtrack(patch, loads, u, z, step, load, eps, tau, K)[:, None] * step
        F = _forces(patch, loads, u, z, _EPS[-1], tau, K)[0]
        converged = np.all(np.abs(F + load) < _CONVERGED, 1)
    z = np.where(moving[:, None], z * scale, 0.0)
    z[~(holds & (converged | ~moving))] = np.nan
    return SkidTwist(z[:, :2], z[:, 2], holds, commanded)


@lru_cache(maxsize=1)
def _kernel() -> Any:
    """The compiled ``mmstab_skid_twist`` (``skid.c``), or None (no C compiler)."""
    return optional_kernel(KERNEL_SOURCE, "mmstab_skid_twist", [
        LONG, LONG, DOUBLES, DOUBLES, LONGS, DOUBLE, DOUBLES, DOUBLES, DOUBLES, DOUBLES,
        DOUBLES, BYTES, BYTES, DOUBLE, DOUBLES, LONG, DOUBLE, LONG, LONG, DOUBLE, BYTES,
    ])  # fmt: skip


def _newton_c(
    patch: TrackPatch,
    loads: FloatArray,
    u: FloatArray,
    z: FloatArray,
    load: FloatArray,
    tau: FloatArray,
    shear: float,
    holds: NDArray[np.bool_],
    moving: NDArray[np.bool_],
) -> tuple[FloatArray, NDArray[np.bool_]] | None:
    """:func:`skid_twist`'s Newton loop in C, row by row (None: no compiler)."""
    f = _kernel()
    if f is None:
        return None
    n, S = loads.shape
    c = np.ascontiguousarray
    out = c(z, dtype=float).copy()
    converged = np.zeros(n, dtype=np.uint8)
    f(n, S, c(patch.x, dtype=float), c(patch.y, dtype=float), c(patch.side, dtype=np.int64),
      float(patch.length), c(loads, dtype=float), c(u, dtype=float), out, c(load, dtype=float),
      c(tau, dtype=float), c(holds, dtype=np.uint8), c(moving, dtype=np.uint8), shear,
      np.asarray(_EPS, dtype=float), len(_EPS), _TOL, _ITERATIONS, _BACKTRACKS, _CONVERGED,
      converged)  # fmt: skip
    return out, converged.astype(bool)


def _backtrack(
    patch: TrackPatch,
    loads: FloatArray,
    u: FloatArray,
    z: FloatArray,
    step: FloatArray,
    load: FloatArray,
    eps: float,
    tau: FloatArray,
    shear: float,
) -> FloatArray:
    """Per-sample step lengths that reduce the residual (halving from 1, at most 8 times)."""
    r0 = np.sum((_forces(patch, loads, u, z, eps, tau, shear)[0] + load) ** 2, 1)
    alpha = np.ones(len(z))
    for _ in range(_BACKTRACKS):
        moved = z + alpha[:, None] * step
        r = np.sum((_forces(patch, loads, u, moved, eps, tau, shear)[0] + load) ** 2, 1)
        worse = r > r0
        if not worse.any():
            break
        alpha = np.where(worse, alpha / 2, alpha)
    return alpha


def point_velocity(
    velocity_body: ArrayLike, yaw_rate: ArrayLike, point_body: ArrayLike
) -> FloatArray:
    """The in-plane velocity of a body-fixed point, ``v + ω × p`` (N, 2) [m/s].

    Args:
        velocity_body: B's origin's velocity along x_B, y_B (N, 2) [m/s].
        yaw_rate: ω (N,) [rad/s].
        point_body: the point's x, y in B (N, 2) or (2,) [m].
    """
    v = np.atleast_2d(np.asarray(velocity_body, dtype=float))
    w = np.asarray(yaw_rate, dtype=float).reshape(-1, 1)
    p = np.broadcast_to(np.asarray(point_body, dtype=float), v.shape)
    return np.asarray(v + w * np.c_[-p[:, 1], p[:, 0]])


class TurnSlide(NamedTuple):
    """The downhill slide a path's motion costs, from :func:`skid_twist` (N samples).

    Attributes:
        rate: downhill velocity beyond the commanded one [m/s]: where the path turns, the
            model's slide per radian times the path's turn rate; on straight stretches the
            downhill creep (the belts' shear, zero for rigid Coulomb contacts inside the
            cone); ``inf`` where the friction cone does not hold.
        per_radian: downhill slide per radian of heading change [m/rad] (NaN on straight
            stretches).
        turn_ratio: the model's yaw rate over the path's [-] (NaN on straight stretches).
    """

    rate: FloatArray
    per_radian: FloatArray
    turn_ratio: FloatArray


def belts_for_twist(
    speed: ArrayLike, yaw_rate: ArrayLike, separation: float, turn_ratio: float = 1.0
) -> FloatArray:
    """Belts (left, right) ``v ∓ ω b / (2 η)`` [m/s] (:mod:`mmstab.stability.drive`).

    Args:
        speed: forward speed v [m/s].
        yaw_rate: yaw rate ω [rad/s].
        separation: the belts' centre-line distance b [m].
        turn_ratio: the drive's turn ratio η [-] (1: the kinematic belts).
    """
    v, w = np.asarray(speed, dtype=float), np.asarray(yaw_rate, dtype=float)
    half = w * separation / (2 * turn_ratio)
    return np.stack([v - half, v + half], axis=-1)


def turn_slide(
    patch: TrackPatch,
    gravity_body: ArrayLike,
    com_body: ArrayLike,
    speed: ArrayLike,
    yaw_rate: ArrayLike,
    friction: float,
    turn_ratio: float = 1.0,
    shear_modulus: float = 0.0,
) -> TurnSlide:
    """The slide a path costs on a slope (module docstring): its velocity beyond the command.

    The belts run at the drive layer's speeds for the path's twist, ``v ∓ ω b / (2 η)``
    (:func:`belts_for_twist`; η = 1: the kinematic ones); the model's velocity of the CoM's
    foot (the overall CoM projected along z_B on the support plane, :func:`point_velocity`)
    less the commanded one (v along x_B: a command that pivots about that point), projected
    on the downhill direction, is what MuJoCo's "slid" measures (the motion beyond the
    kinematic track model's, :func:`mmstab.physics.loop_checks.downhill_drift`): the slope's
    pull and the belts' creep; a level pivot moves that point 1.5 cm per radian (MuJoCo's
    1.8 cm with the arm stowed: it turns about a point a little ahead of it). Where
    the path turns its heading must turn as the path's does, so the slide per radian is
    that velocity over the model's yaw rate (at least :data:`TURN_FLOOR` times the path's:
    the tracks' turn deficit does not hide the slide) and the rate that times |ω|; at least
    the rigid Coulomb model's slope part per radian (its twist less the same belts' on level
    ground: where the level skid points uphill it does not hide the slope's pull, and the
    shear never prices a turn below the rigid model).

    Args:
        patch: the belts' samples.
        gravity_body: gravity in B (N, 3) [m/s^2].
        com_body: the overall CoM in B (N, 3) or (3,) [m].
        speed: the path's forward speed (N,) [m/s].
        yaw_rate: the path's yaw rate (N,) [rad/s].
        friction: Coulomb coefficient [-].
        turn_ratio: the drive layer's η [-] (:class:`mmstab.stability.drive.DriveLayer`).
        shear_modulus: the belts' shear modulus K [m] (:func:`skid_twist`; 0: Coulomb).
    """
    w = np.asarray(yaw_rate, dtype=float)
    belts = belts_for_twist(speed, w, patch.separation, turn_ratio)
    twist = skid_twist(patch, gravity_body, com_body, belts, friction, shear_modulus)
    rigid = skid_twist(patch, gravity_body, com_body, belts, friction)
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    n = len(twist.yaw_rate)
    com = np.broadcast_to(np.asarray(com_body, dtype=float), (n, 3))
    norm = np.linalg.norm(g[:, :2], axis=1, keepdims=True)
    down = np.divide(g[:, :2], norm, out=np.zeros_like(g[:, :2]), where=norm > 1e-12)
    v = np.broadcast_to(np.asarray(speed, dtype=float), (n,))

    def at_com(t: SkidTwist) -> FloatArray:  # the velocity of the CoM's foot on the plane [m/s]
        return point_velocity(t.velocity_body, t.yaw_rate, com[:, :2])

    beyond = np.sum((at_com(twist) - np.c_[v, np.zeros_like(v)]) * down, 1)
    # the rigid model's slope part (the same belts and CoM on level ground taken off): where
    # the level turn's sideways skid points uphill it does not hide the slope's pull
    level = np.c_[np.zeros((len(g), 2)), -np.linalg.norm(g, axis=1)]
    flat = skid_twist(patch, level, com_body, belts, friction)
    slope = np.sum((at_com(rigid) - at_com(flat)) * down, 1)
    turning = np.abs(w) > 1e-6
    floor = TURN_FLOOR * np.abs(w)
    with np.errstate(invalid="ignore"):  # NaN twist where the cone does not hold
        per_radian = np.where(
            turning,
            np.fmax(np.maximum(beyond, 0.0) / np.maximum(np.abs(twist.yaw_rate), floor),
                    np.maximum(slope, 0.0) / np.maximum(np.abs(rigid.yaw_rate), floor)),
            np.nan,
        )  # fmt: skip
    per_radian = np.where(np.isnan(twist.yaw_rate), np.nan, per_radian)
    rate = np.where(turning, per_radian * np.abs(w), np.maximum(beyond, 0.0))
    rate = np.where(np.isnan(rate), np.inf, rate)
    ratio = np.where(turning, twist.yaw_rate / np.where(turning, w, 1.0), np.nan)
    return TurnSlide(rate, np.where(twist.holds, per_radian, np.inf), ratio)
