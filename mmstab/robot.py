"""Robot description: a tracked base (body, two tracks, two flippers) and a 4-DoF arm.

Loaded from YAML (``problems/robots/*.yaml``), validated once, and held as frozen
dataclasses of NumPy arrays. Frames follow ``docs/design.md``, "Frames": the body frame B has its
origin at the centre of the track-ground contact rectangle, x forward, y left, z up
along the plane normal.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab import schema
from mmstab.config import ConfigError, check_order, read_yaml, validate

if TYPE_CHECKING:
    from mmstab.kinematics import ArmKinematics

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
    straight forward, positive raises its tip. ``limits`` (optional in the file): the
    range ``(lower, upper)`` [rad] and rate [rad/s] the planner may move them in.
    """

    length: float
    width: float
    thickness: float
    pivot: FloatArray
    angle: float
    limits: FlipperLimits | None = None

    def box(self, side: Literal["left", "right"]) -> Box:
        """Collision box of one flipper in the body frame."""
        pivot = self.pivot * np.array([1.0, 1.0 if side == "left" else -1.0, 1.0])
        direction = np.array([np.cos(self.angle), 0.0, np.sin(self.angle)])
        return Box(
            size=np.array([self.length, self.width, self.thickness]),
            center=pivot + direction * self.length / 2,
            rpy=np.array([0.0, -self.angle, 0.0]),
        )


@dataclass(frozen=True)
class Base:
    """The tracked base: mass [kg], CoM [m] (body frame), and its collision parts."""

    mass: float
    com: FloatArray
    body: Box
    tracks: Tracks
    flippers: Flippers

    def collision_boxes(self) -> dict[str, Box]:
        """The five base bodies by name, in the body frame."""
        return {
            "body": self.body,
            "track_left": self.tracks.box("left"),
            "track_right": self.tracks.box("right"),
            "flipper_left": self.flippers.box("left"),
            "flipper_right": self.flippers.box("right"),
        }

    def support_points(self) -> FloatArray:
        """Ground contact points in the body frame, (n, 3) [m], z = 0.

        The four outer corners of the track contact rectangle, plus the ground-touching
        corners of the flippers when they reach the ground (``FLIPPER_CONTACT_TOL``).
        """
        t = self.tracks
        half_l, half_w = t.length / 2, t.separation / 2 + t.width / 2
        pts = [np.array([sx * half_l, sy * half_w, 0.0]) for sx in (1, -1) for sy in (1, -1)]
        for side in ("left", "right"):
            corners = self.flippers.box(side).corners()
            low = corners[corners[:, 2] <= FLIPPER_CONTACT_TOL]
            pts.extend(np.array([c[0], c[1], 0.0]) for c in low)
        return np.array(pts)


@dataclass(frozen=True)
class Robot:
    """A tracked mobile manipulator. Build with :func:`load_robot`.

    Attributes:
        name: robot name.
        base: the tracked base.
        links: the four arm links in chain order (link 0 = turret).
        mount_T: pose of the arm's mounting frame in the body frame (4x4) [m].
        stowed: the folded arm posture (4,) [rad].
        source_hash: SHA-256 of the description's content, for cache keys.
        tool_wrench: external wrench at the tool (the wrist frame's origin), body frame,
            ``[f (3) [N], n (3) [N m]]`` (6,), or None (``mmstab.payload``). It loads the
            force-angle measure, not the arm's masses, so it is not in ``source_hash``.
    """

    name: str
    base: Base
    links: tuple[ArmLink, ...]
    mount_T: FloatArray
    stowed: FloatArray
    source_hash: str = ""
    tool_wrench: FloatArray | None = None

    @property
    def arm_mass(self) -> float:
        """Total arm mass m_a [kg]."""
        return float(sum(link.mass for link in self.links))

    @property
    def total_mass(self) -> float:
        """m_T = m_a + m_b [kg]."""
        return self.arm_mass + self.base.mass

    @property
    def joint_lower(self) -> FloatArray:
        """Arm joint lower limits (4,) [rad]."""
        return np.array([link.lower for link in self.links])

    @property
    def joint_upper(self) -> FloatArray:
        """Arm joint upper limits (4,) [rad]."""
        return np.array([link.upper for link in self.links])

    @property
    def joint_velocity(self) -> FloatArray:
        """Arm joint speed limits (4,) [rad/s]."""
        return np.array([link.velocity for link in self.links])

    @functools.cached_property
    def kinematics(self) -> ArmKinematics:
        """Symbolic (CasADi) and batched (NumPy) arm kinematics, built once."""
        from mmstab.kinematics import ArmKinematics

        return ArmKinematics(self)

    def arm_com(self, q: ArrayLike) -> FloatArray:
        """Arm CoM g_a in the body frame (Eq. 1 without G_T_B) [m].

        Args:
            q: arm joint angles, (4,) or (N, 4) [rad].

        Returns:
            (3,) or (N, 3) [m].
        """
        return self.kinematics.arm_com(q)

    def overall_com(self, arm_com_body: ArrayLike) -> FloatArray:
        """Overall CoM g_o = (m_a g_a + m_b g_b) / m_T (Eq. 5), body frame [m].

        Args:
            arm_com_body: arm CoM g_a, (3,) or (N, 3) [m].
        """
        g_a = np.asarray(arm_com_body, dtype=float)
        return (self.arm_mass * g_a + self.base.mass * self.base.com) / self.total_mass


# ------------------------------------------------------------------------------------ loading
def _geometry(d: dict[str, Any]) -> Geometry:
    if d["type"] == "box":
        return Box(
            size=np.array(d["size"], float),
            center=np.array(d["center"], float),
            rpy=np.array(d["rpy"], float),
        )
    return Capsule(
        radius=float(d["radius"]), p0=np.array(d["p0"], float), p1=np.array(d["p1"], float)
    )


def robot_from_dict(data: dict[str, Any], path: str | os.PathLike[str] = "<robot>") -> Robot:
    """Validate a robot description mapping and build a :class:`Robot`.

    Raises:
        ConfigError: naming ``path`` and the offending field.
    """
    p = Path(path)
    validate(p, data, schema.ROBOT)
    b = data["base"]
    links = []
    for i, ld in enumerate(data["arm"]["links"]):
        lim = ld["limits"]
        check_order(p, f"arm.links[{i}].limits", lim["lower"], lim["upper"])
        links.append(
            ArmLink(
                name=ld["name"],
                a=float(ld["dh"]["a"]),
                alpha=float(ld["dh"]["alpha"]),
                d=float(ld["dh"]["d"]),
                theta_offset=float(ld["dh"]["theta_offset"]),
                mass=float(ld["mass"]),
                com=np.array(ld["com"], float),
                geometry=_geometry(ld["geometry"]),
                lower=float(lim["lower"]),
                upper=float(lim["upper"]),
                velocity=float(lim["velocity"]),
            )
        )
    stowed = np.array(data["arm"]["stowed"], float)
    for i, (qi, link) in enumerate(zip(stowed, links, strict=True)):
        if not link.lower <= qi <= link.upper:
            raise ConfigError(p, f"arm.stowed[{i}]", f"{qi} is outside the joint limits")
    tr, fl = b["tracks"], b["flippers"]
    limits = None
    if "limits" in fl:
        lim = fl["limits"]
        check_order(p, "base.flippers.limits", lim["lower"], lim["upper"])
        if not lim["lower"] <= fl["angle"] <= lim["upper"]:
            raise ConfigError(p, "base.flippers.angle", "is outside base.flippers.limits")
        limits = FlipperLimits(float(lim["lower"]), float(lim["upper"]), float(lim["rate"]))
    base = Base(
        mass=float(b["mass"]),
        com=np.array(b["com"], float),
        body=Box(
            size=np.array(b["body"]["size"], float), center=np.array(b["body"]["center"], float)
        ),
        tracks=Tracks(**{k: float(v) for k, v in tr.items()}),
        flippers=Flippers(
            length=float(fl["length"]),
            width=float(fl["width"]),
            thickness=float(fl["thickness"]),
            pivot=np.array(fl["pivot"], float),
            angle=float(fl["angle"]),
            limits=limits,
        ),
    )
    lowest = min(base.flippers.box(s).corners()[:, 2].min() for s in ("left", "right"))
    if lowest < -FLIPPER_CONTACT_TOL:
        raise ConfigError(
            p, "base.flippers.angle", f"flippers reach {-lowest:.3f} m below the ground; raise them"
        )
    mount = data["arm"]["mount"]
    # The flipper limits change no cached artefact (V, generated code), so they are not hashed.
    hashed = [kv for kv in _flatten(data) if not kv[0].startswith(".base.flippers.limits")]
    digest = hashlib.sha256(repr(sorted(hashed)).encode()).hexdigest()
    return Robot(
        name=data["name"],
        base=base,
        links=tuple(links),
        mount_T=homogeneous(rpy_matrix(mount["rpy"]), mount["xyz"]),
        stowed=stowed,
        source_hash=digest,
    )


def _flatten(node: Any, prefix: str = "") -> list[tuple[str, str]]:
    if isinstance(node, dict):
        return [kv for k, v in node.items() for kv in _flatten(v, f"{prefix}.{k}")]
    if isinstance(node, list):
        return [kv for i, v in enumerate(node) for kv in _flatten(v, f"{prefix}[{i}]")]
    return [(prefix, repr(node))]


def with_flipper_angle(robot: Robot, angle: float) -> Robot:
    """The robot with its flippers at ``angle`` [rad]; a new ``source_hash`` if it changed.

    The hash follows the angle (as the file's would), so nothing cached for the file's
    flippers (collision checkers, resting-pose candidates) is reused for other ones.
    """
    if float(angle) == robot.base.flippers.angle:
        return robot
    flippers = dataclasses.replace(robot.base.flippers, angle=float(angle))
    digest = hashlib.sha256(f"{robot.source_hash}|flippers.angle={float(angle)!r}".encode())
    return dataclasses.replace(
        robot,
        base=dataclasses.replace(robot.base, flippers=flippers),
        source_hash=digest.hexdigest(),
    )


def flipper_ground_angle(robot: Robot) -> float:
    """The flipper angle [rad] at which the lowest flipper corner touches the ground plane.

    Lowered from the file's angle by bisection on the lowest corner's height (the side
    where it is at or just above the ground); the file's angle itself if the flippers
    already touch.

    Raises:
        ValueError: the flippers cannot reach the ground (not even pointing down).
    """

    def lowest(angle: float) -> float:
        return float(
            with_flipper_angle(robot, angle).base.flippers.box("left").corners()[:, 2].min()
        )

    hi = robot.base.flippers.angle
    if lowest(hi) <= FLIPPER_CONTACT_TOL:
        return hi
    lo = -np.pi / 2
    if lowest(lo) > 0:
        raise ValueError(f"robot {robot.name}: the flippers cannot reach the ground")
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if lowest(mid) < 0 else (lo, mid)
    return hi


def load_robot(path: str | os.PathLike[str]) -> Robot:
    """Load and validate a robot description YAML file.

    Args:
        path: the robot YAML file.

    Raises:
        ConfigError: the file is missing, not YAML, or has a bad field.
    """
    return robot_from_dict(read_yaml(path), path)
