"""The parts of a robot description: frames, collision shapes, arm links, tracks, flippers.

Plain frozen dataclasses of NumPy arrays (``mmstab.model.robot`` assembles them into a
:class:`~mmstab.model.robot.Robot` and loads them from YAML). Frames follow
``docs/design.md``, "Frames".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: A flipper whose lowest point is within this height of the ground counts as touching [m].
FLIPPER_CONTACT_TOL = 1e-3


def rpy_matrix(rpy: ArrayLike) -> FloatArray:
    """Rotation matrix from roll-pitch-yaw (fixed axes x, then y, then z) [rad]."""
    r, p, y = np.asarray(rpy, dtype=float)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def homogeneous(rotation: ArrayLike, translation: ArrayLike) -> FloatArray:
    """4x4 homogeneous transform from a 3x3 rotation and a translation [m]."""
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = translation
    return T


@dataclass(frozen=True)
class Box:
    """A box: full edge lengths ``size`` [m], pose (``center`` [m], ``rpy`` [rad]) in its frame."""

    size: FloatArray
    center: FloatArray
    rpy: FloatArray = field(default_factory=lambda: np.zeros(3))
    kind: Literal["box"] = "box"

    @property
    def frame_T_shape(self) -> FloatArray:
        """Pose of the box centre in the owning frame."""
        return homogeneous(rpy_matrix(self.rpy), self.center)

    @property
    def bounding_radius(self) -> float:
        """Radius of the sphere about ``center`` that holds the box [m]."""
        return float(np.linalg.norm(self.size) / 2)

    def corners(self) -> FloatArray:
        """The 8 corners in the owning frame, (8, 3) [m]."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        local = signs * self.size / 2
        return local @ rpy_matrix(self.rpy).T + self.center


@dataclass(frozen=True)
class Capsule:
    """A capsule: the set of points within ``radius`` [m] of the segment ``p0``-``p1`` [m]."""

    radius: float
    p0: FloatArray
    p1: FloatArray
    kind: Literal["capsule"] = "capsule"

    @property
    def center(self) -> FloatArray:
        """Midpoint of the segment [m]."""
        return (self.p0 + self.p1) / 2

    @property
    def length(self) -> float:
        """Length of the segment (without the caps) [m]."""
        return float(np.linalg.norm(self.p1 - self.p0))

    @property
    def bounding_radius(self) -> float:
        """Radius of the sphere about ``center`` that holds the capsule [m]."""
        return self.length / 2 + self.radius


Geometry = Box | Capsule


@dataclass(frozen=True)
class ArmLink:
    """One arm link: DH row (standard, distal convention), inertia summary and limits.

    The joint transform is ``Rz(theta + theta_offset) Tz(d) Tx(a) Rx(alpha)``; ``com`` and
    ``geometry`` are expressed in the link's own (distal) frame R_i.
    """

    name: str
    a: float
    alpha: float
    d: float
    theta_offset: float
    mass: float
    com: FloatArray
    geometry: Geometry
    lower: float
    upper: float
    velocity: float


@dataclass(frozen=True)
class Tracks:
    """Track geometry [m] and drive: left/right tracks centred at y = +-separation/2."""

    length: float
    width: float
    height: float
    separation: float
    sprocket_radius: float
    velocity_limit: float  # sprocket speed limit [rad/s]

    def box(self, side: Literal["left", "right"]) -> Box:
        """Collision box of one track in the body frame."""
        y = self.separation / 2 * (1 if side == "left" else -1)
        return Box(
            size=np.array([self.length, self.width, self.height]),
            center=np.array([0.0, y, self.height / 2]),
        )


class FlipperLimits(NamedTuple):
    """Flipper range [rad] and rate limit [rad/s] (the planner's flipper search)."""

    lower: float
    upper: float
    rate: float


@dataclass(frozen=True)
class Flippers:
    """Two coupled flippers; ``pivot`` is the left one's hinge [m], mirrored for the right.

    ``angle`` [rad] turns the flipper about the body's y axis at the hinge: 0 points it
    straight forward (the rear pair, ``rear``: straight backward), positive raises its tip.
    ``limits`` (optional in the file, front pair): the range ``(lower, upper)`` [rad] and
    rate [rad/s] the planner may move them in.
    """

    length: float
    width: float
    thickness: float
    pivot: FloatArray
    angle: float
    limits: FlipperLimits | None = None
    rear: bool = False

    def box(self, side: Literal["left", "right"]) -> Box:
        """Collision box of one flipper in the body frame."""
        pivot = self.pivot * np.array([1.0, 1.0 if side == "left" else -1.0, 1.0])
        ahead = -1.0 if self.rear else 1.0
        direction = np.array([ahead * np.cos(self.angle), 0.0, np.sin(self.angle)])
        return Box(
            size=np.array([self.length, self.width, self.thickness]),
            center=pivot + direction * self.length / 2,
            rpy=np.array([0.0, -ahead * self.angle, 0.0]),
        )

    def lowest(self) -> float:
        """The height of the pair's lowest corner above the tracks' bottom (z = 0 in B) [m]."""
        return float(min(self.box(s).corners()[:, 2].min() for s in ("left", "right")))


#: The base parts' names (:meth:`Base.collision_boxes`), in the collision checker's order.
BASE_PARTS = ("body", "track_left", "track_right", "flipper_left", "flipper_right",
              "flipper_rear_left", "flipper_rear_right")  # fmt: skip


@dataclass(frozen=True)
class Base:
    """The tracked base: mass [kg], CoM [m] (body frame), and its collision parts.

    ``flippers`` is None for a base without them (the file leaves ``base.flippers`` out);
    ``rear_flippers``, a rear pair (``base.rear_flippers``), None for most.
    """

    mass: float
    com: FloatArray
    body: Box
    tracks: Tracks
    flippers: Flippers | None = None
    rear_flippers: Flippers | None = None

    def flipper_pairs(self) -> dict[str, Flippers]:
        """The flipper pairs it has, by their parts' name prefix (``flipper``, ``flipper_rear``)."""
        pairs = {"flipper": self.flippers, "flipper_rear": self.rear_flippers}
        return {k: v for k, v in pairs.items() if v is not None}

    def collision_boxes(self) -> dict[str, Box]:
        """The base bodies by name, in the body frame (:data:`BASE_PARTS`' order)."""
        boxes = {
            "body": self.body,
            "track_left": self.tracks.box("left"),
            "track_right": self.tracks.box("right"),
        }
        for prefix, pair in self.flipper_pairs().items():
            boxes[f"{prefix}_left"] = pair.box("left")
            boxes[f"{prefix}_right"] = pair.box("right")
        return boxes

    def support_points(self) -> FloatArray:
        """Ground contact points in the body frame, (n, 3) [m], z = 0.

        The four outer corners of the track contact rectangle, plus the ground-touching
        corners of the flippers when they reach the ground (``FLIPPER_CONTACT_TOL``).
        """
        t = self.tracks
        half_l, half_w = t.length / 2, t.separation / 2 + t.width / 2
        pts = [np.array([sx * half_l, sy * half_w, 0.0]) for sx in (1, -1) for sy in (1, -1)]
        for pair in self.flipper_pairs().values():
            for side in ("left", "right"):
                corners = pair.box(side).corners()
                low = corners[corners[:, 2] <= FLIPPER_CONTACT_TOL]
                pts.extend(np.array([c[0], c[1], 0.0]) for c in low)
        return np.array(pts)
