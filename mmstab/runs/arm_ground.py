"""The ground under the arm between the planned poses, at the attitudes the body takes there.

**The verdict** (:func:`arm_in_ground_record`, every route and lap on a heightmap): at every
dense sample, the body at its rest, the arm on the plan's posture reference, its least
height above the ground from points on its surface (:func:`arm_heights`, in C with its NumPy
twin); below the ground is the plan's ``arm_contact`` (exit 5). ``mmstab track`` measures
its tracked arm the same way (:func:`mmstab.runs.tracking.checks.arm_in_ground_run`).

**The crests' record** (``physics.arm_over_crests``, opt-in). The planner keeps the arm
``planner.ground_clearance`` above the ground at each planned pose, at the pose's
predicted rest and through tilts of ``planner.attitude_margin``
(:mod:`mmstab.planner.ground.under_arm`). Between the poses, over a bump's crest, the
quasi-static rest flips from one support to the other (rear down to front down, or across
a diagonal) within a few centimetres of travel; the robot does not jump between the two
rests: it turns over the crest's support edge toward its CoM until the ground on the other
side catches it, and may dwell there or overshoot the new rest. :func:`arm_ground_along`
measures the arm's least height above the ground (the planner's own measure,
:class:`mmstab.planner.ground.under_arm.GroundUnderArm`, no margin) at every dense sample
of the path (:func:`mmstab.runs.along.path_timing`), with the arm on its posture reference
there (:func:`reference_postures`, the CoM the rest carries with it):

- at the sample's rest;
- where the rest turns by more than :data:`FLIP` between neighbouring samples (a flip),
  and where a rock was checked (:func:`mmstab.runs.along.rock_samples`):
  also at the rocked attitude, the rest turned outward about its weakest support edge (the
  least force angle: the edge the CoM leans over) until a contact beyond it meets the
  ground (:func:`mmstab.stability.rock.catch`).

A sample whose arm is below the ground (height < 0) is listed as a contact: where, how far
in, at which attitude. :func:`arm_ground_record` takes two postures of the arm at each
sample (the plan's posture reference, and the two planned postures it moves between) and
``mmstab plan`` records both in ``summary.json`` (``along_path.arm_ground``); it is a
record, not an exit status: with the planned postures it lists the sample where MuJoCo's
forearm touches on route 29 of ``make validate-routes``, and also routes MuJoCo drives
without a contact (``docs/stability.md``).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.clib import BYTES, DOUBLE, DOUBLES, LONG, LONGS, optional_kernel
from mmstab.core.masks import true_runs
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.ground.arm_pieces import SURFACE_STEP, ArmSurface, arm_surface
from mmstab.planner.ground.under_arm import GroundUnderArm
from mmstab.stability.rock import catch, rested_supports
from mmstab.stability.support import is_heightmap
from mmstab.terrain.base import Terrain

if TYPE_CHECKING:
    from mmstab.paths.circle import CirclePath
    from mmstab.paths.route import RoutePath
    from mmstab.planner import RoutePlan
    from mmstab.runs.along import LapStage


#: A rest that turns more than this between neighbouring samples is a flip [rad] (3 deg
#: between samples 5 cm apart: the rest has gone over a crest or an edge, not followed a
#: slope; it is not ``planner.attitude_margin``, which the planner keeps the arm clear through).
FLIP = float(np.radians(3.0))


class ArmGround(NamedTuple):
    """The arm's least height above the ground at N path samples (its reference posture).

    Attributes:
        rest: at the samples' rests (N,) [m] (NaN: off the map or tips over).
        rocked: at the rocked attitude (N,) [m] (NaN: not a flip or a rock, or not caught).
        turn: the rock's turn from the rest to its catch (N,) [rad] (NaN: none).
        flip: the rest's largest turn to a neighbouring sample's (N,) [rad].
    """

    rest: FloatArray
    rocked: FloatArray
    turn: FloatArray
    flip: FloatArray

    @property
    def height(self) -> FloatArray:
        """The lower of the two (N,) [m] (NaN where neither is known)."""
        return np.asarray(np.fmin(self.rest, self.rocked))


def _turns(z: FloatArray) -> FloatArray:
    """Each sample's largest turn of B's z axis to a neighbour's (N,) [rad] (z: (N, 3))."""
    step = np.arccos(np.clip(np.sum(z[1:] * z[:-1], axis=1), -1.0, 1.0))
    step = np.nan_to_num(step, nan=0.0)
    out = np.zeros(len(z))
    out[1:] = step
    out[:-1] = np.fmax(out[:-1], step)
    return out


def in_ground_runs(h: ArrayLike) -> list[tuple[int, int, int]]:
    """Each run of samples with the arm in the ground (height h < 0 [m], known).

    Returns:
        (first, end, deepest) sample indices of each run (``end`` exclusive).
    """
    h = np.asarray(h, dtype=float)
    runs = true_runs(np.isfinite(h) & (h < 0.0))
    return [(int(a), int(b), int(a + np.argmin(h[a:b]))) for a, b in runs]


def in_ground_in_time(h: ArrayLike, t: ArrayLike) -> dict[str, Any]:
    """A run's record of the arm in the ground (``track``'s and ``follow``'s ``arm_in_ground``).

    Args:
        h: the arm's least height above the ground at the run's samples (N,) [m] (< 0: in
            it; NaN: unknown).
        t: their times (N,) [s].

    Returns:
        ``contact`` (bool), ``samples`` (N), ``height_min_m`` and its ``at_time_s`` [s]
        (None: none known), ``unknown_samples`` and ``intervals_s`` in the ground:
        ``start_s``, ``end_s`` [s] (its first and last samples) and ``by`` how far in [m].
    """
    h, t = np.asarray(h, dtype=float), np.asarray(t, dtype=float)
    known = np.isfinite(h)
    intervals = [{"start_s": float(t[a]), "end_s": float(t[b - 1]), "by": float(-h[k])}
                 for a, b, k in in_ground_runs(h)]  # fmt: skip
    j = int(np.nanargmin(h)) if known.any() else None
    return {
        "contact": bool(intervals),
        "samples": len(h),
        "height_min_m": None if j is None else float(h[j]),
        "at_time_s": None if j is None else float(t[j]),
        "unknown_samples": int((~known).sum()),
        "intervals_s": intervals,
    }


def reference_postures(
    robot: Robot, plan: RoutePlan | LapStage, route: RoutePath | CirclePath, s: ArrayLike
) -> FloatArray:
    """The arm's posture reference at arc lengths s (N,) [m]: postures (N, n) [rad].

    The plan's postures joined by its moves along the path's time law (a route's, or a
    lap's one speed)
    (:func:`mmstab.control.posture.build_posture_reference`, as
    :func:`mmstab.runs.climb_out.reference_coms`); None where a posture is not realised.
    """
    from mmstab.control.posture import build_posture_reference

    reference = build_posture_reference(robot, plan, 2, repair=False)
    f = np.clip(np.asarray(route.fraction_of_s(np.asarray(s, dtype=float))), 0.0, 1.0 - 1e-12)
    return np.asarray(reference(f).value, dtype=float)


def arm_ground_along(
    robot: Robot,
    terrain: Terrain,
    poses: ArrayLike,
    postures: ArrayLike,
    flip: float,
    rocked: ArrayLike | None = None,
) -> ArmGround:
    """The arm's height above the ground at the samples' rests and rocked attitudes.

    On a heightmap only (on a plane the support does not change along the path and the
    planner's plane check holds at every sample): elsewhere every value is NaN.

    Args:
        robot: the robot.
        terrain: the ground.
        poses: the path's samples (N, 3) of (x, y, yaw) in M [m, m, rad], in driving order.
        postures: the arm's posture at each (N, n) [rad] (:func:`reference_postures`).
        flip: a rest that turns more than this [rad] to a neighbouring sample's is a
            flip (:data:`FLIP`).
        rocked: (N,) samples where a rock was checked (:attr:`Rocks.checked`), if any.
    """
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    q = np.atleast_2d(np.asarray(postures, dtype=float))
    n = len(P)
    out = ArmGround(np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan), np.zeros(n))
    if n == 0 or not is_heightmap(terrain):
        return out
    ground = terrain
    if getattr(terrain, "robot", None) is not robot:
        ground = terrain.with_robot(robot, getattr(terrain, "flipper_angle", None))
    com_B = np.atleast_2d(np.asarray(robot.overall_com(robot.arm_com(q)), dtype=float))
    T = ground.rest(P, strict=False, com_body=com_B).G_T_B  # type: ignore[attr-defined]
    ok = np.isfinite(T).all(axis=(1, 2)) & np.isfinite(q).all(axis=1)
    out.flip[:] = _turns(T[:, :3, 2])
    check = out.flip > flip
    if rocked is not None:
        check |= np.asarray(rocked, dtype=bool)
    # the rocked attitudes: the rest turned over its weakest edge until caught
    rows, turned, turn = [], [], []
    candidates = np.flatnonzero(check & ok)
    supports = rested_supports(ground, P[candidates], np.ascontiguousarray(com_B[candidates]))
    for r, first in zip(candidates, supports, strict=True):
        if first is None:
            continue
        j = int(np.argmin(first.theta))
        c = catch(ground, first.T, first.poly[j], first.poly[(j + 1) % len(first.poly)])
        if c is not None:
            rows.append(r)
            turned.append(c.T)
            turn.append(c.angle)
    at = np.concatenate([np.flatnonzero(ok), np.asarray(rows, dtype=np.intp)])
    G_T_B = np.concatenate([T[ok], np.reshape(turned, (-1, 4, 4))])
    M_T_B = np.linalg.inv(ground.G_T_M()) @ G_T_B
    under = GroundUnderArm(robot, ground, P[at], M_T_B=M_T_B)
    h = np.array([under.heights(k, q[at[k] : at[k] + 1])[0] for k in range(len(at))])
    m = int(ok.sum())
    out.rest[ok] = h[:m]
    out.rocked[rows], out.turn[rows] = h[m:], turn
    return out


def arm_ground_verdict(arm: ArmGround, s: ArrayLike, flip: float) -> dict[str, Any]:
    """Where the arm touches the ground along the path (``summary.json``'s ``arm_ground``).

    Args:
        arm: :func:`arm_ground_along`'s heights.
        s: the samples' arc lengths (N,) [m].
        flip: the flips' least turn [rad] (:data:`FLIP`).

    Returns:
        ``contact`` (bool), ``height_min_m`` (the least height at the rests, and
        ``rocked_height_min_m`` at the rocked attitudes [m]; None: none), ``flip_rad``,
        ``flips`` (samples whose rest turns more than it to a neighbour's), ``rocked_samples``, and
        ``stretches`` where the arm is below the ground: arc lengths [m], ``worst`` height
        [m], ``by`` how far in [m], ``attitude`` (``rest`` or ``rocked``) and the rock's
        ``turn_rad`` [rad] (None at a rest).
    """
    s_m = np.asarray(s, dtype=float)
    h = arm.height

    def least(x: FloatArray) -> float | None:
        return float(np.nanmin(x)) if np.isfinite(x).any() else None

    stretches = []
    for a, b, k in in_ground_runs(h):
        at_rest = bool(arm.rest[k] <= arm.rocked[k]) or not np.isfinite(arm.rocked[k])
        stretches.append(
            {
                "start_s": float(s_m[a]),
                "end_s": float(s_m[b - 1]),
                "at_s": float(s_m[k]),
                "worst": float(h[k]),
                "by": float(-h[k]),
                "attitude": "rest" if at_rest else "rocked",
                "turn_rad": None if at_rest else float(arm.turn[k]),
            }
        )
    return {
        "contact": bool(stretches),
        "height_min_m": least(arm.rest),
        "rocked_height_min_m": least(arm.rocked),
        "flip_rad": float(flip),
        "flips": int((arm.flip > flip).sum()),
        "rocked_samples": int(np.isfinite(arm.rocked).sum()),
        "stretches": stretches,
    }


def arm_ground_record(
    robot: Robot,
    terrain: Terrain,
    route: RoutePath | CirclePath,
    plan: RoutePlan | LapStage,
    poses: ArrayLike,
    s: ArrayLike,
    rocked: ArrayLike | None = None,
) -> dict[str, Any]:
    """The arm against the ground along a plan, route or lap (``summary.json``'s ``arm_ground``).

    Two postures of the arm at each sample: the plan's posture reference there
    (``reference``, :func:`reference_postures`) and the two planned postures it moves
    between (``planned``, the worse of the two, as the dense μ takes them,
    :func:`mmstab.runs.along.along_path`): the run's time law re-times the arm's moves
    against the base, so the arm may still hold the posture before.

    Args:
        robot: the robot.
        terrain: the ground.
        route: the route or lap planned.
        plan: its plan (``s``, ``postures``, ``fractions``, ``moves``).
        poses: the path's samples (N, 3) in M [m, m, rad], in driving order.
        s: their arc lengths (N,) [m].
        rocked: (N,) samples where a rock was checked, if any.

    Returns:
        ``reference`` and ``planned``: :func:`arm_ground_verdict` each.
    """
    from mmstab.runs.along import bracket

    q = np.asarray(plan.postures, dtype=float)
    s_m = np.asarray(s, dtype=float)
    ref = arm_ground_along(robot, terrain, poses, reference_postures(robot, plan, route, s_m),
                           FLIP, rocked)  # fmt: skip
    before, after = bracket(plan.s, s_m, route.closed)
    a, b = (arm_ground_along(robot, terrain, poses, q[k], FLIP, rocked) for k in (before, after))
    worse = ArmGround(
        np.fmin(a.rest, b.rest),
        np.fmin(a.rocked, b.rocked),
        np.where(np.fmin(a.rocked, b.rocked) == a.rocked, a.turn, b.turn),
        np.fmax(a.flip, b.flip),
    )
    return {
        "reference": arm_ground_verdict(ref, s_m, FLIP),
        "planned": arm_ground_verdict(worse, s_m, FLIP),
    }


#: The C twin of :func:`arm_heights`' NumPy path (``arm_heights.c``).
SOURCE = Path(__file__).with_name("arm_heights.c")


@lru_cache(maxsize=1)
def _kernel() -> Any:
    """The compiled ``mmstab_arm_heights``, or None (no C compiler: the NumPy path runs)."""
    return optional_kernel(SOURCE, "mmstab_arm_heights", [
        LONG, LONG, DOUBLES, LONG, LONGS, DOUBLES, DOUBLES, LONG, LONG, DOUBLES, DOUBLE,
        DOUBLES, DOUBLES, BYTES,
    ])  # fmt: skip


def arm_heights(
    robot: Robot,
    terrain: Terrain,
    G_T_B: ArrayLike,
    postures: ArrayLike,
    surface: ArmSurface | None = None,
    backend: Literal["c", "numpy"] = "c",
) -> FloatArray:
    """The arm's least height above the ground at N body poses (N,) [m] (< 0: in it).

    Each point of the arm's surface (:func:`mmstab.planner.ground.arm_pieces.arm_surface`)
    against the ground vertically under it (G's z less the map's bilinear height there):
    exact but for the surface's sampling (a few mm), where :class:`GroundUnderArm`'s
    measure is a lower bound (a piece's lowest point against the highest ground within a
    square about it, which on a slope is several cm below the arm). On a heightmap only
    (elsewhere every value is NaN: the planner's plane check is exact there).

    Args:
        robot: the robot.
        terrain: the ground.
        G_T_B: the body's poses in G (N, 4, 4) [m] (NaN rows: not known, NaN out).
        postures: the arm's posture at each (N, n) [rad].
        surface: the arm's surface points (default :func:`arm_surface`'s).
        backend: ``c`` (``arm_heights.c``, where a C compiler is at hand) or ``numpy``, its
            twin operation for operation (the same values to rounding).

    Returns:
        The least height per pose [m]; NaN where the arm is over an unknown cell. Beyond
        the map's edge the edge's ground is taken (as :class:`GroundUnderArm` takes it).
    """
    T = np.asarray(G_T_B, dtype=float).reshape(-1, 4, 4)
    q = np.atleast_2d(np.asarray(postures, dtype=float))
    out = np.full(len(T), np.nan)
    ok = np.isfinite(T).all(axis=(1, 2)) & np.isfinite(q).all(axis=1)
    if not ok.any() or not is_heightmap(terrain):
        return out
    surface = arm_surface(robot) if surface is None else surface
    hm = terrain.heightmap  # type: ignore[attr-defined]
    x0, x1, y0, y1 = hm.bounds
    frames = T[ok, None] @ robot.kinematics.link_frames(q[ok])  # (n, links, 4, 4) in G
    f = _kernel() if backend == "c" else None
    if f is not None:
        m = int(ok.sum())
        least_c, known_c = np.empty(m), np.empty(m, dtype=np.uint8)
        elev = np.ascontiguousarray(hm.elevation, dtype=np.float64)
        f(m, frames.shape[1], np.ascontiguousarray(frames), len(surface.link),
          np.ascontiguousarray(surface.link, dtype=np.int64),
          np.ascontiguousarray(surface.points, dtype=np.float64), elev, elev.shape[0],
          elev.shape[1], np.ascontiguousarray(hm.origin, dtype=np.float64),
          float(hm.resolution), np.asarray([x0, x1, y0, y1], dtype=np.float64), least_c,
          known_c)  # fmt: skip
        out[ok] = np.where(known_c.astype(bool), least_c, np.nan)
        return out
    least, known = np.full(int(ok.sum()), np.inf), np.ones(int(ok.sum()), dtype=bool)
    for i in np.unique(surface.link):  # one product per link: (n, 3) @ (3, points)
        pts = surface.points[surface.link == i].T
        R, t = frames[:, i, :3, :3], frames[:, i, :3, 3]
        x, y, z = (R[:, r] @ pts + t[:, r, None] for r in range(3))
        # beyond the map's edge the edge's ground, as the planner's check takes it
        x, y = np.clip(x, x0, x1), np.clip(y, y0, y1)
        ground, _, _, valid = hm.sample_rows(x, y, slopes=False)
        least = np.minimum(least, np.where(valid, (z - ground).min(axis=1), np.inf))
        known &= valid
    out[ok] = np.where(known, least, np.nan)
    return out


def arm_heights_at_rest(
    robot: Robot, terrain: Terrain, poses: ArrayLike, postures: ArrayLike
) -> FloatArray:
    """The arm's least height above the ground at the rests of base poses (N,) [m].

    Each pose rested under the arm's CoM in its posture (:func:`arm_heights`; NaN where the
    pose has no rest or the arm is over an unknown cell, or off a heightmap).

    Args:
        robot: the robot.
        terrain: the ground.
        poses: base poses (N, 3) of (x, y, yaw) in M [m, m, rad].
        postures: the arm's posture at each (N, n) [rad].
    """
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    q = np.atleast_2d(np.asarray(postures, dtype=float))
    if not is_heightmap(terrain):
        return np.full(len(P), np.nan)
    ground = terrain
    if getattr(terrain, "robot", None) is not robot:
        ground = terrain.with_robot(robot, getattr(terrain, "flipper_angle", None))
    com_B = np.atleast_2d(np.asarray(robot.overall_com(robot.arm_com(q)), dtype=float))
    G_T_B = ground.rest(P, strict=False, com_body=com_B).G_T_B  # type: ignore[attr-defined]
    return arm_heights(robot, ground, G_T_B, q)


def arm_in_ground_record(
    robot: Robot,
    terrain: Terrain,
    route: RoutePath | CirclePath,
    plan: RoutePlan | LapStage,
    poses: ArrayLike,
    s: ArrayLike,
) -> dict[str, Any] | None:
    """Where the arm on its posture reference is in the ground at rest along a plan.

    At every dense sample of the path (``summary.json``'s ``along_path.arm_in_ground``):
    the body at the sample's rest under the arm's CoM there, the arm on the plan's posture
    reference (:func:`reference_postures`, what ``track`` and ``simulate`` follow), its
    least height above the ground by :func:`arm_heights`. The planner keeps the arm
    ``planner.ground_clearance`` up at its poses (a bound, :class:`GroundUnderArm`);
    between them the ground changes under an arm moving from one planned posture to the
    next (a lap's poses 0.7 m apart over a ditch: 11 cm in the ground). A stretch in the
    ground is an arm contact: the plan's ``arm_contact`` verdict (exit status 5).

    Args:
        robot: the robot.
        terrain: the ground.
        route: the route or lap planned.
        plan: its plan (``s``, ``postures``, ``fractions``, ``moves``).
        poses: the path's samples (N, 3) of (x, y, yaw) in M [m, m, rad], in driving order.
        s: their arc lengths (N,) [m].

    Returns:
        None off a heightmap; else ``contact`` (bool), ``height_min_m`` (the least height
        [m], None: none known), ``at_s`` (where [m]), ``unknown_samples`` (the arm over an
        unknown cell, or no rest), ``surface_step_m`` and ``stretches`` in the ground:
        ``start_s``, ``end_s``, ``at_s`` [m] and ``by`` how far in [m].
    """
    if not is_heightmap(terrain):
        return None
    s_m = np.asarray(s, dtype=float)
    h = arm_heights_at_rest(robot, terrain, poses, reference_postures(robot, plan, route, s_m))
    known = np.isfinite(h)
    stretches = [{"start_s": float(s_m[a]), "end_s": float(s_m[b - 1]),
                  "at_s": float(s_m[k]), "by": float(-h[k])}
                 for a, b, k in in_ground_runs(h)]  # fmt: skip
    k = int(np.nanargmin(h)) if known.any() else None
    return {
        "contact": bool(stretches),
        "height_min_m": None if k is None else float(h[k]),
        "at_s": None if k is None else float(s_m[k]),
        "unknown_samples": int((~known).sum()),
        "surface_step_m": SURFACE_STEP,
        "stretches": stretches,
    }
