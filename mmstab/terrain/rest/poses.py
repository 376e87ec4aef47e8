"""The resting pose of a rigid tracked base lowered onto a heightmap (batched over poses).

A pose ``(x, y, yaw)`` in G fixes where the body frame's origin is seen from above and the
heading of its x axis; the ground decides the rest: the height ``z`` [m], the roll and
the pitch [rad], with ``G_R_B = Rz(yaw) Ry(-pitch) Rx(roll)`` (positive roll lifts the
left side, positive pitch lifts the nose, as ``Ramp.roll_pitch``).

**Method: lower, then tip until the supporting contacts hold the CoM.** Lowering the robot
vertically does not move a candidate point's (x, y), so for a given (roll, pitch) the body
comes to rest at ``z = max_k f_k`` with ``f_k = h(xy_k) - (G_R_B c_k)_z`` (``c_k`` the
contact candidates, ``h`` the bilinear ground): the lift point k needs to touch. Starting
level, each round

1. picks the *supporting triangle*: the three candidates whose lifted points
   ``(a_k, f_k)`` span the facet of their upper convex hull above the CoM, where ``a_k``
   is the horizontal moment arm of a vertical force at k (``-d(G_R_B c_k)_z/d(roll,
   pitch)``) and the CoM's is ``-d(G_R_B g_o)_z/d(roll, pitch)``. It is a 2-D linear
   programme (weights w >= 0 summing to one that put the CoM's arm at the contacts'
   average, maximising the average lift) solved exactly by simplex pivots on triangles;
   its weights are the contacts' load shares. If no triangle holds the CoM, the robot
   tips toward the programme's unbounded direction;
2. takes a Newton step in (roll, pitch) that brings those three candidates to the same
   lift (all touching), with the ground's slope under them (``J_k = d f_k/d(roll, pitch)``).

At the fixed point the three touch, nothing penetrates (the facet is level in f) and the
gravity line of the CoM passes through their triangle: the quasi-static rest that
explicit tipping about support edges reaches (as Oehler & von Stryk's contact estimation
for tracked robots). On a plane it is exact in a few rounds. Long steps are shortened so
the rest is approached from one side (an overshoot could tip a marginally stable robot);
a roll or pitch beyond ``max_tilt`` means the robot tips over. Where a contact on a kerb's
edge or a ditch's rim makes the rounds cycle and stop short, the pose is taken to the
minimum of the CoM's height instead (:mod:`mmstab.terrain.rest.polish`).

**Speed.** The first rounds use a sparse subset of the candidates; the rounds after that
use each pose's highest candidates only, checked against all at the end, with a re-solve
on all of them where the check fails (:func:`mmstab.terrain.rest.numpy_path.solve_active`): the
reference path's rests (``active_candidates=0``) at a fraction of the work
(``docs/terrain.md``, Speed).

**Where.** The settings and results are :mod:`mmstab.terrain.rest.types`; the C kernel's
driver is here (the kernel itself: :mod:`mmstab.terrain.rest.kernel`), the NumPy twin
:mod:`mmstab.terrain.rest.numpy_path` on the geometry of :mod:`mmstab.terrain.rest.geometry`;
:mod:`mmstab.terrain.rest.result` turns attitudes into :class:`RestPoses` (or an off-map
error).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.terrain.heightmap import FloatArray, Heightmap
from mmstab.terrain.rest.geometry import coarse_subset, footprint_corners
from mmstab.terrain.rest.kernel import KernelRests, rest_kernel
from mmstab.terrain.rest.numpy_path import numpy_rests
from mmstab.terrain.rest.polish import polish
from mmstab.terrain.rest.result import raise_off_map, rest_result
from mmstab.terrain.rest.types import RestPoses, RestSettings

__all__ = ["rest_poses"]


def rest_poses(
    heightmap: Heightmap,
    candidates: ArrayLike,
    com_body: ArrayLike,
    poses: ArrayLike,
    part: ArrayLike | None = None,
    settings: RestSettings | None = None,
    strict: bool = True,
    compliant: ArrayLike | None = None,
) -> RestPoses:
    """Resting poses of the rigid base at many poses (vectorised over poses).

    Args:
        heightmap: the ground.
        candidates: (K, 3) contact candidates in B [m] (:func:`contact_candidates`).
        com_body: overall CoM in B, (3,) or (N, 3) [m].
        poses: (3,) or (N, 3) of (x, y, yaw) in G [m, m, rad].
        part: (K,) part codes of the candidates (for ``high_centred``); ``None`` = no chassis.
        settings: solver settings (``None`` = the defaults).
        strict: raise :class:`OffMapError` if a pose needs ground off the map or on unknown
            cells; otherwise such poses come back NaN.
        compliant: (K,) the candidates that bear load within ``settings.compliance`` of the
            ground (:attr:`ContactCandidates.compliant`); ``None`` = none (rigid contacts).

    Returns:
        :class:`RestPoses` (leading axis N, also for a single pose).
    """
    settings = settings or RestSettings()
    c = np.asarray(candidates, dtype=float)
    p = np.atleast_2d(np.asarray(poses, dtype=float))
    n = p.shape[0]
    com = np.broadcast_to(np.asarray(com_body, dtype=float), (n, 3))
    coarse = coarse_subset(c, settings.coarse_spacing)
    if settings.backend == "c":
        att, f, valid, converged, tips, iterations = _rest_c(heightmap, c, coarse, com, p, settings)
    elif settings.backend == "numpy":
        att, f, valid, converged, tips, iterations = numpy_rests(
            heightmap, c, coarse, com, p, settings
        )
    else:
        raise ValueError(f"RestSettings.backend: {settings.backend!r} is not 'c' or 'numpy'")
    if settings.polish:  # the rows the rounds did not settle: V's minimum (polish.py)
        att, f, converged, tips = polish(
            heightmap, c, com, p, att, f, valid, converged, tips, settings
        )
    if strict and not valid.all():
        raise_off_map(heightmap, c, p[:, :2], p[:, 2], att, valid)
    return rest_result(c, p, att, f, valid, converged, tips, iterations, part, settings, compliant)


def _rest_c(
    hm: Heightmap,
    c: FloatArray,
    coarse: NDArray[np.int_],
    com: FloatArray,
    p: FloatArray,
    settings: RestSettings,
) -> KernelRests:
    """:func:`rest_poses`'s stages by the C kernel (one call for all poses)."""
    s = settings
    numbers = [s.max_iterations, s.tol_step, s.max_step, s.max_tilt, s.approach]
    numbers += [s.approach_factor, s.coarse_tol, s.active_candidates, s.final_step, s.active_tol]
    corners_coarse, corners = footprint_corners(c[coarse]), footprint_corners(c)
    return rest_kernel(
        hm.elevation, hm.origin, hm.resolution, c, coarse,
        corners_coarse, corners, com, p, tuple(float(x) for x in numbers),
    )  # fmt: skip
