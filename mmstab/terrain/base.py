"""The terrain interface every stage talks to (see ``docs/design.md``, "Terrain").

Frames: G is the global frame (z up, gravity ``GRAVITY_G``). Each terrain has a *map
frame* M in which base poses ``(x, y, yaw)`` are given and in which the controller's
task-space targets live: for the ramp M is the slope frame S (``G_T_M`` = rotation about
G's x by the slope), for a heightmap M is G itself. A base pose is
``(x [m], y [m], yaw [rad])`` in M; ``yaw`` is the heading of the body x axis about M's z.
The terrain turns a pose into the *resting* body pose ``M_T_B`` (for the ramp: on the
plane; for a heightmap: the pose the rigid robot settles in), and from it gravity in
the body and the support contacts.

**Local ground.** Every resting pose is written ``M_T_B = Trans(x, y, z) Rz(yaw) Ry(-pitch)
Rx(roll)`` (positive roll lifts the left side, positive pitch lifts the nose, as
:func:`roll_pitch`); ``(z [m], roll [rad], pitch [rad])`` is the pose's *local ground*
(:meth:`Terrain.local_ground`; all zero on the ramp, where M is the plane). The one placement
of a body point, :func:`place_local_sx` (CasADi) and :func:`place_local` (NumPy, batched, the
same expression), is written in these terms, so the controller's task map only needs the
local ground as data (``docs/controller-terrain.md``).
"""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, runtime_checkable

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from mmstab.model.robot import Robot

FloatArray = NDArray[np.float64]

GRAVITY_G = np.array([0.0, 0.0, -9.81])  # [m/s^2]
#: ``terrain.friction`` when the problem does not set it: rubber tracks on soil or grass
#: (0.5-0.8) [-] (``docs/terrain.md``).
DEFAULT_FRICTION = 0.7
GROUND_SIZE = 3  #: local ground (z [m], roll [rad], pitch [rad]) per pose


class Support(NamedTuple):
    """How the base stands at one pose.

    Attributes:
        G_T_B: resting pose of the body frame in G (4, 4).
        contacts_G: touching contact points in G (n, 3) [m].
        polygon_G: support polygon, ordered hull vertices of the bearing contacts in G
            (m, 3) [m].
        flags: operator flags, e.g. ``"high_centred"``, ``"line_contact"`` (empty = normal).
        bearing_G: the contacts that carry load in G (k, 3) [m]: the touching ones and, on
            a heightmap, the tracks' bottom run within the compliance of the ground
            (``None``: the touching ones).
    """

    G_T_B: FloatArray
    contacts_G: FloatArray
    polygon_G: FloatArray
    flags: tuple[str, ...] = ()
    bearing_G: FloatArray | None = None

    def bearing(self) -> FloatArray:
        """The contacts that carry load in G (k, 3) [m]."""
        return self.contacts_G if self.bearing_G is None else self.bearing_G


@runtime_checkable
class Terrain(Protocol):
    """The ground, as every stage above ``mmstab.terrain`` sees it.

    ``poses`` arguments are ``(3,)`` or ``(N, 3)`` arrays of ``(x, y, yaw)`` in the map
    frame M [m, m, rad]; batched methods return a leading ``N`` axis (``M_T_B`` and
    ``G_T_B`` drop it for a single ``(3,)`` pose).
    """

    @property
    def kind(self) -> str:
        """The kind of ground (``ramp``, ``heightmap``)."""
        ...

    @property
    def label(self) -> str:
        """A short human description for figure titles (e.g. ``ramp, slope 5.7 deg``)."""
        ...

    def G_T_M(self) -> FloatArray:
        """Pose of the map frame M in G (4, 4)."""
        ...

    def local_ground(self, poses: ArrayLike) -> FloatArray:
        """Local ground ``(z [m], roll [rad], pitch [rad])`` of the resting poses, (N, 3)."""
        ...

    def M_T_B(self, poses: ArrayLike) -> FloatArray:
        """Resting body poses in M: (4, 4) for one pose, (N, 4, 4) for many."""
        ...

    def G_T_B(self, poses: ArrayLike) -> FloatArray:
        """Resting body poses in G: (4, 4) for one pose, (N, 4, 4) for many."""
        ...

    def gravity_body(self, poses: ArrayLike) -> FloatArray:
        """Gravity in the body frame at the resting poses, (N, 3) [m/s^2]."""
        ...

    def place(self, poses: ArrayLike, points_body: ArrayLike) -> FloatArray:
        """Body points (3,) or (N, 3) [m] placed in M at the resting poses: (N, 3) [m]."""
        ...

    def place_sx(self, pose: ca.SX, point_body: Any) -> ca.SX:
        """Symbolic placement ``M_T_B(pose) p`` (CasADi) of a body point (3,) [m]."""
        ...

    def with_robot(
        self, robot: Robot, flipper_angle: float | None = None, arm_q: ArrayLike | None = None
    ) -> Terrain:
        """This ground under ``robot``, flippers at ``flipper_angle`` [rad], arm at ``arm_q``.

        ``None`` keeps the robot's flipper angle and the stowed arm (4,) [rad]. Where the
        resting pose depends on the load (a heightmap), the answers that follow use it.
        """
        ...

    def support(self, robot: Robot, pose: ArrayLike, com_body: ArrayLike | None = None) -> Support:
        """How ``robot``'s base stands at one pose (its contacts from its description).

        ``com_body``: the overall CoM in B (3,) [m] whose load the base rests under (``None``:
        the bound robot's); where the rest depends on the load (a heightmap), a state's
        support is its own CoM's, the one its μ is computed on.
        """
        ...

    def surface_G(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Ground points in G under map coordinates ``x``, ``y`` [m] (broadcast), (..., 3).

        What drawing needs (patches, paths on the ground), without matplotlib here.
        """
        ...

    @property
    def bounds(self) -> tuple[float, float, float, float] | None:
        """``(x_min, x_max, y_min, y_max)`` [m] of M the ground covers (a map); None: no edge.

        :meth:`surface_G` answers inside it (a heightmap's map); drawing clips to it.
        """
        ...


@runtime_checkable
class GridHeights(Protocol):
    """A ground that gives its heights on a grid at once (a heightmap): optional.

    A lattice of map points costs such a ground its grid's rows, not its points; users
    that sample many (the ground under the arm) ask for it where the ground offers it.
    """

    def height_grid_M(self, x: FloatArray, y: FloatArray) -> FloatArray:
        """The ground's z_M [m] at map x (n,) [m] times y (m,) [m]: (m, n).

        The values :meth:`Terrain.surface_G` gives at those points, written in M.
        """
        ...


# ------------------------------------------------------------------------------ poses
def as_poses(poses: ArrayLike) -> FloatArray:
    """Poses as an (N, 3) float array; raise ``ValueError`` for any other shape."""
    p = np.asarray(poses, dtype=float)
    if p.ndim == 1 and p.shape == (3,):
        return p[None, :]
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"poses must be (3,) or (N, 3) of (x, y, yaw), got shape {p.shape}")
    return p


def rot_x(angle: float) -> FloatArray:
    """Rotation about x by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_z(angle: ArrayLike) -> FloatArray:
    """Rotation about z by ``angle`` [rad]: (3, 3), or (N, 3, 3) for angles (N,)."""
    c, s = np.cos(angle), np.sin(angle)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack(r, axis=-1) for r in ((c, -s, z), (s, c, z), (z, z, o))], axis=-2)


def wrap_angle(angle: ArrayLike) -> FloatArray:
    """Wrap angles to (-pi, pi] [rad]."""
    a = np.asarray(angle, dtype=float)
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


# -------------------------------------------------------------------------- placement
def local_rotation_sx(yaw: Any, ground: Any) -> Any:
    """``Rz(yaw) Ry(-pitch) Rx(roll)`` (CasADi) with ``ground = (z, roll, pitch)``."""
    cy, sy = ca.cos(yaw), ca.sin(yaw)
    cr, sr = ca.cos(ground[1]), ca.sin(ground[1])
    cp, sp = ca.cos(ground[2]), -ca.sin(ground[2])  # Ry(-pitch): the nose up for pitch > 0
    return ca.vertcat(
        ca.horzcat(cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
        ca.horzcat(sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
        ca.horzcat(-sp, cp * sr, cp * cr),
    )


def place_local_sx(pose: Any, ground: Any, point_body: Any) -> Any:
    """The one placement of a body point in M (CasADi, SX or MX).

    ``M_T_B p = [x, y, z] + Rz(yaw) Ry(-pitch) Rx(roll) p``.

    Args:
        pose: base pose ``(x, y, yaw)`` in M [m, m, rad].
        ground: local ground ``(z, roll, pitch)`` [m, rad, rad] (:meth:`Terrain.local_ground`).
        point_body: the point in B (3,) [m].
    """
    offset = ca.vertcat(pose[0], pose[1], ground[0])
    return offset + local_rotation_sx(pose[2], ground) @ point_body


@lru_cache(maxsize=1)
def placement_function() -> ca.Function:
    """``place`` (pose (3), ground (3), point (3)) -> point in M (3) and its Jacobians.

    Outputs: ``p_M`` [m], ``dp_dpose`` (3x3) [m/m, m/rad], ``dp_dpoint`` (3x3) = the rotation.
    """
    pose, ground, point = ca.SX.sym("pose", 3), ca.SX.sym("ground", 3), ca.SX.sym("point", 3)
    p_M = place_local_sx(pose, ground, point)
    return ca.Function(
        "place",
        [pose, ground, point],
        [p_M, ca.jacobian(p_M, pose), ca.jacobian(p_M, point)],
        ["pose", "ground", "point"],
        ["p_M", "dp_dpose", "dp_dpoint"],
    )


@lru_cache(maxsize=16)
def _placement_map(n: int) -> ca.Function:
    """:func:`placement_function` mapped over ``n`` columns (built once per n: 0.2 ms)."""
    return placement_function().map(n)


class Placement(NamedTuple):
    """Body points placed in M (N, 3) [m] with their Jacobians (N, 3, 3)."""

    points: FloatArray
    d_pose: FloatArray
    d_point: FloatArray


def _rows(a: ArrayLike, n: int, what: str) -> FloatArray:
    v = np.asarray(a, dtype=float)
    v = np.broadcast_to(v, (n, 3)) if v.ndim == 1 else v
    if v.shape != (n, 3):
        raise ValueError(f"{what} must be (3,) or ({n}, 3), got {np.shape(a)}")
    return v


def place_local(poses: ArrayLike, ground: ArrayLike, points_body: ArrayLike) -> Placement:
    """:func:`place_local_sx` evaluated for many poses at once (NumPy in, NumPy out).

    Args:
        poses: base poses (N, 3) or (3,) in M [m, m, rad].
        ground: local ground (N, 3) or (3,) [m, rad, rad].
        points_body: body points (N, 3) or (3,) [m].

    Returns:
        The placed points (N, 3) [m] and their Jacobians with respect to the pose and the
        point (N, 3, 3) each.
    """
    P = as_poses(poses)
    n = len(P)
    Gd, X = _rows(ground, n, "ground"), _rows(points_body, n, "points_body")
    if n == 0:
        return Placement(np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3, 3)))
    p, dpose, dpoint = _placement_map(n)(P.T, Gd.T, X.T)
    return Placement(
        np.asarray(p).T,
        np.asarray(dpose).reshape(3, n, 3).transpose(1, 0, 2),
        np.asarray(dpoint).reshape(3, n, 3).transpose(1, 0, 2),
    )


def local_transforms(poses: ArrayLike, ground: ArrayLike) -> FloatArray:
    """``M_T_B`` (N, 4, 4) from poses and their local ground (NumPy, batched)."""
    P = as_poses(poses)
    Gd = _rows(ground, len(P), "ground")
    cy, sy = np.cos(P[:, 2]), np.sin(P[:, 2])
    cr, sr = np.cos(Gd[:, 1]), np.sin(Gd[:, 1])
    cp, sp = np.cos(Gd[:, 2]), -np.sin(Gd[:, 2])  # Ry(-pitch), as local_rotation_sx
    T = np.zeros((len(P), 4, 4))
    T[:, 0, :3] = np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], 1)
    T[:, 1, :3] = np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], 1)
    T[:, 2, :3] = np.stack([-sp, cp * sr, cp * cr], 1)
    T[:, :3, 3] = np.stack([P[:, 0], P[:, 1], Gd[:, 0]], 1)
    T[:, 3, 3] = 1.0
    return T


def roll_pitch(terrain: Terrain, pose: ArrayLike) -> tuple[float, float]:
    """Roll and pitch of the base at one pose [rad], from gravity in the body.

    Positive roll lifts the left side; positive pitch lifts the nose.
    """
    g = terrain.gravity_body(pose)[0]
    roll = float(np.arctan2(-g[1], -g[2]))
    pitch = float(np.arctan2(-g[0], np.hypot(g[1], g[2])))
    return roll, pitch
