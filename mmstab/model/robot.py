"""Robot description: a tracked base (body, two tracks, two flippers) and an n-DoF arm.

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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core import schema
from mmstab.core.files import ConfigError, MmstabError, check_order, read_yaml, validate
from mmstab.core.hints import did_you_mean
from mmstab.model.kinematics import ArmKinematics
from mmstab.model.parts import (
    BASE_PARTS,
    FLIPPER_CONTACT_TOL,
    ArmLink,
    Base,
    Box,
    Capsule,
    FlipperLimits,
    Flippers,
    FloatArray,
    Geometry,
    Tracks,
    homogeneous,
    rpy_matrix,
)

__all__ = [
    "ArmLink",
    "Base",
    "Box",
    "Capsule",
    "FLIPPER_CONTACT_TOL",
    "FlipperLimits",
    "Flippers",
    "FloatArray",
    "Geometry",
    "Tracks",
    "homogeneous",
    "rpy_matrix",
    "Robot",
    "load_robot",
    "robot_from_dict",
    "with_flipper_angle",
    "flipper_ground_angle",
    "link_extent_warnings",
]


@dataclass(frozen=True)
class Robot:
    """A tracked mobile manipulator. Build with :func:`load_robot`.

    Attributes:
        name: robot name.
        base: the tracked base.
        links: the arm links in chain order (link 0 = turret); n = ``len(links)`` joints.
        mount_T: pose of the arm's mounting frame in the body frame (4x4) [m].
        stowed: the folded arm posture (n,) [rad].
        source_hash: SHA-256 of the description's content, for cache keys.
        tool_wrench: external wrench at the tool (the wrist frame's origin), body frame,
            ``[f (3) [N], n (3) [N m]]`` (6,), or None (``mmstab.model.payload``). It loads the
            force-angle measure, not the arm's masses, so it is not in ``source_hash``.
        collision_allow: pairs of bodies (link names, base part names) the self-collision
            checker never checks against each other: the file's ``collision.allow``
            (MoveIt's ``disable_collisions``).
    """

    name: str
    base: Base
    links: tuple[ArmLink, ...]
    mount_T: FloatArray
    stowed: FloatArray
    source_hash: str = ""
    tool_wrench: FloatArray | None = None
    collision_allow: frozenset[frozenset[str]] = frozenset()

    @property
    def arm_mass(self) -> float:
        """Total arm mass m_a [kg]."""
        return float(sum(link.mass for link in self.links))

    @property
    def total_mass(self) -> float:
        """m_T = m_a + m_b [kg]."""
        return self.arm_mass + self.base.mass

    @property
    def arm_joints(self) -> int:
        """The arm's joint count n (``len(links)``, the robot file's ``arm.links``)."""
        return len(self.links)

    @property
    def joint_lower(self) -> FloatArray:
        """Arm joint lower limits (n,) [rad]."""
        return np.array([link.lower for link in self.links])

    @property
    def joint_upper(self) -> FloatArray:
        """Arm joint upper limits (n,) [rad]."""
        return np.array([link.upper for link in self.links])

    @property
    def joint_velocity(self) -> FloatArray:
        """Arm joint speed limits (n,) [rad/s]."""
        return np.array([link.velocity for link in self.links])

    @functools.cached_property
    def kinematics(self) -> ArmKinematics:
        """Symbolic (CasADi) and batched (NumPy) arm kinematics, built once."""
        return ArmKinematics(self.links, self.mount_T)

    def __getstate__(self) -> dict[str, object]:
        """The state to pickle: all but the built kinematics, rebuilt on first use.

        CasADi's SX does not pickle: a Dask worker sending a used robot to a peer failed.
        """
        state = dict(self.__dict__)
        state.pop("kinematics", None)
        return state

    def arm_com(self, q: ArrayLike) -> FloatArray:
        """Arm CoM g_a in the body frame (Eq. 1 without G_T_B) [m].

        Args:
            q: arm joint angles, (n,) or (N, n) [rad].

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
    if len(stowed) != len(links):
        raise ConfigError(
            p, "arm.stowed", f"has {len(stowed)} angles for {len(links)} links (one per joint)"
        )
    for i, (qi, link) in enumerate(zip(stowed, links, strict=True)):
        if not link.lower <= qi <= link.upper:
            raise ConfigError(p, f"arm.stowed[{i}]", f"{qi} is outside the joint limits")
    base = Base(
        mass=float(b["mass"]),
        com=np.array(b["com"], float),
        body=Box(
            size=np.array(b["body"]["size"], float), center=np.array(b["body"]["center"], float)
        ),
        tracks=Tracks(**{k: float(v) for k, v in b["tracks"].items()}),
        flippers=None if "flippers" not in b else _flippers(p, b["flippers"]),
        rear_flippers=None
        if "rear_flippers" not in b
        else _flippers(p, b["rear_flippers"], rear=True),
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
        collision_allow=_allowed_pairs(p, data.get("collision", {}), [ln.name for ln in links]),
    )


def _flippers(path: Path, fl: dict[str, Any], rear: bool = False) -> Flippers:
    """A flipper pair (``base.flippers``, or ``base.rear_flippers``: ``rear``), not below ground.

    Raises:
        ConfigError: limits out of order, the angle outside them, flippers below the ground.
    """
    key = "base.rear_flippers" if rear else "base.flippers"
    limits = None
    if "limits" in fl:
        lim = fl["limits"]
        check_order(path, f"{key}.limits", lim["lower"], lim["upper"])
        if not lim["lower"] <= fl["angle"] <= lim["upper"]:
            raise ConfigError(path, f"{key}.angle", f"is outside {key}.limits")
        limits = FlipperLimits(float(lim["lower"]), float(lim["upper"]), float(lim["rate"]))
    flippers = Flippers(
        length=float(fl["length"]),
        width=float(fl["width"]),
        thickness=float(fl["thickness"]),
        pivot=np.array(fl["pivot"], float),
        angle=float(fl["angle"]),
        limits=limits,
        rear=rear,
    )
    lowest = flippers.lowest()
    if lowest < -FLIPPER_CONTACT_TOL:
        raise ConfigError(
            path,
            f"{key}.angle",
            f"flippers reach {-lowest:.3f} m below the ground; raise them",
        )
    return flippers


def _allowed_pairs(
    path: Path, section: dict[str, Any], names: list[str]
) -> frozenset[frozenset[str]]:
    """``collision.allow``: pairs of known bodies, each of two different names.

    Raises:
        ConfigError: ``collision.allow[i][j]`` naming an unknown body and the closest valid one.
    """
    known = [*names, *BASE_PARTS]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        i = [k for k, n in enumerate(names) if n == dup][1]
        raise ConfigError(path, f"arm.links[{i}].name", f"{dup!r} names two links")
    pairs = []
    for i, pair in enumerate(section.get("allow", [])):
        for j, name in enumerate(pair):
            if name not in known:
                hint = did_you_mean(name, known) or f"; one of {', '.join(known)}"
                raise ConfigError(
                    path, f"collision.allow[{i}][{j}]", f"unknown body {name!r}{hint}"
                )
        if pair[0] == pair[1]:
            raise ConfigError(path, f"collision.allow[{i}]", "a pair of two different bodies")
        pairs.append(frozenset(pair))
    return frozenset(pairs)


#: A link's collision shape or CoM farther than this from its DH segment (from the previous
#: joint's origin to its own frame's origin) is reported at load [m]:
#: :func:`link_extent_warnings`.
LINK_EXTENT_TOL = 0.05


def _segment_distance(x: FloatArray, a: FloatArray, b: FloatArray) -> float:
    """Distance from point ``x`` to the segment ``a``-``b`` [m]."""
    ab = b - a
    t = float(np.clip(np.dot(x - a, ab) / np.dot(ab, ab), 0.0, 1.0)) if np.dot(ab, ab) > 0 else 0.0
    return float(np.linalg.norm(x - (a + t * ab)))


def link_extent_warnings(robot: Robot, tol: float = LINK_EXTENT_TOL) -> list[str]:
    """Links whose collision shape or CoM lies beyond their DH segment by more than ``tol`` [m].

    A link's DH segment runs, in its own (distal) frame R_i, from the previous joint's origin
    ``(-a, -d sin(alpha), -d cos(alpha))`` to R_i's origin; a capsule's ends, a box's centre
    and the CoM are measured from it across the two joint axes (z_{i-1}, ``(0, sin(alpha),
    cos(alpha))`` in R_i, and z_i): a body offset along a joint's axis, as a UR arm's
    shoulder offset, is where real links are. A changed DH length (``dh.a``) that left the
    shape and the CoM where they were is the usual cause.

    Returns:
        One line per such link: ``arm.links[i] (name): ...`` with the distances [m].
    """
    out = []
    for i, link in enumerate(robot.links):
        axes = np.array([[0.0, np.sin(link.alpha), np.cos(link.alpha)], [0.0, 0.0, 1.0]])
        basis = np.linalg.svd(axes)[2][: np.linalg.matrix_rank(axes, tol=1e-9)]
        across = np.eye(3) - basis.T @ basis  # drops the components along the joint axes
        start, end = across @ np.array([-link.a, 0.0, 0.0]), np.zeros(3)
        g = link.geometry
        points = {"com": link.com}
        if isinstance(g, Capsule):
            points.update({"geometry.p0": g.p0, "geometry.p1": g.p1})
        else:
            points["geometry.center"] = g.center
        far = {k: _segment_distance(across @ v, start, end) for k, v in points.items()}
        far = {k: v for k, v in far.items() if v > tol}
        if far:
            length = float(np.hypot(link.a, link.d))
            what = ", ".join(f"{k} {v:.3f} m" for k, v in far.items())
            out.append(
                f"arm.links[{i}] ({link.name}): {what} off its DH segment of {length:.3f} m "
                f"(more than {tol} m: was dh.a changed without them?)"
            )
    return out


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
    if robot.base.flippers is None:
        raise MmstabError(
            f"robot {robot.name}: has no flippers (base.flippers) to set at {angle} rad"
        )
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
        ValueError: the flippers cannot reach the ground (not even pointing down), or the
            robot has none.
    """
    if robot.base.flippers is None:
        raise ValueError(f"robot {robot.name}: has no flippers (base.flippers)")

    flippers = robot.base.flippers

    def lowest(angle: float) -> float:
        return dataclasses.replace(flippers, angle=angle).lowest()

    hi = flippers.angle
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
        ConfigError: the file is missing, not YAML, a problem file, or has a bad field.
    """
    data = read_yaml(path)
    if isinstance(data, dict) and "robot" in data and {"terrain", "path"} & set(data):
        raise ConfigError(  # the usual slip: the problem handed where its robot is asked for
            path, "robot", f"a problem file, not a robot file: its robot is {data['robot']!r}"
        )
    return robot_from_dict(data, path)
