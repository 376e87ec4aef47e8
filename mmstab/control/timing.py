"""The arm's time law: slow the reference where its inertial forces would tip the robot.

The plan is quasi-static: each pose is stable with the arm at rest. Between poses the arm
moves (a roadmap move fills the time between two poses, a spline joins the postures), and a
long move in a short interval is fast: on the tests' random route pair 5 a turret swing of
1.2 rad in 0.25 s with the arm out tipped the robot in MuJoCo, the plan's μ at its poses
602 N rad (``docs/physics.md``).

**The measure.** Along the reference (base pose and arm posture at nominal time τ = s ·
lap_time) every body's CoM (base, arm links) is placed in the map frame M with the base's
planar motion (x, y, heading) and the ground's attitude at that instant held (the ground's
own undulation is left out: on a heightmap the resting attitude jumps where the contacts
switch); accelerations are central differences over ``STEP`` [s]. The dynamic force-angle
measure of those accelerations (:mod:`mmstab.stability.dynamic`, with the tool wrench of a
payload) is μ_dyn; with the bodies at rest it is the static μ exactly.

**The joint-speed limits.** A stretch whose reference asks a joint more than
``JOINT_SPEED_SHARE`` of its speed limit is slowed to it first (:func:`joint_speed_factors`).

**The law.** ``controller.dynamic_fraction`` f (default 0.5; null: off): along the reference
μ_dyn ≥ f · μ_static wherever μ_static > 0 (the inertial forces may take at most 1 − f of the
static margin). Time is stretched by a speed factor λ(τ) = dτ/dt ∈ (0, 1], base and arm
together, so that the arm is at each planned posture when the base is at its pose (the plan's
pairs stay as planned). Between consecutive planned poses λ is a constant k: every
acceleration of that stretch scales by k², so the largest k meeting the bound is found by
bisection; λ returns to 1 outside the stretch linearly over ``v_max (1 − k) / DECELERATION``
[s] (the base slows down and speeds up at most ``DECELERATION``). The timed reference is
measured again (the ramps' own accelerations included) and a stretch still below the bound
is slowed further, ``ROUNDS`` times at most. The run lasts longer by the time added.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.control.reference import PathSample
from mmstab.model.robot import FloatArray, Robot
from mmstab.paths.base import BasePath
from mmstab.stability.dynamic import dynamic_force_angle, net_wrench
from mmstab.stability.static import base_polygon
from mmstab.terrain import Terrain, rot_z

#: Step of the central differences and of the law's grid, nominal time [s].
STEP = 0.01
#: The base's largest change of speed from the law [m/s^2] (the routes' default acceleration).
DECELERATION = 0.3
#: Least ramp of λ back to 1 [s nominal], so that a slow base still eases in and out.
MIN_RAMP = 0.5
#: Smallest speed factor: a stretch that needs less is reported, not slowed further.
MIN_FACTOR = 0.05
#: Rounds of measuring the timed reference and slowing the stretches still below the bound.
ROUNDS = 6
#: Largest share of the joint-speed limits the timed reference asks of a joint: the
#: controller keeps the rest to correct its errors. A sequence plan's turret swing of 5.4 rad
#: between poses 3 s apart asked 2.7 times a 3-joint arm's limit; saturated, the arm lagged
#: off the checked move into the body.
JOINT_SPEED_SHARE = 0.8
#: Bisection steps on a stretch's factor k (k within 2^-12 of the largest that meets the bound).
BISECTION = 12


class ReferenceMotion(NamedTuple):
    """The bodies along a reference at nominal times ``tau`` (N,), in the body frame B.

    Attributes:
        tau: nominal times (N,) [s].
        gravity: gravity in B (N, 3) [m/s^2].
        positions: body CoMs in B (N, k, 3) [m]: the base, then the arm links.
        velocity: d/dτ of the bodies' CoMs in M, expressed in B (N, k, 3) [m/s].
        acceleration: d²/dτ² of the same (N, k, 3) [m/s^2].
        tool: the tool point in B (N, 3) [m] (where a payload's wrench acts).
    """

    tau: FloatArray
    gravity: FloatArray
    positions: FloatArray
    velocity: FloatArray
    acceleration: FloatArray
    tool: FloatArray


def _bodies(robot: Robot, q: FloatArray) -> FloatArray:
    """Body CoMs in B (N, 1 + n, 3) [m] at postures q (N, n): the base, the arm links."""
    base = np.broadcast_to(robot.base.com, (len(q), 1, 3))
    return np.concatenate([base, robot.kinematics.link_coms(q)], axis=1)


def reference_motion(
    robot: Robot,
    path: BasePath,
    terrain: Terrain,
    posture: Any,
    lap_time: float,
    tau: ArrayLike,
) -> ReferenceMotion:
    """The bodies' CoMs, velocities and accelerations along a reference (module text).

    Args:
        robot: the robot.
        path: the base path (its pose at fraction s = τ / lap_time).
        terrain: the ground (gravity in B, the attitude held at each instant).
        posture: the arm's posture reference ``s -> PathSample`` (q [rad]).
        lap_time: the references' period [s].
        tau: nominal times (N,) [s].
    """
    tau = np.atleast_1d(np.asarray(tau, dtype=float))
    pose = path.pose_at(tau / lap_time)
    M_R_B = np.asarray(terrain.M_T_B(pose)).reshape(-1, 4, 4)[:, :3, :3]
    tilt = np.einsum("nji,njk->nik", rot_z(pose[:, 2]), M_R_B)  # Rz(γ)ᵀ M_R_B, held
    placed = []
    for d in (-STEP, 0.0, STEP):
        p = pose if d == 0.0 else path.pose_at((tau + d) / lap_time)
        q = np.asarray(posture((tau + d) / lap_time).value)
        R = np.einsum("nij,njk->nik", rot_z(p[:, 2]), tilt)
        world = np.einsum("nij,nkj->nki", R, _bodies(robot, q))
        world[:, :, :2] += p[:, None, :2]
        placed.append(world)
    vel = (placed[2] - placed[0]) / (2 * STEP)
    acc = (placed[2] - 2 * placed[1] + placed[0]) / STEP**2
    q0 = np.asarray(posture(tau / lap_time).value)
    return ReferenceMotion(
        tau=tau,
        gravity=np.asarray(terrain.gravity_body(pose)),
        positions=_bodies(robot, q0),
        velocity=np.einsum("nji,nkj->nki", M_R_B, vel),
        acceleration=np.einsum("nji,nkj->nki", M_R_B, acc),
        tool=robot.kinematics.link_frames(q0)[:, -1, :3, 3],
    )


def dynamic_mu(robot: Robot, motion: ReferenceMotion, acceleration: ArrayLike) -> FloatArray:
    """μ_dyn [N rad] (N,) of the bodies of ``motion`` with CoM accelerations (N, k, 3) in B.

    Point masses (the links' rotational inertia about their own CoMs is left out); a
    payload's tool wrench (``Robot.tool_wrench``) acts at ``motion.tool``. Zero
    accelerations give the static measure (``robot_mu``).
    """
    m = np.array([robot.base.mass, *(link.mass for link in robot.links)])
    w = None if robot.tool_wrench is None else np.asarray(robot.tool_wrench, dtype=float)
    net = net_wrench(
        m, motion.positions, acceleration, motion.gravity,
        force_ext=None if w is None else w[:3], point_ext=motion.tool,
        moment_ext=None if w is None else w[3:],
    )  # fmt: skip
    return dynamic_force_angle(base_polygon(robot).vertices, net.com, net.force, net.moment).mu


class TimeLaw(NamedTuple):
    """The nominal time τ of the references at real time t, periodic with the lap.

    Attributes:
        tau: the law's grid over one lap, nominal times (G,) [s], 0 to ``lap_time``.
        t: the real times at them (G,) [s].
        speed: λ = dτ/dt at them (G,) [-], in (0, 1].
        stretches: the stretches between planned poses, nominal [start, end] (S, 2) [s].
        factors: each stretch's speed factor k (S,) [-] (1: not slowed).
        fraction: ``controller.dynamic_fraction`` f [-].
        mu_dynamic_min_before: least μ_dyn of the reference at its own speed [N rad].
        mu_dynamic_min: least μ_dyn of the timed reference [N rad].
        mu_static_min: least static μ of the reference [N rad] (over the same samples).
        below_bound: samples of the timed reference still below f · μ_static (0: met).
    """

    tau: FloatArray
    t: FloatArray
    speed: FloatArray
    stretches: FloatArray
    factors: FloatArray
    fraction: float
    mu_dynamic_min_before: float
    mu_dynamic_min: float
    mu_static_min: float
    below_bound: int

    @property
    def slows(self) -> bool:
        """Whether any stretch is slowed (else the reference keeps its own time exactly)."""
        return bool(np.any(self.factors < 1.0))

    @property
    def lap_time(self) -> float:
        """The nominal period [s]."""
        return float(self.tau[-1])

    def _cells(self, grid: FloatArray, x: FloatArray) -> tuple[FloatArray, ...]:
        """Each x's grid cell: its start τ0, t0, λ0 and slope κ = dλ/dτ there."""
        i = np.clip(np.searchsorted(grid, x, side="right") - 1, 0, len(grid) - 2)
        kappa = np.diff(self.speed)[i] / np.diff(self.tau)[i]
        return self.tau[i], self.t[i], self.speed[i], kappa

    def nominal(self, t: ArrayLike) -> PathSample:
        """Nominal times τ (N,) [s] at real times t (N,) [s], and λ = dτ/dt (N,) [-].

        Exact for λ linear in τ within a grid cell: λ = λ0 exp(κ (t − t0)).
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        laps = np.floor(t / self.t[-1])
        rest = t - laps * self.t[-1]
        tau0, t0, l0, kappa = self._cells(self.t, rest)
        speed = l0 * np.exp(kappa * (rest - t0))
        flat = np.abs(kappa) < 1e-12
        step = np.where(flat, l0 * (rest - t0), (speed - l0) / np.where(flat, 1.0, kappa))
        return PathSample(laps * self.lap_time + tau0 + step, speed)

    def real_time(self, tau: float) -> float:
        """The real time [s] at which the timed reference reaches nominal time τ [s]."""
        laps = np.floor(tau / self.lap_time)
        rest = np.atleast_1d(tau - laps * self.lap_time)
        tau0, t0, l0, kappa = self._cells(self.tau, rest)
        speed = l0 + kappa * (rest - tau0)
        flat = np.abs(kappa) < 1e-12
        dt = np.where(flat, (rest - tau0) / l0, np.log(speed / l0) / np.where(flat, 1.0, kappa))
        return float(laps * self.t[-1] + t0[0] + dt[0])

    def summary(self, run_end: float | None = None) -> dict[str, Any]:
        """The report for ``summary.json``: the bound, the slowed moves, μ before and after.

        Args:
            run_end: the run's last real time [s]; with it, ``run_time_added_s``: what the
                law added to that run, its end less the reference's nominal time there (less
                than the lap's ``lap_time_added_s`` when a run ends before the lap does).
        """
        slowed = np.flatnonzero(self.factors < 1.0)
        added = None
        if run_end is not None:
            nominal = self.nominal(np.array([run_end])).value[0] if self.slows else run_end
            added = float(run_end - nominal)
        return {
            "run_time_added_s": added,
            "dynamic_fraction": self.fraction,
            "mu_dynamic_min_before": self.mu_dynamic_min_before,
            "mu_dynamic_min": self.mu_dynamic_min,
            "mu_static_min": self.mu_static_min,
            "samples_below_bound": self.below_bound,
            "lap_time_added_s": float(self.t[-1] - self.tau[-1]),
            "slowed_moves": [
                {"nominal_s": self.stretches[i].tolist(), "factor": float(self.factors[i])}
                for i in slowed
            ],
        }


def law_speed(
    tau: FloatArray, stretches: FloatArray, factors: FloatArray, v_max: float
) -> FloatArray:
    """λ(τ) (N,): each slowed stretch's k, ramped linearly back to 1 outside it (module text)."""
    speed = np.ones_like(tau)
    for (a, b), k in zip(stretches, factors, strict=True):
        if k >= 1.0:
            continue
        ramp = max(MIN_RAMP, v_max * (1.0 - k) / DECELERATION)
        away = np.maximum(0.0, np.maximum(a - tau, tau - b))
        speed = np.minimum(speed, k + (1.0 - k) * np.clip(away / ramp, 0.0, 1.0))
    return speed


def real_times(tau: FloatArray, speed: FloatArray) -> FloatArray:
    """Real times (G,) [s] at the grid τ (G,) [s] of a piecewise-linear λ: ∫ dτ / λ, exactly."""
    l0, l1, h = speed[:-1], speed[1:], np.diff(tau)
    same = np.isclose(l0, l1)
    dt = np.where(same, h / l0, h * np.log(l1 / l0) / np.where(same, 1.0, l1 - l0))
    return np.r_[0.0, np.cumsum(dt)]


def _largest_factor(
    robot: Robot, motion: ReferenceMotion, rows: NDArray[np.intp], bound: FloatArray, k: float
) -> float:
    """The largest factor ≤ k whose k² accelerations keep μ_dyn ≥ bound on ``rows``."""
    part = motion._replace(
        gravity=motion.gravity[rows], positions=motion.positions[rows], tool=motion.tool[rows]
    )
    acc = motion.acceleration[rows]

    def meets(x: float) -> bool:
        return bool(np.all(dynamic_mu(robot, part, x * x * acc) >= bound[rows]))

    lo, hi = MIN_FACTOR, k
    if meets(hi):
        return hi
    for _ in range(BISECTION):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if meets(mid) else (lo, mid)
    return lo


class Stretches:
    """The stretches between planned poses on the law's grid, and which one a sample blames.

    A sample within ``1.5 STEP`` of a stretch's end has central differences reaching into
    the next stretch (a roadmap move stops there at its smoothstep's end deceleration): its
    low μ_dyn is blamed on the neighbour whose arm moves fastest, not on a long, slow
    stretch that happens to begin there.
    """

    def __init__(self, ends: FloatArray, tau: FloatArray, motion: ReferenceMotion):
        self.ends, self.tau = ends, tau
        self.spans = np.column_stack([ends[:-1], ends[1:]])
        self.which = np.clip(np.searchsorted(ends, tau, side="right") - 1, 0, len(ends) - 2)
        arm = np.linalg.norm(motion.acceleration[:, 1:], axis=2).max(axis=1)  # (N,) [m/s^2]
        self.intensity = np.zeros(len(self.spans))
        np.maximum.at(self.intensity, self.which, arm)

    def rows(self, i: int) -> NDArray[np.intp]:
        """The samples of stretch i and those within 1.5 STEP of its ends (indices)."""
        a, b = self.spans[i]
        return np.flatnonzero((self.tau >= a - 1.5 * STEP) & (self.tau <= b + 1.5 * STEP))

    def blamed(self, bad: NDArray[np.intp]) -> NDArray[np.intp]:
        """The stretches to slow for the samples ``bad`` (indices), each blamed once."""
        out = set()
        last = len(self.spans) - 1
        for j in bad:
            i, t = int(self.which[j]), self.tau[j]
            near = [i]
            if i > 0 and t - self.spans[i, 0] < 1.5 * STEP:
                near.append(i - 1)
            if i < last and self.spans[i, 1] - t < 1.5 * STEP:
                near.append(i + 1)
            out.add(max(near, key=lambda k: self.intensity[k]))
        return np.array(sorted(out), dtype=np.intp)


def joint_speed_factors(
    robot: Robot, posture: Any, lap_time: float, stretches: Stretches
) -> FloatArray:
    """Per stretch the factor k ≤ 1 that keeps the arm within ``JOINT_SPEED_SHARE`` of its limits.

    Args:
        robot: the robot (joint-speed limits [rad/s]).
        posture: the arm's posture reference ``s -> PathSample`` (dq/ds [rad]).
        lap_time: the references' period [s].
        stretches: the stretches over the checked samples.
    """
    rate = np.abs(posture(stretches.tau / lap_time).rate) / lap_time  # dq/dτ (N, n) [rad/s]
    share = (rate / robot.joint_velocity).max(axis=1)
    worst = np.zeros(len(stretches.spans))
    np.maximum.at(worst, stretches.which, share)
    return np.minimum(1.0, JOINT_SPEED_SHARE / np.maximum(worst, 1e-12))


def timed_mu(robot: Robot, motion: ReferenceMotion, speed: FloatArray) -> FloatArray:
    """μ_dyn (N,) [N rad] of the reference timed by λ (N,) on the motion's grid.

    d²p/dt² = λ² d²p/dτ² + λ λ' dp/dτ, with λ' = dλ/dτ (the ramps' own accelerations).
    """
    dspeed = np.gradient(speed, motion.tau)
    acc = (speed**2)[:, None, None] * motion.acceleration
    acc += (speed * dspeed)[:, None, None] * motion.velocity
    return dynamic_mu(robot, motion, acc)


def build_time_law(
    robot: Robot,
    path: BasePath,
    terrain: Terrain,
    posture: Any,
    lap_time: float,
    fractions: ArrayLike,
    fraction: float,
    window: tuple[float, float],
) -> TimeLaw:
    """The time law of a reference: μ_dyn ≥ ``fraction`` · μ_static along it (module text).

    Args:
        robot: the robot.
        path: the base path.
        terrain: the ground.
        posture: the arm's posture reference ``s -> PathSample`` (q [rad]).
        lap_time: the references' period [s].
        fractions: the planned poses' path fractions (K,) [-]: the stretches' ends.
        fraction: f [-], the share of the static μ the dynamic μ keeps.
        window: nominal times [start, end] [s] that are checked: after the arm's start-up
            approach (its own reference), until the run's end (at most one lap).
    """
    tau = np.linspace(0.0, lap_time, max(int(np.ceil(lap_time / STEP)), 2) + 1)
    on = np.flatnonzero((tau >= window[0]) & (tau <= min(window[1], lap_time)))
    on = on if on.size > 1 else np.arange(len(tau) - 2, len(tau))  # ends in its approach
    motion = reference_motion(robot, path, terrain, posture, lap_time, tau[on])  # checked
    static = dynamic_mu(robot, motion, np.zeros_like(motion.acceleration))
    bound = np.where(static > 0, fraction * static, -np.inf)
    ends = np.unique(np.r_[0.0, np.asarray(fractions, dtype=float) * lap_time, lap_time])
    stretches = Stretches(ends, motion.tau, motion)
    factors = joint_speed_factors(robot, posture, lap_time, stretches)
    v_max = float(np.linalg.norm(motion.velocity[:, 0, :2], axis=1).max())
    before = mu = timed_mu(robot, motion, np.ones(on.size))
    speed = np.ones_like(tau)
    if np.any(factors < 1.0):  # the joint-speed limits first
        speed = law_speed(tau, stretches.spans, factors, v_max)
        speed[tau < window[0]] = 1.0
        mu = timed_mu(robot, motion, speed[on])
    for rnd in range(ROUNDS):
        low = stretches.blamed(np.flatnonzero(mu < bound))
        if not low.size:
            break
        for i in low:
            if rnd == 0:
                rows = stretches.rows(i)
                factors[i] = _largest_factor(robot, motion, rows, bound, factors[i])
            else:  # the ramps' accelerations or a neighbour's: a little slower
                factors[i] = max(MIN_FACTOR, 0.8 * factors[i])
        speed = law_speed(tau, stretches.spans, factors, v_max)
        speed[tau < window[0]] = 1.0  # the approach keeps its own time
        mu = timed_mu(robot, motion, speed[on])
    return TimeLaw(
        tau=tau,
        t=real_times(tau, speed),
        speed=speed,
        stretches=stretches.spans,
        factors=factors,
        fraction=float(fraction),
        mu_dynamic_min_before=float(before.min()),
        mu_dynamic_min=float(mu.min()),
        mu_static_min=float(static.min()),
        below_bound=int(np.count_nonzero(mu < bound)),
    )
