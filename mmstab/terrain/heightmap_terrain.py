"""A heightmap as a :class:`~mmstab.terrain.base.Terrain`: poses in G, resting poses.

The map frame M is G itself. A base pose ``(x, y, yaw)`` [m, m, rad] puts the body
origin above (x, y) with the body x axis heading ``yaw`` about G's z; the ground decides
the rest (:mod:`mmstab.terrain.rest`). The resting pose depends on the robot (its contact
candidates and its centre of mass), so a terrain is bound to one robot, flipper angle and
arm posture with :meth:`HeightmapTerrain.with_robot` before it answers pose queries.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, NamedTuple

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.robot import Robot
from mmstab.model.robot import with_flipper_angle as robot_with_flipper_angle
from mmstab.terrain.base import DEFAULT_FRICTION, GRAVITY_G, Support, as_poses, place_local
from mmstab.terrain.contacts import ContactCandidates, contact_candidates
from mmstab.terrain.heightmap import FloatArray, Heightmap
from mmstab.terrain.polygon import support_vertices
from mmstab.terrain.rest import RestPoses, RestSettings, rest_poses

#: Each robot's contact candidates by (its id, the flipper angle), the robot kept with them.
_CANDIDATES: dict[tuple[int, float | None], tuple[Robot | None, ContactCandidates]] = {}
#: Each robot's overall CoM with the arm stowed in B [m], likewise.
_STOWED_COM: dict[tuple[int, float | None], tuple[Robot | None, FloatArray]] = {}
#: Batches of at least this many poses are kept (:meth:`HeightmapTerrain.rest`): a run's
#: reference, timing, checks and summary each ask the rests of the same samples (a 75 s
#: MuJoCo run asked 18706 rests three times, 0.5-0.7 s each).
_KEEP_ROWS = 1000
#: How many such batches a terrain keeps (the most recent).
_KEEP_BATCHES = 2


def with_flipper_angle(robot: Robot, angle: float | None) -> Robot:
    """The robot with its flippers at ``angle`` [rad] (``None``: unchanged)."""
    return robot if angle is None else robot_with_flipper_angle(robot, angle)


class LocalPlane(NamedTuple):
    """The resting pose at one base pose, as a plane the controller can use locally.

    Attributes:
        pose: the base pose (x, y, yaw) in G [m, m, rad].
        roll: [rad]. pitch: [rad]. z: G height of the body origin [m].
        normal: the body's z axis in G (3,) (the plane's upward normal).
        G_T_B: the resting pose (4, 4).
    """

    pose: FloatArray
    roll: float
    pitch: float
    z: float
    normal: FloatArray
    G_T_B: FloatArray


@dataclasses.dataclass(frozen=True, eq=False)
class HeightmapTerrain:
    """A heightmap ground (``kind = "heightmap"``).

    Attributes:
        heightmap: the elevation grid.
        robot: the robot standing on it (``None`` until :meth:`with_robot`).
        flipper_angle: flipper angle used for the contacts [rad] (``None`` = the robot's).
        arm_q: arm posture whose CoM loads the base (4,) [rad] (``None`` = stowed).
        settings: resting-pose solver settings.
        reference: the pose whose resting plane :meth:`place_sx` uses (``None`` = the map
            centre, heading +x).
        friction: Coulomb friction coefficient of the tracks on this ground [-].
    """

    heightmap: Heightmap
    robot: Robot | None = None
    flipper_angle: float | None = None
    arm_q: FloatArray | None = None
    settings: RestSettings = RestSettings()
    reference: FloatArray | None = None
    friction: float = DEFAULT_FRICTION
    kind: str = "heightmap"

    # ---------------------------------------------------------------------- binding
    def with_robot(
        self, robot: Robot, flipper_angle: float | None = None, arm_q: ArrayLike | None = None
    ) -> HeightmapTerrain:
        """This ground with a robot (flipper angle [rad], arm posture (4,) [rad]) on it."""
        q = None if arm_q is None else np.asarray(arm_q, dtype=float)
        return dataclasses.replace(self, robot=robot, flipper_angle=flipper_angle, arm_q=q)

    def at(self, pose: ArrayLike) -> HeightmapTerrain:
        """This ground with :meth:`place_sx` linearised at ``pose`` (x, y, yaw) in G."""
        return dataclasses.replace(self, reference=np.asarray(pose, dtype=float))

    def _robot(self) -> Robot:
        if self.robot is None:
            raise MmstabError(
                f"{self.heightmap.source}: a heightmap terrain needs a robot for resting "
                "poses (HeightmapTerrain.with_robot)"
            )
        return with_flipper_angle(self.robot, self.flipper_angle)

    @functools.cached_property
    def candidates(self) -> ContactCandidates:
        """Contact candidates of the bound robot in B.

        They depend on the robot and the flipper angle only: kept per robot, so a new map
        under the same robot (the online loop's every map) does not compute them again.
        """
        key = (id(self.robot), self.flipper_angle)
        kept = _CANDIDATES.get(key)
        if kept is None or kept[0] is not self.robot:
            cand = contact_candidates(self._robot().base)
            for a in cand:  # shared from now on: read-only
                a.setflags(write=False)
            kept = _CANDIDATES[key] = (self.robot, cand)
        return kept[1]

    @functools.cached_property
    def com_body(self) -> FloatArray:
        """Overall CoM of the bound robot in B [m] (base + arm at ``arm_q``).

        With the arm stowed kept per robot and flipper angle, as the contact candidates.
        """
        if self.arm_q is None:
            key = (id(self.robot), self.flipper_angle)
            kept = _STOWED_COM.get(key)
            if kept is None or kept[0] is not self.robot:
                r = self._robot()
                com = np.asarray(r.overall_com(r.arm_com(r.stowed)), dtype=float)
                com.setflags(write=False)
                kept = _STOWED_COM[key] = (self.robot, com)
            return kept[1]
        r = self._robot()
        return np.asarray(r.overall_com(r.arm_com(self.arm_q)), dtype=float)

    # ---------------------------------------------------------------- Terrain interface
    @property
    def label(self) -> str:
        """``heightmap NAME (nx x ny cells of R m)``, for figure titles."""
        ny, nx = self.heightmap.shape
        name = getattr(self.heightmap, "source", "")
        return f"heightmap {name} ({nx} x {ny} cells of {self.heightmap.resolution:g} m)"

    def local_ground(self, poses: ArrayLike) -> FloatArray:
        """``(z [m], roll [rad], pitch [rad])`` of the resting poses, (N, 3)."""
        r = self.rest(as_poses(poses))
        return np.stack([r.z, r.roll, r.pitch], axis=1)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` [m] of the map (its cell centres' rectangle)."""
        return self.heightmap.bounds

    def surface_G(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Ground points in G under (x, y) [m] (bilinear heights), (..., 3)."""
        xb, yb = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        z = self.heightmap.height(np.stack([xb.ravel(), yb.ravel()], axis=1)).reshape(xb.shape)
        return np.stack([xb, yb, z], axis=-1)

    def height_grid_M(self, x: FloatArray, y: FloatArray) -> FloatArray:
        """The ground's z [m] at x (n,) [m] times y (m,) [m] (M is G): (m, n).

        :meth:`surface_G`'s heights (:meth:`Heightmap.height_grid`: a lattice costs its rows).
        """
        return self.heightmap.height_grid(x, y)

    def rest(
        self, poses: ArrayLike, strict: bool = True, com_body: ArrayLike | None = None
    ) -> RestPoses:
        """Resting poses, batched (see :func:`mmstab.terrain.rest.rest_poses`).

        Args:
            poses: (3,) or (N, 3) of (x, y, yaw) in G [m, m, rad].
            strict: raise for ground off the map or unknown (else NaN rows).
            com_body: the overall CoM in B, (3,) or (N, 3) [m] (``None``: the bound
                robot's, :attr:`com_body`): each state rests under its own load.

        A batch of ``_KEEP_ROWS`` poses or more is kept: the same poses under the same load
        (and ``strict``) again give the same, read-only :class:`RestPoses`.
        """
        p = np.asarray(poses, dtype=float)
        key = None
        if p.ndim == 2 and p.shape[0] >= _KEEP_ROWS:  # same poses, same load: the same rests
            com_key = None if com_body is None else np.asarray(com_body, dtype=float)
            key = (p.shape, p.tobytes(), strict) + (
                () if com_key is None else (com_key.shape, com_key.tobytes())
            )
            kept = self._kept_rests.get(key)
            if kept is not None:
                return kept
        c = self.candidates
        com = self.com_body if com_body is None else com_body
        r = rest_poses(self.heightmap, c.points, com, p, c.part, self.settings, strict, c.compliant)
        if key is not None:
            for a in r:  # shared with the next caller of the same batch: read-only
                a.setflags(write=False)
            self._kept_rests[key] = r
            while len(self._kept_rests) > _KEEP_BATCHES:
                del self._kept_rests[next(iter(self._kept_rests))]
        return r

    @functools.cached_property
    def _kept_rests(self) -> dict[tuple[Any, ...], RestPoses]:
        """The rests of the last :data:`_KEEP_BATCHES` large batches solved, oldest first.

        A batch of 18706 poses against 390 candidates holds about 75 MB (its ``gap`` and
        flags); the terrain keeps two.
        """
        return {}

    def G_T_M(self) -> FloatArray:
        """The map frame is G."""
        return np.eye(4)

    def M_T_B(self, poses: ArrayLike) -> FloatArray:
        """Resting body poses: (4, 4) for one pose, (N, 4, 4) for many."""
        p = np.asarray(poses, dtype=float)
        T = self.rest(p).G_T_B
        return T[0] if p.ndim == 1 else T

    def G_T_B(self, poses: ArrayLike) -> FloatArray:
        """Resting body poses in G (= M)."""
        return self.M_T_B(poses)

    def gravity_body(self, poses: ArrayLike) -> FloatArray:
        """Gravity in the body at the resting poses, (N, 3) [m/s^2]."""
        T = self.rest(np.atleast_2d(np.asarray(poses, dtype=float))).G_T_B
        return np.einsum("nji,j->ni", T[:, :3, :3], GRAVITY_G)

    def place(self, poses: ArrayLike, points_body: ArrayLike) -> FloatArray:
        """Body points (3,) or (N, 3) placed in G at the resting poses -> (N, 3) [m].

        The one placement (:func:`mmstab.terrain.place_local`) with the local ground.
        """
        P = as_poses(poses)
        return place_local(P, self.local_ground(P), points_body).points

    def local_plane(self, pose: ArrayLike) -> LocalPlane:
        """The resting pose at one pose, for export to a controller (per-step ground data)."""
        p = np.asarray(pose, dtype=float)
        r = self.rest(p)
        T = r.G_T_B[0]
        return LocalPlane(p, float(r.roll[0]), float(r.pitch[0]), float(r.z[0]), T[:3, 2], T)

    def place_sx(self, pose: ca.SX, point_body: Any) -> ca.SX:
        """Symbolic ``G_T_B(pose) p`` on the resting plane at :attr:`reference` (CasADi).

        The ground is approximated by the plane of the resting pose at the reference pose
        (exact on planar ground): the body origin at (x, y) on that plane, z_B its normal,
        x_B the heading ``yaw`` projected onto it.
        """
        ref = self.reference
        if ref is None:
            x0, x1, y0, y1 = self.heightmap.bounds
            ref = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
        lp = self.local_plane(ref)
        n = lp.normal
        c, s = ca.cos(pose[2]), ca.sin(pose[2])
        z = lp.z - (n[0] * (pose[0] - ref[0]) + n[1] * (pose[1] - ref[1])) / n[2]
        x_dir = ca.vertcat(c, s, -(n[0] * c + n[1] * s) / n[2])
        x_b = x_dir / ca.norm_2(x_dir)
        n_dm = ca.DM(n)
        y_b = ca.cross(n_dm, x_b)
        return ca.vertcat(pose[0], pose[1], z) + (
            x_b * point_body[0] + y_b * point_body[1] + n_dm * point_body[2]
        )

    # ---------------------------------------------------------------------- support
    def support(self, robot: Robot, pose: ArrayLike, com_body: ArrayLike | None = None) -> Support:
        """How ``robot`` stands at one pose: resting pose, contacts, polygon, flags.

        ``com_body``: the overall CoM in B (3,) [m] the base rests under (``None``: the
        bound robot's, :attr:`com_body`).
        """
        terrain = self if robot is self.robot else self.with_robot(robot, self.flipper_angle)
        r = terrain.rest(np.asarray(pose, dtype=float), com_body=com_body)
        return rest_support(r, 0, terrain.candidates.points)

    # ---------------------------------------------------------------------- drawing
    def draw(
        self, ax3d: Any, stride: int | None = None, cmap: str = "terrain", alpha: float = 0.9
    ) -> Any:
        """Draw the ground as a surface on matplotlib 3-D axes (NaN cells left out).

        Args:
            ax3d: matplotlib 3-D axes.
            stride: draw every ``stride``-th cell (``None``: about 120 per side).
            cmap: colour map of the heights.
            alpha: opacity.
        """
        hm = self.heightmap
        step = stride or max(1, max(hm.shape) // 120)
        X, Y = np.meshgrid(hm.x[::step], hm.y[::step])
        Z = hm.elevation[::step, ::step]
        return ax3d.plot_surface(
            X, Y, Z, cmap=cmap, alpha=alpha, linewidth=0, antialiased=False, rstride=1, cstride=1
        )


def rest_support(rests: RestPoses, k: int, points_body: FloatArray) -> Support:
    """Row ``k`` of batched rests as a :class:`Support` (the one :meth:`support` returns).

    Args:
        rests: rests solved on a heightmap (:meth:`HeightmapTerrain.rest`).
        k: the row.
        points_body: the contact candidates they were solved against, in B (n, 3) [m].
    """
    contacts = rests.contacts_G(points_body, k)
    bearing = rests.bearing_G(points_body, k)
    poly, line = support_vertices(bearing, GRAVITY_G)
    flags = rests.flags(k)
    if line and "line_contact" not in flags:
        flags = (*flags, "line_contact")
    return Support(rests.G_T_B[k], contacts, poly, flags, bearing)
