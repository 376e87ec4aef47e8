"""The terrain interface every stage talks to (see ``docs/design.md``, "Terrain").

Frames: G is the global frame (z up, gravity ``GRAVITY_G``). Each terrain has a *map
frame* M in which base poses ``(x, y, yaw)`` are given and in which the controller's
task-space targets live: for the ramp M is the slope frame S (``G_T_M`` = rotation about
G's x by the slope), for a heightmap M is G itself. A base pose is
``(x [m], y [m], yaw [rad])`` in M; ``yaw`` is the heading of the body x axis about M's z.
The terrain turns a pose into the *resting* body pose ``M_T_B`` (for the ramp: on the
plane; for a heightmap: the pose the rigid robot settles in), and from it gravity in
the body and the support contacts.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Protocol, runtime_checkable

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

GRAVITY_G = np.array([0.0, 0.0, -9.81])  # [m/s^2]


class Support(NamedTuple):
    """How the base stands at one pose.

    Attributes:
        G_T_B: resting pose of the body frame in G (4, 4).
        contacts_G: touching contact points in G (n, 3) [m].
        polygon_G: support polygon, ordered hull vertices of the contacts in G (m, 3) [m].
        flags: operator flags, e.g. ``"high_centred"``, ``"line_contact"`` (empty = normal).
    """

    G_T_B: FloatArray
    contacts_G: FloatArray
    polygon_G: FloatArray
    flags: tuple[str, ...] = ()


@runtime_checkable
class Terrain(Protocol):
    """The ground, as every stage above ``mmstab.terrain`` sees it.

    ``poses`` arguments are ``(3,)`` or ``(N, 3)`` arrays of ``(x, y, yaw)`` in the map
    frame M [m, m, rad]; batched methods return a leading ``N`` axis.
    """

    kind: str

    def G_T_M(self) -> FloatArray:
        """Pose of the map frame M in G (4, 4)."""
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
        """Body points placed in M at the resting poses: (N, 3) [m] (numeric, batched)."""
        ...

    def place_sx(self, pose: ca.SX, point_body: Any) -> ca.SX:
        """Symbolic placement ``M_T_B(pose) p`` (CasADi) for the controller's task map."""
        ...
