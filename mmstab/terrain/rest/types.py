"""The resting pose's settings and results (:func:`mmstab.terrain.rest.poses.rest_poses`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.terrain.heightmap import FloatArray

BoolArray = NDArray[np.bool_]


class RestSettings(NamedTuple):
    """Solver settings of :func:`rest_poses`.

    Attributes:
        max_iterations: linearise-and-solve rounds per pose.
        tol_step: stop when the attitude step is below this [rad].
        max_step: largest attitude step per round [rad].
        max_tilt: a roll or pitch beyond this means the robot tips over [rad].
        contact_tol: a candidate within this of the ground touches it [m].
        compliance: a candidate on a track's flat bottom run within this of the ground
            carries load [m]: the tracks' suspension and rubber yield that much, so the
            rigid rest's few touching points (often three) are not all that holds the
            robot up. Other candidates (arcs, flippers, chassis) carry load only when they
            touch. On a plane the bottom runs all touch, so the support is the ramp's.
        line_width: touching contacts within this of one line are a line contact [m].
        cycle_tol: a rest that neither the rounds nor the polish settled is carried by
            every candidate within this of the highest lift [m]: the triangles it rocks
            between.
        approach: Newton steps longer than this [rad] are shortened ...
        approach_factor: ... by this factor (approach the rest without overshooting it).
        coarse_spacing: the first rounds use candidates this far apart [m] ...
        coarse_tol: ... until their step is below this [rad]; then all candidates.
        active_candidates: ... or only each pose's this many highest, checked against all
            (0 = all candidates every round, the reference path).
        final_step: on the highest candidates, a Newton step below this [rad] on an
            unchanged triangle is the last (quadratic convergence puts the next below
            ``tol_step``).
        active_tol: a left-out candidate higher than the subset's highest by more than
            this [m] sends the pose to another pass.
        polish: take the rows the rounds did not settle to the potential energy's minimum
            (:mod:`mmstab.terrain.rest.polish`); ``False``: leave them as the rounds end.
        backend: ``"c"`` the compiled kernel (:mod:`mmstab.terrain.rest.kernel`, the default),
            ``"numpy"`` the vectorised NumPy path here: the same algorithm, kept as its
            independent twin (the tests hold one against the other).
    """

    max_iterations: int = 40
    tol_step: float = 1e-11
    max_step: float = 0.35
    max_tilt: float = 1.3
    contact_tol: float = 2e-4
    compliance: float = 0.02
    line_width: float = 1e-3
    cycle_tol: float = 2e-3
    approach: float = 0.02
    approach_factor: float = 0.8
    coarse_spacing: float = 0.09
    coarse_tol: float = 1e-3
    active_candidates: int = 24
    final_step: float = 1e-6
    active_tol: float = 1e-10
    polish: bool = True
    backend: str = "c"


class RestPoses(NamedTuple):
    """Resting poses of N base poses against K contact candidates.

    Attributes:
        poses: (N, 3) the queried (x, y, yaw) in G [m, m, rad].
        roll: (N,) [rad]; positive lifts the left side.
        pitch: (N,) [rad]; positive lifts the nose.
        z: (N,) G height of the body origin [m].
        G_T_B: (N, 4, 4) resting body poses in G.
        gap: (N, K) height of each candidate above the ground below it [m].
        touching: (N, K) candidates within ``contact_tol`` of the ground.
        bearing: (N, K) candidates that carry load: the touching ones and the tracks'
            bottom-run candidates within ``compliance`` of the ground; the support polygon
            is their hull.
        high_centred: (N,) the chassis touches the ground.
        line_contact: (N,) the bearing contacts lie on one line (no polygon).
        tips_over: (N,) no resting attitude within ``max_tilt``: the CoM leaves the footprint.
        converged: (N,) the attitude step fell below ``tol_step``.
        iterations: (N,) rounds used.
    """

    poses: FloatArray
    roll: FloatArray
    pitch: FloatArray
    z: FloatArray
    G_T_B: FloatArray
    gap: FloatArray
    touching: BoolArray
    bearing: BoolArray
    high_centred: BoolArray
    line_contact: BoolArray
    tips_over: BoolArray
    converged: BoolArray
    iterations: NDArray[np.int_]

    def flags(self, i: int) -> tuple[str, ...]:
        """The operator flags of pose ``i`` (empty = normal)."""
        names = ("high_centred", "line_contact", "tips_over")
        out = tuple(n for n in names if bool(getattr(self, n)[i]))
        return out if self.converged[i] or self.tips_over[i] else (*out, "not_converged")

    def contacts_G(self, points_body: ArrayLike, i: int) -> FloatArray:
        """The touching candidates of pose ``i`` in G (n, 3) [m]."""
        c = np.asarray(points_body, dtype=float)[self.touching[i]]
        T = self.G_T_B[i]
        return c @ T[:3, :3].T + T[:3, 3]

    def bearing_G(self, points_body: ArrayLike, i: int) -> FloatArray:
        """The bearing candidates of pose ``i`` in G (n, 3) [m] (their hull: the support)."""
        c = np.asarray(points_body, dtype=float)[self.bearing[i]]
        T = self.G_T_B[i]
        return c @ T[:3, :3].T + T[:3, 3]
