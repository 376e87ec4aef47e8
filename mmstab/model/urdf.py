"""URDF export of a robot description, so RViz, pinocchio, MuJoCo or Drake can load it.

Tree (all frames follow ``docs/design.md``, "Frames")::

    base_link (= body frame B; no inertia of its own)
    ├── body, track_left, track_right, flipper_left, flipper_right   (fixed joints)
    └── arm_mount (fixed, at ``robot.mount_T``)
        └── arm_joint_0 ─► arm_link_0 ─► arm_joint_1 ─► arm_link_1 ─► ... ─► arm_link_3
                              └── arm_frame_0 (fixed)        └── arm_frame_1 (fixed) ...

**Base.** Each of the base links has its frame at its collision box's centre and
axes (``Box.frame_T_shape``) and carries a solid-box inertia. The base mass is spread
over the boxes in proportion to their volumes, and every box's CoM is shifted by
one common offset ``delta = base.com - (volume centroid of the boxes)`` so that the
base as a whole has exactly ``base.mass`` at ``base.com`` (the offset is a few cm for
the Cameleon); each box keeps its solid-box inertia about its (shifted) CoM.

**Arm.** mmstab's DH row ``i`` is ``R_{i-1}_T_R_i = Rz(q_i + theta_offset_i) C_i`` with
``C_i = Tz(d_i) Tx(a_i) Rx(alpha_i)``. A URDF joint applies its rotation *after* its
fixed origin, about an axis through the child's origin, so the URDF link ``arm_link_i``
is the frame ``L_i = R_{i-1} Rz(q_i + theta_offset_i)`` (before ``C_i``):

- ``arm_joint_0`` origin: ``Rz(theta_offset_0)`` in ``arm_mount`` (= R_{-1}, the mount frame);
- ``arm_joint_i`` origin (i >= 1): ``C_{i-1} Rz(theta_offset_i)`` in ``arm_link_{i-1}``;
- axis ``0 0 1`` each, so the URDF joint angle is mmstab's ``q_i``: same zero, same sign;
- the link's inertial, visual and collision origins are ``C_i`` times their pose in R_i,
  and a massless fixed link ``arm_frame_i`` sits at ``C_i``: it *is* mmstab's R_i.

Joint limits: position ``[lower, upper]`` and ``velocity`` from the description; mmstab
has no torque model, so ``effort`` is a placeholder, :data:`DEFAULT_EFFORT` unless given.

**Inertias** (uniform density): boxes as solid boxes; capsules as solid capsules (a
cylinder and two hemispheres). A link's tensor is the solid shape's inertia about its
own centroid, in the shape's axes, placed at the link's CoM from the description (which
need not be the shape's centroid: motors sit off-centre).

URDF has no capsule: a capsule's visual and collision are a cylinder along ``p0 -> p1``
plus a sphere at each end.
"""

from __future__ import annotations

import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.robot import ArmLink, Box, FloatArray, Geometry, Robot, homogeneous

#: Joint effort limit written for every arm joint [N m]: a placeholder (no torque model).
DEFAULT_EFFORT = 100.0

_MATERIALS = {
    "body": (0.55, 0.58, 0.50, 1.0),
    "track": (0.15, 0.15, 0.15, 1.0),
    "arm": (0.90, 0.55, 0.10, 1.0),
}


class Inertia(NamedTuple):
    """A rigid body's inertia summary.

    Attributes:
        mass: [kg].
        frame_T_com: pose (4x4) of the CoM frame in the owning frame; the tensor's axes [m].
        tensor: 3x3 inertia about the CoM, in the axes of ``frame_T_com`` [kg m^2].
    """

    mass: float
    frame_T_com: FloatArray
    tensor: FloatArray


# --------------------------------------------------------------------------- maths helpers
def matrix_to_rpy(rotation: ArrayLike) -> FloatArray:
    """Roll-pitch-yaw [rad] of a rotation matrix; inverse of :func:`mmstab.model.robot.rpy_matrix`.

    URDF's convention: ``R = Rz(yaw) Ry(pitch) Rx(roll)``. At pitch = +-pi/2 (gimbal
    lock) yaw is set to 0 and the whole turn goes into roll.

    Args:
        rotation: 3x3 rotation matrix.

    Returns:
        (3,) roll, pitch, yaw [rad].
    """
    R = np.asarray(rotation, dtype=float)
    pitch = np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0]))
    if np.hypot(R[0, 0], R[1, 0]) > 1e-12:
        roll = np.arctan2(R[2, 1], R[2, 2])
        yaw = np.arctan2(R[1, 0], R[0, 0])
    else:
        roll, yaw = np.arctan2(-R[1, 2], R[1, 1]), 0.0
    return np.array([roll, pitch, yaw])


def rot_z_T(angle: float) -> FloatArray:
    """Homogeneous rotation about z by ``angle`` [rad] (4x4)."""
    c, s = np.cos(angle), np.sin(angle)
    return homogeneous(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), np.zeros(3))


def dh_constant_T(link: ArmLink) -> FloatArray:
    """The joint-independent part ``C = Tz(d) Tx(a) Rx(alpha)`` of a DH row (4x4) [m]."""
    c, s = np.cos(link.alpha), np.sin(link.alpha)
    return homogeneous(np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]), [link.a, 0, link.d])


def axis_to_z_rotation(direction: ArrayLike) -> FloatArray:
    """A rotation (3x3) whose z column is the unit vector along ``direction`` (any length > 0)."""
    z = np.asarray(direction, dtype=float)
    z = z / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def solid_box_inertia(mass: float, size: ArrayLike) -> FloatArray:
    """Inertia of a uniform solid box about its centre, in its axes (3x3) [kg m^2].

    Args:
        mass: [kg].
        size: full edge lengths (3,) [m].
    """
    a, b, c = np.asarray(size, dtype=float) ** 2
    return mass / 12.0 * np.diag([b + c, a + c, a + b])


def solid_capsule_inertia(mass: float, radius: float, length: float) -> FloatArray:
    """Inertia of a uniform solid capsule about its centre, axis along z (3x3) [kg m^2].

    Args:
        mass: [kg].
        radius: [m].
        length: length of the cylindrical part (between the hemisphere centres) [m].
    """
    r, h = radius, length
    v_cyl, v_sph = np.pi * r**2 * h, 4.0 / 3.0 * np.pi * r**3
    m_cyl, m_sph = mass * v_cyl / (v_cyl + v_sph), mass * v_sph / (v_cyl + v_sph)
    axial = m_cyl * r**2 / 2 + m_sph * 2 * r**2 / 5
    # two hemispheres: own centroid 3r/8 from the flat face, parallel-axis theorem
    transverse = m_cyl * (h**2 / 12 + r**2 / 4) + m_sph * (2 * r**2 / 5 + h**2 / 4 + 3 * h * r / 8)
    return np.diag([transverse, transverse, axial])


def geometry_inertia(geometry: Geometry, mass: float) -> tuple[FloatArray, FloatArray]:
    """Solid-shape inertia of ``geometry`` about its centroid.

    Args:
        geometry: a box or capsule, in its owning frame [m].
        mass: [kg].

    Returns:
        (``frame_R_shape`` 3x3, inertia 3x3 in the shape's axes [kg m^2]).
    """
    if isinstance(geometry, Box):
        return geometry.frame_T_shape[:3, :3], solid_box_inertia(mass, geometry.size)
    axis = geometry.p1 - geometry.p0
    R = axis_to_z_rotation(axis) if geometry.length > 0 else np.eye(3)
    return R, solid_capsule_inertia(mass, geometry.radius, geometry.length)


def base_link_inertias(robot: Robot) -> dict[str, Inertia]:
    """The base links' inertias, each in its link frame (at its box's pose).

    Masses in proportion to the boxes' volumes; CoMs at the box centres shifted by one
    common offset, so that the links sum to ``base.mass`` at ``base.com`` exactly.
    """
    boxes = robot.base.collision_boxes()
    volumes = np.array([float(np.prod(b.size)) for b in boxes.values()])
    masses = robot.base.mass * volumes / volumes.sum()
    centroid = sum(v * b.center for v, b in zip(volumes, boxes.values(), strict=True))
    delta = robot.base.com - centroid / volumes.sum()  # in B
    out = {}
    for (name, box), m in zip(boxes.items(), masses, strict=True):
        R = box.frame_T_shape[:3, :3]
        out[name] = Inertia(
            mass=float(m),
            frame_T_com=homogeneous(np.eye(3), R.T @ delta),
            tensor=solid_box_inertia(float(m), box.size),
        )
    return out


def arm_link_inertia(link: ArmLink) -> Inertia:
    """An arm link's inertia in its DH frame R_i: solid shape at the link's CoM."""
    R, tensor = geometry_inertia(link.geometry, link.mass)
    return Inertia(mass=link.mass, frame_T_com=homogeneous(R, link.com), tensor=tensor)


# ---------------------------------------------------------------------------------- writing
def _num(x: float) -> str:
    v = float(x)
    return repr(0.0 if v == 0.0 else v)


def _vec(v: ArrayLike) -> str:
    return " ".join(_num(x) for x in np.asarray(v, dtype=float).ravel())


def _origin(parent: ET.Element, T: FloatArray) -> None:
    ET.SubElement(parent, "origin", xyz=_vec(T[:3, 3]), rpy=_vec(matrix_to_rpy(T[:3, :3])))


def _inertial(link_el: ET.Element, link_T_frame: FloatArray, inertia: Inertia) -> None:
    el = ET.SubElement(link_el, "inertial")
    _origin(el, link_T_frame @ inertia.frame_T_com)
    ET.SubElement(el, "mass", value=_num(inertia.mass))
    inertia_3 = inertia.tensor
    ET.SubElement(
        el,
        "inertia",
        ixx=_num(inertia_3[0, 0]),
        ixy=_num(inertia_3[0, 1]),
        ixz=_num(inertia_3[0, 2]),
        iyy=_num(inertia_3[1, 1]),
        iyz=_num(inertia_3[1, 2]),
        izz=_num(inertia_3[2, 2]),
    )


def _shapes(
    link_el: ET.Element, link_T_frame: FloatArray, geometry: Geometry, material: str
) -> None:
    """Visual and collision elements of ``geometry`` (given in a frame at ``link_T_frame``)."""
    parts: list[tuple[FloatArray, str, dict[str, str]]] = []
    if isinstance(geometry, Box):
        parts.append((geometry.frame_T_shape, "box", {"size": _vec(geometry.size)}))
    else:
        r = _num(geometry.radius)
        if geometry.length > 0:
            R = axis_to_z_rotation(geometry.p1 - geometry.p0)
            cyl = {"radius": r, "length": _num(geometry.length)}
            parts.append((homogeneous(R, geometry.center), "cylinder", cyl))
        for p in (geometry.p0, geometry.p1):
            parts.append((homogeneous(np.eye(3), p), "sphere", {"radius": r}))
    for kind in ("visual", "collision"):
        for frame_T_shape, shape, attrs in parts:
            el = ET.SubElement(link_el, kind)
            _origin(el, link_T_frame @ frame_T_shape)
            ET.SubElement(ET.SubElement(el, "geometry"), shape, attrs)
            if kind == "visual":
                ET.SubElement(el, "material", name=material)


def _fixed_joint(root: ET.Element, name: str, parent: str, child: str, T: FloatArray) -> None:
    j = ET.SubElement(root, "joint", name=name, type="fixed")
    _origin(j, T)
    ET.SubElement(j, "parent", link=parent)
    ET.SubElement(j, "child", link=child)


def robot_to_urdf(robot: Robot, effort: float = DEFAULT_EFFORT) -> str:
    """The robot as a URDF document (see the module docstring for the tree and frames).

    Args:
        robot: the robot description.
        effort: effort limit written for every arm joint [N m] (mmstab has no torque model).

    Returns:
        The URDF XML text (UTF-8, indented).
    """
    root = ET.Element("robot", name=robot.name)
    root.append(
        ET.Comment(
            f" generated by mmstab from robot '{robot.name}' (sha256 {robot.source_hash[:12]}); "
            "base_link = body frame B (x forward, y left, z plane normal); SI units "
        )
    )
    for name, rgba in _MATERIALS.items():
        ET.SubElement(ET.SubElement(root, "material", name=name), "color", rgba=_vec(rgba))
    ET.SubElement(root, "link", name="base_link")

    identity = np.eye(4)
    inertias = base_link_inertias(robot)
    for name, box in robot.base.collision_boxes().items():
        link_el = ET.SubElement(root, "link", name=name)
        _inertial(link_el, identity, inertias[name])
        shape = Box(size=box.size, center=np.zeros(3))  # the link frame is the box's pose
        _shapes(link_el, identity, shape, "body" if name == "body" else "track")
        _fixed_joint(root, f"{name}_joint", "base_link", name, box.frame_T_shape)

    ET.SubElement(root, "link", name="arm_mount")
    _fixed_joint(root, "arm_mount_joint", "base_link", "arm_mount", robot.mount_T)
    parent, parent_T_joint = "arm_mount", identity
    for i, link in enumerate(robot.links):
        name = f"arm_link_{i}"
        j = ET.SubElement(root, "joint", name=f"arm_joint_{i}", type="revolute")
        _origin(j, parent_T_joint @ rot_z_T(link.theta_offset))
        ET.SubElement(j, "parent", link=parent)
        ET.SubElement(j, "child", link=name)
        ET.SubElement(j, "axis", xyz="0 0 1")
        ET.SubElement(
            j,
            "limit",
            lower=_num(link.lower),
            upper=_num(link.upper),
            velocity=_num(link.velocity),
            effort=_num(effort),
        )
        L_T_R = dh_constant_T(link)  # this link's URDF frame L_i -> mmstab's DH frame R_i
        link_el = ET.SubElement(root, "link", name=name)
        _inertial(link_el, L_T_R, arm_link_inertia(link))
        _shapes(link_el, L_T_R, link.geometry, "arm")
        ET.SubElement(root, "link", name=f"arm_frame_{i}")
        _fixed_joint(root, f"arm_frame_{i}_joint", name, f"arm_frame_{i}", L_T_R)
        parent, parent_T_joint = name, L_T_R
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def default_file_mode() -> int:
    """Permissions of a newly created file under the current umask (e.g. 0644)."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def write_urdf(robot: Robot, path: str | os.PathLike[str], effort: float = DEFAULT_EFFORT) -> Path:
    """Write :func:`robot_to_urdf` to ``path`` atomically (temp file + rename).

    Args:
        robot: the robot description.
        path: output file, e.g. ``robot.urdf``; parent folders are created.
        effort: effort limit of the arm joints [N m].

    Raises:
        MmstabError: the file cannot be written.
    """
    p = Path(path)
    text = robot_to_urdf(robot, effort)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(text)
            os.chmod(tmp, default_file_mode())  # mkstemp makes it private (0600)
            os.replace(tmp, p)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError as exc:
        raise MmstabError(f"{p}: cannot write ({exc.strerror})") from None
    return p
