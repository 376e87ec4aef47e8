"""The arm references of the tracking controller: postures, their CoM, checked and repaired.

The controller's posture task (:mod:`mmstab.control.tasks`) pulls the arm toward q_ref(s), and its
arm-CoM task toward g_ref(s). Both come from the plan's postures:

1. **Interpolate the postures**: the periodic cubic spline that the plan's CoMs used to be
   interpolated with (:func:`mmstab.control.reference.posture_reference`, the turret unwrapped).
   A roadmap plan (``planner: {method: roadmap}``) is followed on its checked moves
   instead: straight joint moves between their vertices, at rest at each
   (:func:`roadmap_knots`): a spline through them would leave the checked moves and, on
   random routes, touched the body where the moves pass within millimetres of it. A
   sequence plan (``method: sequence``) checked the straight moves between its postures:
   where its spline comes within ``MOVE_CLEARANCE`` of the robot, those moves are followed
   the same way (a user's 3-joint arm: its spline cut through the body; ``interpolation``).
2. **Its CoM is the CoM reference**: g_ref^B(s) = g_a^B(q_ref(s)), rate J_a q̇_ref
   (:meth:`PostureReference.com_body`). At the planned poses it is the planned CoM (to the
   IK's 10⁻⁴ m). Splining the planned CoMs instead (:func:`mmstab.control.reference.arm_reference`)
   gives a CoM path up to 24 mm away from the posture spline's CoM on the default lap, and
   outside the arm's reach on a quarter of it (by up to 8 mm, near the stretched postures):
   the two tasks would pull against each other, and the CoM task alone could not track it.
   With the CoM of the posture reference both tasks ask for the same, reachable motion, and
   the posture task only decides the arm's free direction (3 CoM rows, 4 joints).
3. **Check and repair**: every planned posture is collision-free, but the spline between two
   of them need not be: on the default problem it swings the lowered upper arm over the left
   track between the postures at s = 0.8 and s = 0.9 (s ∈ [0.813, 0.869], upper_arm–track_left
   and upper_arm–body; straight lines in joint space collide there too).
   :func:`build_posture_reference` checks the reference at every control period of the lap
   with :class:`~mmstab.model.collision.CollisionChecker` and repairs each colliding stretch with a
   **via posture** at its middle s_m: a collision-free posture realising the plan's splined
   CoM at s_m, the one nearest the colliding posture among IPOPT solutions from a few seeds
   (:class:`mmstab.workspace.ik.PostureSolver`), else the free posture at s_m on the straight
   joint move between the knots around it; then it interpolates and checks again, until the
   reference is free or no via posture is found. Nothing is hidden: the result keeps the check
   before and after and every via posture with the stretch it repairs; the tracking summary
   reports them.

The start-up part, from the arm's initial posture onto these references, is
:mod:`mmstab.control.approach`.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike

from mmstab.control.reference import (
    BasePath,
    PathSample,
    PlanLike,
    StepReference,
    periodic_spline,
    place_on_path,
    posture_reference,
)
from mmstab.core.masks import true_runs
from mmstab.model.collision import CollisionChecker
from mmstab.model.collision_sequence import SequenceCollisions, sequence_collisions
from mmstab.model.robot import FloatArray, Robot
from mmstab.terrain import Terrain

#: At most this many repair rounds (each adds one via posture per colliding stretch).
MAX_REPAIR_ROUNDS = 8


class PosturePlan(PlanLike, Protocol):
    """What the posture reference needs of a plan (:class:`mmstab.planner.Plan` has it)."""

    @property
    def postures(self) -> FloatArray:
        """Arm postures realising the targets (K, 4) [rad], collision-free."""
        ...


def arm_com_jacobians(robot: Robot, q: ArrayLike) -> FloatArray:
    """The arm-CoM Jacobians d g_a^B / d q at many postures (N, 3, n) [m/rad].

    Args:
        robot: the robot.
        q: arm postures (N, n) [rad].
    """
    qa = np.atleast_2d(np.asarray(q, dtype=float))
    n = qa.shape[1]
    out = np.asarray(robot.kinematics.f_arm_com_jac.map(len(qa))(qa.T))  # (3, n N)
    return out.reshape(3, len(qa), n).transpose(1, 0, 2)


def posture_com(robot: Robot, posture: PathSample) -> PathSample:
    """The arm CoM of postures and its rate: g_a^B(q) (N, 3) [m] and J_a(q) q̇ (N, 3).

    Args:
        robot: the robot.
        posture: postures (N, 4) [rad] and their rates (N, 4) [rad per unit of time or path].
    """
    q, dq = np.atleast_2d(posture.value), np.atleast_2d(posture.rate)
    rate = np.einsum("nij,nj->ni", arm_com_jacobians(robot, q), dq)
    return PathSample(robot.arm_com(q), rate)


def body_frame_reference(robot: Robot, reference: StepReference) -> StepReference:
    """The reference with its arm-CoM rows in the body frame (``arm_com_frame: body``).

    ξ_des[3:6] = g_a^B(q_ref) [m] and ξ̇_ref[3:6] = J_a(q_ref) q̇_ref [m/s]: the CoM of the
    posture reference, which the map-frame rows place with the reference pose (lap and
    approach alike), so both frames ask for the same arm when the base is on its reference.

    Args:
        robot: the robot.
        reference: the run's references (N rows), arm-CoM rows in M.
    """
    com = posture_com(robot, PathSample(reference.q_ref, reference.q_dot_ref))
    xi_des, xi_dot_ref = np.array(reference.xi_des), np.array(reference.xi_dot_ref)
    xi_des[:, 3:6], xi_dot_ref[:, 3:6] = com.value, com.rate
    return reference._replace(xi_des=xi_des, xi_dot_ref=xi_dot_ref)


@dataclasses.dataclass(frozen=True)
class ViaPosture:
    """A posture added to a reference where it collided.

    Attributes:
        fraction: where it is placed: path fraction s [-] (lap), path parameter u (approach).
        posture: the posture (4,) [rad], collision-free.
        interval: the colliding stretch it repairs [first colliding, first free] (s or [s]).
        pairs: the pairs that collided in the middle of that stretch.
    """

    fraction: float
    posture: FloatArray
    interval: tuple[float, float]
    pairs: tuple[str, ...]


@dataclasses.dataclass(frozen=True)
class PostureReference:
    """The posture reference q_ref(s) along the lap, its CoM, and its collision check.

    Call it like the functions of :mod:`mmstab.control.reference`: ``ref(s) -> PathSample`` with
    q_ref (N, 4) [rad] and d q_ref / ds (N, 4) [rad].

    Attributes:
        fractions: the knots' path fractions (K + V,), increasing in [0, 1).
        postures: the knots (K + V, 4) [rad]: the plan's postures and the via postures.
        via: the via postures, in the order they were added.
        planned_check: the plan's postures interpolated, before any repair (x = s).
        check: the reference as used (x = s); ``colliding_samples`` 0 when it is free.
        com_gap_max: largest distance of its CoM from the plan's CoMs splined (the paper's
            CoM reference, :func:`mmstab.control.reference.arm_reference`) over the checked samples
            [m].
        spline: the knots' spline ``s -> PathSample``.
        robot: the robot.
        interpolation: ``spline`` (cubic through the knots), ``moves`` (straight between
            them, at rest at each: a roadmap plan's moves, or a sequence plan's checked moves
            where its spline touched the robot).
    """

    fractions: FloatArray
    postures: FloatArray
    via: tuple[ViaPosture, ...]
    planned_check: SequenceCollisions
    check: SequenceCollisions
    com_gap_max: float
    spline: Any
    robot: Robot
    interpolation: str = "spline"

    def __call__(self, s: ArrayLike) -> PathSample:
        """q_ref and d q_ref / ds at path fractions s (N,)."""
        return self.spline(s)

    def com_body(self, s: ArrayLike) -> PathSample:
        """Its arm CoM g_a^B(q_ref(s)) (N, 3) [m] and d/ds (N, 3) [m]: the CoM reference."""
        return posture_com(self.robot, self(s))

    def arm_reference(self, circle: BasePath, terrain: Terrain) -> Any:
        """The arm-CoM reference in M: its CoM placed with the reference base pose.

        Args:
            circle: the base path.
            terrain: the ground.

        Returns:
            ``s -> PathSample``: g_a^M (N, 3) [m] and d/ds (N, 3) [m], as
            :func:`mmstab.control.reference.arm_reference` places the plan's CoMs.
        """

        def reference(s: ArrayLike) -> PathSample:
            s = np.atleast_1d(np.asarray(s, dtype=float))
            return place_on_path(circle, terrain, s, self.com_body(s))

        return reference

    @property
    def collision_free(self) -> bool:
        """Whether no checked sample of the reference collides."""
        return self.check.colliding_samples == 0

    def summary(self, lap_time: float) -> dict[str, Any]:
        """The report for ``summary.json``: checks and via postures, fractions and times.

        Args:
            lap_time: time of one lap [s] (times are s · lap_time).
        """

        def report(c: SequenceCollisions) -> dict[str, Any]:
            return {
                "samples": c.samples,
                "colliding_samples": c.colliding_samples,
                "colliding_share": c.colliding_share,
                "intervals_fraction": c.intervals,
                "intervals_s": [[a * lap_time, b * lap_time] for a, b in c.intervals],
                "pairs": c.pairs,
            }

        return {
            "samples_per_lap": self.check.samples,
            "planned_postures": int(self.fractions.size - len(self.via)),
            "interpolation": self.interpolation,
            "com_gap_to_planned_com_spline_max_m": self.com_gap_max,
            "planned_interpolation": report(self.planned_check),
            "via_postures": [
                {
                    "fraction": v.fraction,
                    "time_s": v.fraction * lap_time,
                    "posture": v.posture.tolist(),
                    "repairs_fraction": list(v.interval),
                    "pairs": list(v.pairs),
                }
                for v in self.via
            ],
            "reference": report(self.check),
        }


def _via_posture(
    robot: Robot,
    solver: Any,
    checker: CollisionChecker,
    target: FloatArray,
    seeds: list[FloatArray],
    near: FloatArray,
) -> FloatArray | None:
    """The collision-free posture realising ``target`` nearest ``near``, from ``seeds``."""
    from mmstab.workspace.ik import COM_TOLERANCE

    best, best_d = None, np.inf
    for seed in seeds:
        q = np.clip(solver.solve(target, seed, near), robot.joint_lower, robot.joint_upper)
        if np.linalg.norm(robot.arm_com(q) - target) > COM_TOLERANCE or checker.collides(q):
            continue
        d = float(np.linalg.norm(q - near))
        if d < best_d:
            best, best_d = q, d
    return best


def _straight_via(
    checker: CollisionChecker, ref: PostureReference, k: int, s_mid: float
) -> FloatArray | None:
    """The straight joint move between the knots about ``s_mid`` [-] at ``s_mid``, if free."""
    f, q = ref.fractions, ref.postures
    a, b = k - 1, k % len(f)
    fa, fb = f[a], f[b] + (1.0 if k == len(f) else 0.0)
    if k == 0:
        a, fa = len(f) - 1, f[-1] - 1.0
    u = (s_mid - fa) / (fb - fa)
    mid = q[a] + u * (q[b] - q[a])
    return None if checker.collides(mid) else mid


def piece_times(robot: Robot, q: FloatArray) -> FloatArray:
    """Cumulative time weights (n,) of the straight pieces between postures q (n, 4) [rad].

    Each piece runs rest to rest (smoothstep); its weight is the square root of its time at
    the joint-speed limits, so that, filling a given interval, every piece has the same peak
    acceleration (6 Δ / h²). Weights in proportion to the time itself gave short pieces the
    same mean speed as long ones: a 0.05 rad piece in 0.03 s needs ~270 rad/s², and the
    arm, tracked at a 10 ms period, overshot its end by 0.015 rad (random route pair 5:
    0.34 mm from the body).
    """
    at_limit = (np.abs(np.diff(q, axis=0)) / robot.joint_velocity).max(axis=1)
    return np.r_[0.0, np.cumsum(np.sqrt(at_limit))]


def roadmap_knots(
    robot: Robot, fractions: FloatArray, postures: FloatArray, moves: tuple[FloatArray, ...]
) -> tuple[FloatArray, FloatArray]:
    """The plan's knots with its roadmap moves inserted (``planner: {method: roadmap}``).

    The vertices of each move into pose k (from pose k−1, or on a closed plan from the last
    pose into pose 0 at s = 1) are placed between the two poses' fractions, the move
    time-scaled to fill its interval, each straight piece's share by :func:`piece_times`;
    the reference moves straight between them, at rest at each
    (:func:`mmstab.control.reference.periodic_polyline`). The open plan's move from the start
    posture is the approach's (:mod:`mmstab.control.approach`), not inserted.

    Args:
        robot: the robot (joint-speed limits [rad/s]).
        fractions: the planned poses' fractions (K,) [-].
        postures: their postures (K, 4) [rad].
        moves: the roadmap move into each pose (K arrays (n, 4) [rad]).
    """
    K = len(postures)
    d0 = moves[0][0] - postures[-1]
    closed = K > 1 and np.allclose(np.r_[np.cos(d0[0]) - 1.0, d0[1:]], 0.0, atol=1e-9)
    f_out, q_out = [fractions], [postures]
    for k, move in enumerate(moves):
        if k == 0 and not closed:
            continue
        a, b = (fractions[-1], 1.0 + fractions[0]) if k == 0 else (fractions[k - 1], fractions[k])
        q = np.asarray(move, dtype=float)
        tau = piece_times(robot, q)
        if len(q) < 3 or tau[-1] <= 0:
            continue
        f = a + (b - a) * tau[1:-1] / tau[-1]
        keep = (f > a) & (f < b) & (f < 1.0)
        f_out.append(f[keep])
        q_out.append(q[1:-1][keep])
    f_all, q_all = np.concatenate(f_out), np.vstack(q_out)
    order = np.argsort(f_all, kind="stable")
    f_all, q_all = f_all[order], q_all[order]
    unique = np.r_[True, np.diff(f_all) > 1e-12]
    return f_all[unique], q_all[unique]


def _keeps_clearance(checker: CollisionChecker, q: FloatArray) -> bool:
    """Whether the sampled reference q (N, n) [rad] keeps ``MOVE_CLEARANCE`` from the robot."""
    from mmstab.model.reach import joint_reach
    from mmstab.workspace.roadmap_checks import MOVE_CLEARANCE

    reach = joint_reach(checker.robot, q)  # over every sample: a bound between them
    step = float((np.abs(np.diff(q, axis=0)) @ reach).max(initial=0.0))
    return bool(checker.keeps_clearance(q, MOVE_CLEARANCE, max(step, 1e-9)))


def straight_moves_checked(plan: Any) -> bool:
    """Whether the plan checked the straight joint moves between its postures (``sequence``)."""
    settings = getattr(plan, "settings", None)
    return getattr(settings, "method", None) == "sequence" and not getattr(plan, "moves", ())


def build_posture_reference(
    robot: Robot, plan: PosturePlan, samples: int, *, repair: bool = True
) -> PostureReference:
    """The posture reference of a plan, checked at ``samples`` points per lap and repaired.

    Args:
        robot: the robot (joint limits, kinematics, collision geometry).
        plan: ``fractions`` (K,), body-frame ``target_com`` (K, 3) [m] and ``postures``
            (K, 4) [rad].
        samples: points per lap the reference is checked at (s = k / samples); the tracking
            run uses one per control period, lap_time / dt (:func:`posture_samples`).
        repair: add via postures where the reference collides (False: check only).

    Raises:
        ValueError: bad plan shapes or fractions, or fewer than 2 samples.
    """
    if samples < 2:
        raise ValueError(f"need at least 2 samples per lap, got {samples}")
    lo, hi = robot.joint_lower, robot.joint_upper
    fractions = np.asarray(plan.fractions, dtype=float)
    postures = np.array(plan.postures, dtype=float, ndmin=2)
    com_body = periodic_spline(fractions, plan.target_com, "target_com")
    moves = getattr(plan, "moves", ())
    linear = len(moves) == len(postures) and len(postures) > 0
    if linear:  # method roadmap: follow its moves, straight between their knots
        fractions, postures = roadmap_knots(robot, fractions, postures, moves)
    s = np.arange(samples) / samples
    checker = CollisionChecker(robot)

    def make(
        fractions: FloatArray, postures: FloatArray, linear: bool = linear
    ) -> tuple[PostureReference, Any, Any]:
        spline = posture_reference(fractions, postures, lo, hi, linear=linear)
        q = spline(s).value
        check, hit = sequence_collisions(checker, s, q)
        gap = float(np.linalg.norm(robot.arm_com(q) - com_body(s).value, axis=1).max())
        kind = "moves" if linear else "spline"
        ref = PostureReference(fractions, postures, (), check, check, gap, spline, robot, kind)
        return ref, q, hit

    ref, q_s, hit = make(fractions, postures)
    if not linear and straight_moves_checked(plan) and not _keeps_clearance(checker, q_s):
        # the plan checked the straight moves between its postures: follow them instead
        spline_check = ref.check
        ref = make(fractions, postures, True)[0]
        return dataclasses.replace(ref, planned_check=spline_check)
    planned, via = ref.check, []
    solver = None
    for _ in range(MAX_REPAIR_ROUNDS if repair else 0):
        if not hit.any():
            break
        if solver is None:
            from mmstab.workspace.ik import PostureSolver

            solver = PostureSolver(robot, None)
        added = []
        for (a, b), interval in zip(true_runs(hit), ref.check.intervals, strict=True):
            mid = (a + b - 1) // 2
            if np.any((ref.fractions >= s[a]) & (ref.fractions <= s[b - 1])):
                continue  # a knot itself collides (a plan's posture): no via posture helps
            if np.min(np.abs(ref.fractions - s[mid])) < 1.0 / samples:
                continue  # a knot already sits there: another one would only make a kink
            k = int(np.searchsorted(ref.fractions, s[mid]))
            seeds = [q_s[mid], ref.postures[k - 1], ref.postures[k % len(ref.postures)]]
            q = _via_posture(robot, solver, checker, com_body(s[mid]).value[0], seeds, q_s[mid])
            if q is None:
                q = _straight_via(checker, ref, k, s[mid])
            if q is not None:
                pairs = tuple(checker.colliding_pairs(q_s[mid]))
                added.append(ViaPosture(float(s[mid]), q, (interval[0], interval[1]), pairs))
        if not added:
            break  # nothing more can be repaired: the check says where it still collides
        via.extend(added)
        order = np.argsort(np.r_[ref.fractions, [v.fraction for v in added]])
        knots = np.r_[ref.fractions, [v.fraction for v in added]][order]
        ref, q_s, hit = make(knots, np.vstack([ref.postures, [v.posture for v in added]])[order])
    return dataclasses.replace(ref, via=tuple(via), planned_check=planned)


def posture_samples(lap_time: float, dt: float) -> int:
    """Check points per lap: one per control period (lap_time / dt, rounded), at least 2.

    Args:
        lap_time: time of one lap [s].
        dt: control period [s].
    """
    return max(int(round(lap_time / dt)), 2)
