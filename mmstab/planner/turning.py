"""The slide limit at a route's turns (``planner.turn_slide``): postures whose turns hold.

The skid-steer model prices a turn's downhill slide per radian of heading change
(:func:`mmstab.stability.skid.turn_slide`), and where the overall CoM sits changes it: on
validation route 26 of ``make validate-routes`` (an 18.5 deg side slope, a 41 deg pivot) the
model gives 0.23 and 0.39 m/rad for the two postures chosen for stability alone, 0.17 with the
arm stowed and 0.09 with the arm reaching ahead and uphill; MuJoCo's downhill drift in that
pivot with the arm held at each: 5.0 (the planned postures), 3.0 and 2.5 cm. The most stable
posture is not the one that turns best on a side slope.

So after the search, at each turning chord (planned pose k to pose k + 1, their headings
more than :data:`TURN_MIN` apart) the planner prices the turn with the chosen postures: the
whole heading change as a pivot (the belts' speed does not change the slide per radian;
a pivot at the reference's rates turns a corner of up to 75 deg within the slide verdict's
1 s window), at the gravity of :data:`HEADINGS` headings swept across the turn at the
chord's middle, with the CoM of pose k's posture and of pose k + 1's (the posture
reference moves between them around the corner). A chord whose turn slides more than
``planner.turn_slide`` [m] constrains both poses: their eligible rows are priced on a grid of
overall CoMs (:data:`GRID` x :data:`GRID` over the rows' x, y; their lowest and highest z;
trilinear between) at the worst heading, and rows that slide more are excluded
(:attr:`mmstab.planner.candidates.NodeClearance.excluded`, as the climb limit's), unless no
stable row would remain (the pose keeps them all: the plan's slide verdict reports the
turn). Then the path is searched again. Routes whose turns hold cost nothing more than the
pricing (three model evaluations per turning chord).

The plan's slide verdict (:func:`mmstab.runs.verdict.turn_slip`, the dense path at the
closed loop's turn rate, the problem's ``physics.slip_distance``) stays the judge; this only
steers the choice toward postures that pass it, so the limit sits below the verdict's 5 cm.
The model's constants are the defaults of ``physics`` (shear modulus, drive ratio).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import RegularGridInterpolator

from mmstab.core.defaults import SECTION_DEFAULTS
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.climbing import any_stable
from mmstab.stability.drive import resolve_turn_ratio
from mmstab.stability.skid import track_patch, turn_slide
from mmstab.stability.slip import terrain_friction
from mmstab.terrain.base import Terrain

#: A chord whose headings differ by less is no turn [rad].
TURN_MIN = 0.05
#: Headings at which a turning chord's gravity is sampled (its ends and between).
HEADINGS = 3
#: Overall-CoM samples per horizontal axis of the rows' grid.
GRID = 3
#: Yaw rate the pivot is priced at [rad/s] (the slide per radian does not depend on it).
PRICE_RATE = 1.0


class TurnChord(NamedTuple):
    """A turn of the planned poses: consecutive chords turning the same way.

    Attributes:
        first: its first pose k.
        last: its last pose (k + the chords; on a loop taken modulo the poses).
        turn: its heading change [rad].
        gravity_body: gravity in B midway between its end poses, at :data:`HEADINGS`
            headings across the turn (H, 3) [m/s^2].
    """

    first: int
    last: int
    turn: float
    gravity_body: FloatArray

    def poses(self, count: int) -> list[int]:
        """The poses whose postures carry it, first to last (of ``count`` poses)."""
        return [k % count for k in range(self.first, self.last + 1)]


def turn_chords(terrain: Terrain, poses: ArrayLike, closed: bool) -> list[TurnChord]:
    """The route's turns between consecutive planned poses (module text).

    A chord (pose k to pose k + 1) turns when its headings differ by more than
    :data:`TURN_MIN`; consecutive chords turning the same way are one turn (a pivot the
    planned poses fall inside, an arc).

    Args:
        terrain: the ground.
        poses: planned base poses (K, 3) of (x [m], y [m], heading [rad]) in M.
        closed: the last pose drives on to the first.
    """
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    K = len(P)
    n = K if closed and K > 1 else K - 1
    turn = np.array(
        [np.angle(np.exp(1j * (P[(k + 1) % K, 2] - P[k, 2]))) for k in range(max(n, 0))]
    )
    sign = np.where(np.abs(turn) > TURN_MIN, np.sign(turn), 0.0)
    runs: list[list[int]] = []
    for k in range(len(sign)):
        if sign[k] == 0:
            continue
        if runs and runs[-1][-1] == k - 1 and sign[k - 1] == sign[k]:
            runs[-1].append(k)
        else:
            runs.append([k])
    if closed and len(runs) > 1 and runs[0][0] == 0 and runs[-1][-1] == n - 1:
        if sign[0] == sign[n - 1]:  # a turn across the loop's seam
            runs[0] = runs.pop() + runs[0]
    out = []
    for run in runs:
        a, b = P[run[0]], P[(run[-1] + 1) % K]
        total = float(turn[run].sum())
        f = np.linspace(0.0, 1.0, HEADINGS)
        mid = (a[:2] + b[:2]) / 2
        samples = np.c_[np.broadcast_to(mid, (HEADINGS, 2)), a[2] + f * total]
        g = np.asarray(terrain.gravity_body(samples), dtype=float)
        last = run[-1] + 1 if run[-1] + 1 > run[0] else run[-1] + 1 + K
        out.append(TurnChord(run[0], last, total, g))
    return out


class SlideLimit(NamedTuple):
    """The slide limit at a route's turns, for the search.

    Attributes:
        terrain: the ground.
        chords: the turning chords of the planned poses (:func:`turn_chords`).
        limit: the slide a turn may cost [m] (``planner.turn_slide``).
    """

    terrain: Terrain
    chords: list[TurnChord]
    limit: float


class TurnPricer:
    """The slide the model prices a chord's turn at, for overall CoMs (module text).

    Args:
        robot: the robot.
        terrain: the ground (its friction).
    """

    def __init__(self, robot: Robot, terrain: Terrain) -> None:
        physics = SECTION_DEFAULTS["physics"]
        self.robot, self.patch = robot, track_patch(robot)
        self.friction = terrain_friction(terrain)
        self.ratio = resolve_turn_ratio(robot, physics["turn_ratio"])
        self.shear = float(physics["shear_modulus"])

    def per_radian(self, gravity_body: FloatArray, com_body: FloatArray) -> FloatArray:
        """|slide per radian| of a pivot (N,) [m/rad] (NaN: beyond the cone or not settled).

        Args:
            gravity_body: gravity in B (N, 3) or (3,) [m/s^2].
            com_body: overall CoMs in B (N, 3) [m].
        """
        com = np.atleast_2d(np.asarray(com_body, dtype=float))
        g = np.broadcast_to(np.asarray(gravity_body, dtype=float), com.shape)
        n = len(com)
        ts = turn_slide(self.patch, g, com, np.zeros(n), np.full(n, PRICE_RATE), self.friction,
                        self.ratio, self.shear)  # fmt: skip
        return np.abs(np.asarray(ts.per_radian, dtype=float))

    def slide(self, chord: TurnChord, com_body: FloatArray) -> tuple[float, int]:
        """The chord's slide [m] with overall CoMs (M, 3) [m] (the worst), and its heading.

        NaN counts as sliding (beyond the friction cone: the cone's verdict).
        """
        com = np.atleast_2d(np.asarray(com_body, dtype=float))
        H = len(chord.gravity_body)
        p = self.per_radian(np.repeat(chord.gravity_body, len(com), axis=0), np.tile(com, (H, 1)))
        p = np.nan_to_num(p, nan=np.inf).reshape(H, len(com)).max(axis=1)
        worst = int(np.argmax(p))
        return float(p[worst] * abs(chord.turn)), worst

    def grid_slide(self, chord: TurnChord, heading: int, com_body: FloatArray) -> FloatArray:
        """The chord's slide [m] for many overall CoMs (N, 3) [m], from a grid (module text)."""
        com = np.asarray(com_body, dtype=float)
        lo, hi = com.min(axis=0), com.max(axis=0)
        axes = [np.linspace(lo[i], hi[i], GRID) if hi[i] - lo[i] > 1e-9 else None for i in (0, 1)]
        axes.append(np.array([lo[2], hi[2]]) if hi[2] - lo[2] > 1e-9 else None)
        if any(a is None for a in axes):  # a flat spread: price them one by one
            p = self.per_radian(chord.gravity_body[heading], com)
            return np.nan_to_num(p, nan=np.inf) * abs(chord.turn)
        X, Y, Z = np.meshgrid(*[a for a in axes if a is not None], indexing="ij")
        nodes = np.c_[X.ravel(), Y.ravel(), Z.ravel()]
        p = self.per_radian(chord.gravity_body[heading], nodes)
        p = np.nan_to_num(p, nan=1e3).reshape(X.shape)  # beyond the cone: far over any limit
        table = RegularGridInterpolator(tuple(a for a in axes if a is not None), p)
        return np.asarray(table(com)) * abs(chord.turn)


def slide_exclusions(
    robot: Robot,
    terrain: Terrain,
    chords: list[TurnChord],
    chosen_arm_com: FloatArray,
    limit: float,
    arm_com_rows: FloatArray,
    eligible: NDArray[np.bool_],
    fits: list[Any],
) -> tuple[dict[int, NDArray[np.bool_]], list[dict[str, Any]]]:
    """The rows each pose by a turn that slides with the chosen postures may not choose.

    At the poses of a chord whose turn slides more than ``limit`` with the chosen postures,
    the eligible rows whose turn would (module text).

    Args:
        robot: the robot.
        terrain: the ground.
        chords: the route's turning chords (:func:`turn_chords`).
        chosen_arm_com: the search's arm CoM at each pose, body frame (K, 3) [m].
        limit: the slide a turn may cost [m] (``planner.turn_slide``).
        arm_com_rows: the rows' arm CoMs, body frame (N, 3) [m].
        eligible: the rows any pose may choose (N,).
        fits: Eq. 6 per pose (their ``mu``).

    Returns:
        The exclusions (pose -> the eligible rows it may not choose), and per sliding chord
        a record: ``first`` pose, ``turn_rad``, ``slide_m`` with the chosen postures, the
        poses constrained.
    """
    pricer = TurnPricer(robot, terrain)
    chosen = robot.overall_com(np.asarray(chosen_arm_com, dtype=float))
    K = len(chosen)
    out: dict[int, NDArray[np.bool_]] = {}
    records: list[dict[str, Any]] = []
    rows = np.flatnonzero(eligible)
    com_rows = robot.overall_com(np.asarray(arm_com_rows, dtype=float)[rows])
    for chord in chords:
        ends = chord.poses(K)
        slide, heading = pricer.slide(chord, chosen[ends])
        if slide <= limit:
            continue
        over = pricer.grid_slide(chord, heading, com_rows) > limit
        constrained = []
        for k in ends:
            mask = out.get(k, np.zeros(len(eligible), dtype=bool)).copy()
            mask[rows[over]] = True
            if any_stable(fits[k], arm_com_rows, np.flatnonzero(eligible & ~mask)):
                out[k] = mask
                constrained.append(int(k))
        records.append({
            "first": int(chord.first), "last": int(chord.last) % K, "turn_rad": chord.turn,
            "slide_m": slide, "poses": constrained,
        })  # fmt: skip
    return out, records
