"""The slide limit at a route's turns (``planner.turn_slide``): postures whose turns hold.

The skid-steer model prices a turn's downhill slide per radian of heading change
(:func:`mmstab.stability.skid.turn_slide`), and where the overall CoM sits changes it: on
validation route 26 of ``make validate-routes`` (an 18.5 deg side slope, a 41 deg pivot) the
model gives 0.23 and 0.39 m/rad for the two postures chosen for stability alone, 0.17 with the
arm stowed and 0.09 with the arm reaching ahead and uphill; MuJoCo's downhill drift in that
pivot with the arm held at each: 5.0 (the planned postures), 3.0 and 2.5 cm. The most stable
posture is not the one that turns best on a side slope.

So after the search, at each turn of the planned poses (:func:`turn_chords`: consecutive
chords, pose k to pose k + 1, whose headings differ by more than :data:`TURN_MIN` and turn
the same way; a pivot the poses fall inside is one turn) the planner prices the turn with
the chosen postures: the whole heading change as a pivot (the belts' speed does not change
the slide per radian; a pivot at the reference's rates turns a corner of up to 75 deg
within the slide verdict's 1 s window), at the gravity of :data:`HEADINGS` headings swept
across the turn midway between its end poses, with the CoMs of its poses' postures (the
posture reference moves between them around the corner). A turn that slides more than
``planner.turn_slide`` [m] constrains its poses: their eligible rows are priced on a grid of
overall CoMs (:data:`GRID` x :data:`GRID` over the rows' x, y; their lowest and highest z;
trilinear between) at the worst heading, and rows that slide more are excluded
(:attr:`mmstab.planner.candidates.NodeClearance.excluded`, as the climb limit's), unless no
stable row would remain (the pose keeps them all: the plan's slide verdict reports the
turn). Then the path is searched again. The turns are priced in one evaluation of the model,
the grids of the sliding ones in another (its Newton iterations shared: about as long as
one turn's); routes whose turns hold cost only the first.

The plan's slide verdict (:func:`mmstab.runs.verdict.turn_slip`, the dense path at the
closed loop's turn rate, the problem's ``physics.slip_distance``) stays the judge; this only
steers the choice toward postures that pass it, so the limit sits below the verdict's 5 cm.
The model's constants are the problem's (``physics.shear_modulus``, ``physics.turn_ratio``:
:attr:`mmstab.planner.PlannerSettings.slide_model`), as the verdict's.
"""

from __future__ import annotations

import ctypes
import functools
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import map_coordinates

from mmstab.core.clib import DOUBLE, DOUBLES, LONG, LONGS, compiled_library
from mmstab.core.files import MmstabError
from mmstab.core.masks import true_runs
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.climbing import any_stable
from mmstab.planner.settings import DEFAULT_SLIDE_MODEL
from mmstab.stability.drive import resolve_turn_ratio
from mmstab.stability.skid import track_patch, turn_slide
from mmstab.stability.slip import terrain_friction
from mmstab.terrain.base import Terrain, wrap_angle

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
    k = np.arange(K if closed and K > 1 else max(K - 1, 0))
    turn = wrap_angle(P[(k + 1) % K, 2] - P[k, 2])
    sign = np.where(np.abs(turn) > TURN_MIN, np.sign(turn), 0.0)
    runs = sorted(list(range(a, b)) for s in (1.0, -1.0) for a, b in true_runs(sign == s))
    n = len(k)
    if closed and len(runs) > 1 and runs[0][0] == 0 and runs[-1][-1] == n - 1:
        if sign[0] == sign[n - 1]:  # a turn across the loop's seam
            runs[0] = runs.pop() + runs[0]
    if not runs:
        return []
    f = np.linspace(0.0, 1.0, HEADINGS)
    totals = [float(turn[run].sum()) for run in runs]
    samples = np.vstack([
        np.c_[np.broadcast_to((P[run[0], :2] + P[(run[-1] + 1) % K, :2]) / 2, (HEADINGS, 2)),
              P[run[0], 2] + f * total]
        for run, total in zip(runs, totals, strict=True)
    ])  # fmt: skip
    g = np.asarray(terrain.gravity_body(samples), dtype=float).reshape(len(runs), HEADINGS, 3)
    # a run across the seam ends past the last pose: its last pose index counts on from K
    return [
        TurnChord(run[0], run[-1] + 1 + (K if run[-1] < run[0] else 0), total, gk)
        for run, total, gk in zip(runs, totals, g, strict=True)
    ]


class SlideLimit(NamedTuple):
    """The slide limit at a route's turns, for the search.

    Attributes:
        terrain: the ground.
        chords: the turning chords of the planned poses (:func:`turn_chords`).
        limit: the slide a turn may cost [m] (``planner.turn_slide``).
        model: the skid-steer model's constants (:class:`TurnPricer`); None: the defaults.
    """

    terrain: Terrain
    chords: list[TurnChord]
    limit: float
    model: tuple[float, float | str] | None = None


class TurnPricer:
    """The slide the model prices a chord's turn at, for overall CoMs (module text).

    Args:
        robot: the robot.
        terrain: the ground (its friction).
        model: the belts' shear modulus [m] and the drive ratio (a number or ``auto``):
            ``physics.shear_modulus``, ``physics.turn_ratio``
            (:attr:`mmstab.planner.PlannerSettings.slide_model`); default their defaults.
    """

    def __init__(
        self, robot: Robot, terrain: Terrain, model: tuple[float, float | str] | None = None
    ) -> None:
        shear, ratio = DEFAULT_SLIDE_MODEL if model is None else model
        self.robot, self.patch = robot, track_patch(robot)
        self.friction = terrain_friction(terrain)
        self.ratio = resolve_turn_ratio(robot, ratio)
        self.shear = float(shear)

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

    def slides(
        self, chords: list[TurnChord], com_body: list[FloatArray]
    ) -> list[tuple[float, int]]:
        """Each turn's slide [m] with its overall CoMs (M, 3) [m] (the worst), and its heading.

        All turns in one evaluation of the model (its iterations shared). NaN counts as
        sliding (beyond the friction cone: the cone's verdict).
        """
        coms = [np.atleast_2d(np.asarray(c, dtype=float)) for c in com_body]
        g = [np.repeat(t.gravity_body, len(c), axis=0) for t, c in zip(chords, coms, strict=True)]
        c = [np.tile(c, (len(t.gravity_body), 1)) for t, c in zip(chords, coms, strict=True)]
        if not g:
            return []
        p = np.nan_to_num(self.per_radian(np.vstack(g), np.vstack(c)), nan=np.inf)
        out, at = [], 0
        for t, com in zip(chords, coms, strict=True):
            H = len(t.gravity_body)
            worst = p[at : at + H * len(com)].reshape(H, len(com)).max(axis=1)
            at += H * len(com)
            h = int(np.argmax(worst))
            out.append((float(worst[h] * abs(t.turn)), h))
        return out

    def slide(self, chord: TurnChord, com_body: FloatArray) -> tuple[float, int]:
        """:meth:`slides` of one turn."""
        return self.slides([chord], [com_body])[0]

    def grid_slides(
        self, chords: list[TurnChord], headings: list[int], com_body: FloatArray
    ) -> list[FloatArray]:
        """Each turn's slide [m] for many overall CoMs (N, 3) [m], from a grid (module text).

        The grids of all turns in one evaluation of the model; trilinear between its nodes
        (the nodes span the CoMs' extent; an axis the CoMs do not spread along has one).
        """
        com = np.asarray(com_body, dtype=float)
        if not chords:
            return []
        axes = _grid_axes(com.min(axis=0), com.max(axis=0))
        tables = self._tables(chords, headings, axes)
        # each CoM's place on the grid in nodes (an axis of one node: 0), trilinear between
        at = np.stack([(com[:, i] - a[0]) / (a[1] - a[0]) if len(a) > 1 else np.zeros(len(com))
                       for i, a in enumerate(axes)])  # fmt: skip
        return [
            map_coordinates(table, at, order=1, mode="nearest") * abs(t.turn)
            for t, table in zip(chords, tables, strict=True)
        ]

    def grid_slides_of_rows(
        self, chords: list[TurnChord], headings: list[int], arm_com: FloatArray,
        rows: NDArray[np.intp],
    ) -> list[FloatArray]:  # fmt: skip
        """:meth:`grid_slides` of the overall CoMs of arm CoMs ``arm_com[rows]`` (N, 3) [m] in B.

        In C (``turning.c``: the overall CoMs, their extent and the trilinear read, two
        passes over the rows and no temporaries; 260k rows a route), else in NumPy. The twins
        agree to round-off (``tests/planner/test_turn_slide.py``).
        """
        kernels = _turn_kernels()
        robot = self.robot
        if kernels is None or not chords or not len(rows):
            return self.grid_slides(chords, headings, robot.overall_com(arm_com[rows]))
        extent, trilinear = kernels
        arm = np.ascontiguousarray(arm_com, dtype=float)
        at = np.ascontiguousarray(rows, dtype=np.int64)
        masses = np.array([robot.arm_mass, robot.base.mass], dtype=float)
        base = np.ascontiguousarray(robot.base.com, dtype=float)
        total = float(robot.total_mass)
        lo, hi = np.empty(3), np.empty(3)
        extent(len(at), at, arm, masses, base, total, lo, hi)
        axes = _grid_axes(lo, hi)
        tables = np.ascontiguousarray(self._tables(chords, headings, axes), dtype=float)
        nodes = np.array([len(a) for a in axes], dtype=np.int64)
        a0 = np.array([a[0] for a in axes], dtype=float)
        da = np.array([a[1] - a[0] if len(a) > 1 else 1.0 for a in axes], dtype=float)
        scale = np.array([abs(t.turn) for t in chords], dtype=float)
        out = np.empty((len(chords), len(at)))
        trilinear(len(at), at, arm, masses, base, total, len(chords), tables, nodes, a0, da,
                  scale, out)  # fmt: skip
        return list(out)

    def _tables(
        self, chords: list[TurnChord], headings: list[int], axes: list[FloatArray]
    ) -> FloatArray:
        """Each turn's slide per radian [m/rad] on the grid's nodes (C, n_x, n_y, n_z)."""
        nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        g = [
            np.broadcast_to(t.gravity_body[h], nodes.shape)
            for t, h in zip(chords, headings, strict=True)
        ]
        p = self.per_radian(np.vstack(g), np.tile(nodes, (len(chords), 1)))
        p = np.nan_to_num(p, nan=1e3)  # beyond the cone: far over any limit
        return p.reshape(len(chords), *(len(a) for a in axes))

    def grid_slide(self, chord: TurnChord, heading: int, com_body: FloatArray) -> FloatArray:
        """:meth:`grid_slides` of one turn."""
        return self.grid_slides([chord], [heading], com_body)[0]


def _grid_axes(lo: FloatArray, hi: FloatArray) -> list[FloatArray]:
    """The grid's nodes along each axis over the CoMs' extent ``lo`` .. ``hi`` (3,) [m]."""
    counts = [GRID, GRID, 2]
    return [np.linspace(lo[i], hi[i], n) if hi[i] - lo[i] > 1e-9 else lo[i : i + 1]
            for i, n in enumerate(counts)]  # fmt: skip


@functools.lru_cache(maxsize=1)
def _turn_kernels() -> tuple[Any, Any] | None:
    """The compiled ``turning.c`` (its extent and trilinear read), or None (no C compiler)."""
    try:
        lib = ctypes.CDLL(str(compiled_library(Path(__file__).with_name("turning.c"), "turning")))
    except (MmstabError, OSError):
        return None
    extent, trilinear = lib.mmstab_turn_extent, lib.mmstab_turn_trilinear
    extent.argtypes = [LONG, LONGS, DOUBLES, DOUBLES, DOUBLES, DOUBLE, DOUBLES, DOUBLES]
    trilinear.argtypes = [LONG, LONGS, DOUBLES, DOUBLES, DOUBLES, DOUBLE, LONG, DOUBLES, LONGS,
                          DOUBLES, DOUBLES, DOUBLES, DOUBLES]  # fmt: skip
    for f in (extent, trilinear):
        f.restype = ctypes.c_int
    return extent, trilinear


def slide_exclusions(
    robot: Robot,
    terrain: Terrain,
    chords: list[TurnChord],
    chosen_arm_com: FloatArray,
    limit: float,
    arm_com_rows: FloatArray,
    eligible: NDArray[np.bool_],
    fits: list[Any],
    model: tuple[float, float | str] | None = None,
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
        model: the skid-steer model's constants (:class:`TurnPricer`); None: the defaults.

    Returns:
        The exclusions (pose -> the eligible rows it may not choose), and per sliding chord
        a record: ``first`` pose, ``turn_rad``, ``slide_m`` with the chosen postures, the
        poses constrained.
    """
    pricer = TurnPricer(robot, terrain, model)
    chosen = robot.overall_com(np.asarray(chosen_arm_com, dtype=float))
    K = len(chosen)
    out: dict[int, NDArray[np.bool_]] = {}
    records: list[dict[str, Any]] = []
    priced = pricer.slides(chords, [chosen[t.poses(K)] for t in chords])
    sliding = [(t, h, x) for t, (x, h) in zip(chords, priced, strict=True) if x > limit]
    if not sliding:
        return out, records
    rows = np.flatnonzero(eligible)
    grids = pricer.grid_slides_of_rows(
        [t for t, _, _ in sliding], [h for _, h, _ in sliding], arm_com_rows, rows
    )
    for (chord, _, slide), grid in zip(sliding, grids, strict=True):
        ends = chord.poses(K)
        over = grid > limit
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
