"""The climb limit: whether the tracks can lift their front over a step they run into.

A track's flat run ends at the front in a wheel (sprocket or idler) of radius
``r = tracks.height / 2``. Driving into a step of height ``h < r`` the wheel meets the
step's edge E at height h, ``sqrt(r² − (r − h)²)`` ahead of its axle; the edge's normal
force on the wheel points from E to the axle, ``θ`` above the horizontal with
``sin θ = (r − h) / r`` (5.2° for the Cameleon's 11 cm wheels at a 10 cm kerb). The front
lifts only if the edge's traction (the driven belt pulling itself up the edge, at most
``friction`` times the edge's normal force) and the rear's push (the rear wheels' traction,
at most ``friction`` times their load) can rotate the robot about its rear contact. In the
track's plane (x_B forward, z_B up, the rear contact at x_r = −L/2 on the support plane)
with gravity ``g_B`` and the overall CoM at (x_c, z_c), the balance of forces and moments
with both tractions at their limit gives the condition (the robot climbs iff)::

    [(x_c − x_r)(−g_z) + z_c g_x] cos θ (1 + μ²) ≤ D (g_x − μ g_z),
    D = a (sin θ + μ cos θ) + h (cos θ − μ sin θ),   a = x_E − x_r,

linear in the overall CoM, so in the arm's CoM: a half-plane the planner can keep the
CoM in (``docs/climbing.md``, "The climb limit"). The step and θ come from the map: the
front wheel is rolled forward over the ground ahead (:func:`step_profile`) and the most
horizontal normal it meets is the step's. On level ground the condition reads
``x_c − x_r ≤ μ D / ((1 + μ²) cos θ)``: at the shipped 10 cm kerb (its face 78.7° steep
across one 2 cm cell, θ = 10.9°) the Cameleon's CoM may be 2.5 cm ahead of the track's
centre (the stowed arm puts it 4.9 cm ahead, the arm stretched ahead 9.6 cm).

Assumptions: quasi-static (no momentum: a robot driving at speed may bump over a step this
condition refuses), both tracks meet the step together (the track's plane,
no lateral gravity), rigid wheels, Coulomb friction. Against the whole robot in MuJoCo
crawling at 5 cm/s (``tests/physics/test_physics_climb.py``) it is conservative: it never lets
through a CoM that stalls there, and refuses some that climb (at an 8 cm kerb by 5 cm of
CoM or more).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.core.clib import BYTES, DOUBLE, DOUBLES, LONG, optional_kernel
from mmstab.model.robot import FloatArray, Robot
from mmstab.terrain.base import GRAVITY_G, Terrain

#: Spacing of the ground samples ahead of the front wheels, and the step of the wheel rolled
#: over them [m]: it sinks at most this far into an edge between two rolls, which tilts the
#: normal found by ~SAMPLE_STEP / r (0.3° at 0.5 mm; the maps' cells are 2-5 cm).
SAMPLE_STEP = 0.0005
#: A rise of the ground ahead of the front wheel below this is not a step [m] (the rough
#: ground's 3 cm bumps meet the wheel at 55° and more: never binding).
MIN_STEP = 0.02
#: The rolls' C source (:func:`_worst_contact`'s default; NumPy's loop without a compiler)
KERNEL_SOURCE = Path(__file__).with_name("climb_rolls.c")


class ClimbLimit(NamedTuple):
    """The climb condition at each pose, as a half-plane of the overall CoM in B.

    Attributes:
        step: (N,) whether a front wheel meets a step within the look-ahead.
        height: (N,) the step's edge above the support plane [m] (0 where no step).
        angle: (N,) θ, the edge normal's angle above the horizontal [rad] (π/2: no step).
        ahead: (N,) how far the robot drives until the wheel meets the edge [m].
        com_gain: (N, 2) coefficients (of x_c, z_c) of the condition
            ``com_gain · (x_c, z_c) <= com_bound`` (zero where no step).
        com_bound: (N,) its right-hand side (+inf where no step; -inf where no CoM climbs).
    """

    step: np.ndarray
    height: FloatArray
    angle: FloatArray
    ahead: FloatArray
    com_gain: FloatArray
    com_bound: FloatArray

    def climbs(self, com_body: ArrayLike) -> np.ndarray:
        """Whether the overall CoM (N, 3) or (3,) in B [m] satisfies the condition, per pose."""
        return self.keeps(np.arange(len(self.step)), com_body)

    def keeps(self, k: int | NDArray[np.intp], com_body: ArrayLike) -> np.ndarray:
        """Whether overall CoMs (M, 3) in B [m] lie in pose ``k``'s half-plane (k: (M,) or one)."""
        c = np.atleast_2d(np.asarray(com_body, dtype=float))
        gain, bound = self.com_gain[k], self.com_bound[k]
        return np.asarray(gain[..., 0] * c[:, 0] + gain[..., 1] * c[:, 2] <= bound)


def step_profile(
    robot: Robot, terrain: Terrain, G_T_B: ArrayLike, lookahead: float
) -> tuple[FloatArray, FloatArray]:
    """The ground ahead of each front wheel in B: forward offsets and heights (N, 2, S) [m].

    Samples along both tracks' centre lines from the front axle to ``r + lookahead`` ahead
    of it (``lookahead`` [m]), each the terrain's surface under the point, written in the
    resting body frame ``G_T_B`` (N, 4, 4): (x_B − L/2, z_B). NaN off the map (outside
    ``terrain.bounds``).
    """
    G_T_B = np.asarray(G_T_B, dtype=float).reshape(-1, 4, 4)
    t = robot.base.tracks
    r = t.height / 2
    u = np.arange(SAMPLE_STEP, r + lookahead + 1e-12, SAMPLE_STEP)
    side = np.array([t.separation / 2, -t.separation / 2])
    pts_B = np.zeros((2, len(u), 4))
    pts_B[..., 0], pts_B[..., 1], pts_B[..., 3] = t.length / 2 + u, side[:, None], 1.0
    M_T_B = np.linalg.inv(terrain.G_T_M()) @ G_T_B
    pts_M = np.einsum("nij,ksj->nksi", M_T_B, pts_B)
    x, y, box = pts_M[..., 0], pts_M[..., 1], terrain.bounds
    off = np.zeros(x.shape, bool)
    if box is not None:  # past the map's edge (a route ending near it): NaN, not an error
        off = (x < box[0]) | (x > box[1]) | (y < box[2]) | (y > box[3])
        x, y = np.clip(x, box[0], box[1]), np.clip(y, box[2], box[3])
    ground_G = terrain.surface_G(x, y)  # (N, 2, S, 3)
    ground_G[off] = np.nan
    ones = np.ones((*ground_G.shape[:-1], 1))
    ground_B = np.einsum(
        "nij,nksj->nksi", np.linalg.inv(G_T_B), np.concatenate([ground_G, ones], -1)
    )
    return ground_B[..., 0] - t.length / 2, ground_B[..., 2]


def _worst_contact(
    z: FloatArray, rolls: int, r: float, backend: Literal["c", "numpy"] = "c"
) -> tuple[float, float]:
    """The most horizontal contact normal met rolling the front wheels ahead.

    The samples z (2, S) [m] lie at u_j = (j + 1) ``SAMPLE_STEP`` ahead of the axle; the
    wheel rolled s_k = k ``SAMPLE_STEP`` ahead (k < ``rolls``) rests on the highest of the
    plane (centre at r) and the samples within r of it (centre z_j + sqrt(r² − (u_j − s_k)²),
    a window of samples about k); the normal at the touching sample rises θ above the
    horizontal, sin θ = (centre − z_j) / r.

    A roll whose centre stays at or below r rests on the plane (sin θ = 1): a sample lifts
    the wheel above r only if it lies above the plane and within
    ``sqrt(r² − (r − z_j)²)`` of the wheel (:func:`_lifted_rolls`), so only the rolls
    near such samples are computed; the others are 1 as the whole computation gives. The
    rolls computed run in C (``climb_rolls.c``; at a kerb higher than the wheel's radius
    every roll is, about a million sums: 15 ms in NumPy on a live map); ``backend="numpy"``,
    or no compiler, runs its NumPy twin.

    Returns:
        (the smallest sin θ over both tracks and every roll; the roll where it occurs [m]).
    """
    w = int(np.ceil(r / SAMPLE_STEP))
    offset = np.arange(-w, w + 1) * SAMPLE_STEP  # u_j - s_k over the window
    lift = np.where(np.abs(offset) < r, np.sqrt(np.maximum(r**2 - offset**2, 0.0)), -np.inf)
    pad = np.full((2, w + 1), -np.inf)
    zpad = np.concatenate([pad, z, pad], axis=1)  # window k holds samples k - w - 1 ...
    windows = np.lib.stride_tricks.sliding_window_view(zpad, 2 * w + 1, axis=1)[:, :rolls]
    R = int(windows.shape[1])  # the rolls (fewer where the samples end first)
    sin_roll = np.ones((2, R))
    at = _lifted_rolls(z, R, r, w) if lift.max() <= r else np.ones((2, R), bool)
    f = _kernel() if backend == "c" else None
    if f is not None:
        f(zpad.shape[1], 2 * w + 1, np.ascontiguousarray(zpad), lift, R,
          np.ascontiguousarray(at, dtype=np.uint8), float(r), sin_roll)  # fmt: skip
        m = int(sin_roll.argmin())
        return float(sin_roll.ravel()[m]), float((m % R) * SAMPLE_STEP)
    t, k = np.nonzero(at)
    centre = windows[t, k] + lift  # (rolls computed, 2w + 1)
    j = centre.argmax(axis=-1)
    top = centre[np.arange(len(j)), j]
    touch = zpad[t, k + j]  # the window's j-th sample
    # a sample at or above the centre pushes the wheel down: a wall (sin θ <= 0, no climb);
    # with no ground in the window (off the map: -inf) top - touch is NaN but unused
    with np.errstate(invalid="ignore"):
        sin_roll[at] = np.where(top <= r, 1.0, np.clip((top - touch) / r, -1.0, 1.0))
    m = int(sin_roll.argmin())
    return float(sin_roll.ravel()[m]), float((m % R) * SAMPLE_STEP)


@lru_cache(maxsize=1)
def _kernel() -> Any:
    """The compiled ``mmstab_climb_rolls``, or None (no C compiler: the NumPy path runs)."""
    args = [LONG, LONG, DOUBLES, DOUBLES, LONG, BYTES, DOUBLE, DOUBLES]
    return optional_kernel(KERNEL_SOURCE, "mmstab_climb_rolls", args)


def _lifted_rolls(z: FloatArray, rolls: int, r: float, w: int) -> NDArray[np.bool_]:
    """Which rolls (2, ``rolls``) a sample of z (2, S) [m] may lift above r (the others not).

    A sample at or below the plane (z ≤ 0) adds at most r (every lift is at most r); one
    above it at z < r lifts the wheel above r only within ``sqrt(r² − (r − z)²)`` of it (the
    lift's circle), two samples (1 mm) more for round-off; one at r or higher (or NaN)
    anywhere in the window. Sample j lies in roll k's window ``(j + 1 − k)`` samples from
    its middle; w: the window's half-width [samples].
    """
    reach = np.full(z.shape, -1, dtype=np.intp)  # half-width in samples, -1: lifts nowhere
    up = ~(z <= 0.0)  # NaN too
    zu = z[up]
    below = zu < r  # the others: anywhere in the window
    half = np.sqrt(np.maximum(r**2 - (r - np.where(below, zu, r)) ** 2, 0.0)) / SAMPLE_STEP
    reach[up] = np.where(below, np.floor(half).astype(np.intp) + 2, w + 1)
    out = np.zeros((2, rolls), dtype=bool)
    for t in range(2):
        j = np.flatnonzero(reach[t] >= 0)
        if not j.size:
            continue
        lo = np.clip(j + 1 - reach[t, j], 0, rolls)
        hi = np.clip(j + 2 + reach[t, j], 0, rolls)  # exclusive
        mark = np.bincount(lo, minlength=rolls + 1) - np.bincount(hi, minlength=rolls + 1)
        out[t] = np.cumsum(mark[:rolls]) > 0
    return out


def climb_limit(
    robot: Robot, terrain: Terrain, poses: ArrayLike, friction: float, lookahead: float
) -> ClimbLimit:
    """The climb condition (module text) at resting poses (x [m], y [m], yaw [rad]) (N, 3).

    Args:
        robot: the robot (its tracks' length and height).
        terrain: the ground.
        poses: base poses in M.
        friction: Coulomb friction of the tracks on the ground [-].
        lookahead: how far ahead of the front wheel a step counts [m] (the distance the
            robot drives on the posture chosen here: the spacing of planned poses).
    """
    p = np.atleast_2d(np.asarray(poses, dtype=float))
    t, n = robot.base.tracks, len(p)
    r, L, mu = t.height / 2, t.length, float(friction)
    G_T_B = np.asarray(terrain.G_T_B(p)).reshape(n, 4, 4)  # one rest solve for everything
    du, z = step_profile(robot, terrain, G_T_B, lookahead)  # (N, 2, S)
    z = np.where(np.isfinite(z), z, -np.inf)  # off the map: no ground to meet
    rolls = int(np.floor(lookahead / SAMPLE_STEP + 1e-9)) + 1
    sin_t, ahead = np.ones(n), np.full(n, np.inf)
    for i in range(n):  # one pose at a time: (2, rolls, samples) each
        sin_t[i], ahead[i] = _worst_contact(z[i], rolls, r)
    h = r * (1.0 - sin_t)  # the edge's height above the wheel's support
    wall = sin_t <= 0.0  # touched at or above the axle: no front wheel climbs it
    step = (h > MIN_STEP) | wall
    sin_t = np.where(step, np.maximum(sin_t, 0.0), 1.0)
    h = np.minimum(h, r)
    cos_t = np.sqrt(1.0 - sin_t**2)
    a = L + r * cos_t  # the edge ahead of the rear contact, x_E - x_r
    D = a * (sin_t + mu * cos_t) + h * (cos_t - mu * sin_t)
    g = GRAVITY_G @ G_T_B[:, :3, :3]  # gravity in B: R_GB^T g_G per pose
    k = cos_t * (1 + mu**2)
    gain = np.stack([-g[:, 2] * k, g[:, 0] * k], axis=1)
    bound = D * (g[:, 0] - mu * g[:, 2]) - gain[:, 0] * L / 2  # x_c - x_r = x_c + L / 2
    return ClimbLimit(
        step=step,
        height=np.where(wall, np.inf, np.where(step, h, 0.0)),
        angle=np.where(step, np.arcsin(sin_t), np.pi / 2),
        ahead=np.where(step, np.maximum(ahead, 0.0), np.inf),
        com_gain=np.where(step[:, None], gain, 0.0),
        com_bound=np.where(wall, -np.inf, np.where(step, bound, np.inf)),
    )
