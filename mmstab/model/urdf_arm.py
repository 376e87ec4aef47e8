"""An arm from URDF: a serial chain of revolute joints as the robot file's ``arm:`` section.

An arm usually comes as URDF (its maker's description); mmstab describes it by standard DH
rows (``docs/robot.md``). :func:`build_arm` reads the chain from a base link to a tip link
and :func:`arm_section` writes the section: the mount, one DH row per joint, each link's
mass, CoM and one collision shape, the joint limits, a stowed posture.

**Frames.** At q = 0 each joint's axis is a line in the base link's frame (its joint frame's
origin, its axis as URDF gives it: sign included). R_0 (the mount) has z along joint 1's
axis, its origin at joint 1's origin and x along the base link's x made normal to z. R_i
(i < n) has z along joint i+1's axis and x along the common normal from axis i to axis i+1,
its origin where that normal meets axis i+1; where the two axes meet, x = z_{i-1} x z_i;
where they are parallel, the normal passes through joint i+1's origin, which R_i takes (on
one line, with R_{i-1}'s x). R_n takes the tip link's origin as a virtual axis parallel to
joint n's: R_n sits at the tip link's origin. ``theta_offset`` is the angle from x_{i-1}
to x_i at q = 0, so every joint keeps its URDF zero and sign.

**Links.** Link i is joint i's child link with every link fixed to it (fixed joints,
recursively): masses summed, the CoM mass-weighted, in R_i. Links further along moving
joints that are not on the chain (a gripper's fingers) are left out, with a note. The
collision shape: a URDF link with one box keeps it; otherwise the least-volume capsule
(:mod:`mmstab.model.enclosing`) holding all its collision shapes' points (box corners,
cylinder rims and spheres sampled with the sag added to the radius, mesh vertices). A link
without collision shapes takes its visual ones.

Checked against pinocchio reading the same file (``tests/model/test_urdf_arm.py``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.core.hints import did_you_mean
from mmstab.model.enclosing import enclosing_capsule
from mmstab.model.robot import ArmLink, Box, Capsule, FloatArray, Geometry, homogeneous, rpy_matrix
from mmstab.model.urdf import matrix_to_rpy

#: Points per cylinder rim when a capsule is fitted (the radius gets the chord's sag).
RIM_POINTS = 48
#: Mass given to a link the file leaves without an inertial [kg] (noted).
MASSLESS_KG = 1e-6
MOVING = ("revolute", "continuous")
#: (URDF mesh filename, where it is named) -> the mesh's vertices (n, 3).
MeshReader = Callable[[str, str], FloatArray]


class Shape(NamedTuple):
    """A URDF collision (or visual) shape: ``kind`` box / cylinder / sphere / mesh.

    ``size``: box (x, y, z) [m]; cylinder (radius, length) [m]; sphere (radius,) [m];
    ``points``: a mesh's vertices (scaled) in the shape's frame [m]; ``link_T_shape``: the
    shape's frame in the link frame (4, 4).
    """

    kind: str
    size: FloatArray
    link_T_shape: FloatArray
    points: FloatArray | None = None


@dataclass
class Link:
    """A URDF link: mass [kg], CoM in the link frame [m], collision (or visual) shapes."""

    name: str
    mass: float = 0.0
    com: FloatArray = field(default_factory=lambda: np.zeros(3))
    shapes: list[Shape] = field(default_factory=list)


class Joint(NamedTuple):
    """A URDF joint: ``origin`` is the child frame in the parent's at q = 0 (4, 4)."""

    name: str
    kind: str
    parent: str
    child: str
    origin: FloatArray
    axis: FloatArray
    lower: float | None
    upper: float | None
    velocity: float | None
    mimic: bool


class Arm(NamedTuple):
    """The arm read from URDF: the mount R_0 in the base link (4, 4), rows, notes, links.

    ``base`` and ``tip``: the links it was read between (found where not given).
    """

    base_T_R0: FloatArray
    rows: tuple[ArmLink, ...]
    notes: tuple[str, ...]
    base: str = ""
    tip: str = ""


# ------------------------------------------------------------------------------- reading
def _floats(text: str | None, n: int, default: float = 0.0, what: str = "") -> FloatArray:
    """``n`` finite numbers from attribute ``what``'s text (``default`` each where absent)."""
    if text is None:
        return np.full(n, default)
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        values = np.zeros(0)
    if len(values) != n or not np.isfinite(values).all():
        raise ValueError(f"{what}: {text!r} is not {n} finite number{'s' if n > 1 else ''}")
    return values


def _number(el: ET.Element | None, key: str, what: str, minimum: float | None = None) -> float:
    """A finite number attribute (above ``minimum`` where given); ``what`` names it."""
    text = None if el is None else el.get(key)
    if text is None:
        raise ValueError(f"{what}: missing")
    value = float(_floats(text, 1, what=what)[0])
    if minimum is not None and not value > minimum:
        raise ValueError(f"{what}: {value:g} is not above {minimum:g}")
    return value


def _origin(el: ET.Element | None) -> FloatArray:
    if el is None:
        return np.eye(4)
    rpy = _floats(el.get("rpy"), 3, what=f"<{el.tag} rpy>")
    return homogeneous(rpy_matrix(rpy), _floats(el.get("xyz"), 3, what=f"<{el.tag} xyz>"))


def _shape(el: ET.Element, mesh_file: MeshReader, where: str) -> Shape:
    geometry = el.find("geometry")
    if geometry is None or len(geometry) == 0:
        raise ValueError("a shape without <geometry>")
    g, T = geometry[0], _origin(el.find("origin"))
    if g.tag == "box":
        size = _floats(g.get("size"), 3, what="<box size>")
        if not (size > 0).all():
            raise ValueError(f"<box size>: {g.get('size')!r} is not three lengths above 0")
        return Shape("box", size, T)
    if g.tag == "cylinder":
        radius = _number(g, "radius", "<cylinder radius>", 0.0)
        length = _number(g, "length", "<cylinder length>", 0.0)
        return Shape("cylinder", np.array([radius, length]), T)
    if g.tag == "sphere":
        return Shape("sphere", np.array([_number(g, "radius", "<sphere radius>", 0.0)]), T)
    if g.tag == "mesh":
        scale = _floats(g.get("scale"), 3, 1.0, "<mesh scale>")
        points = mesh_file(g.get("filename", ""), where) * scale
        return Shape("mesh", np.zeros(0), T, points)
    raise ValueError(f"unknown geometry <{g.tag}>")


def _link(el: ET.Element, mesh_file: MeshReader, where: str) -> Link:
    link = Link(el.get("name", ""))
    inertial = el.find("inertial")
    if inertial is not None and inertial.find("mass") is not None:
        link.mass = _number(inertial.find("mass"), "value", "<mass value>")
        if link.mass < 0:
            raise ValueError(f"<mass value>: {link.mass:g} is below 0")
        link.com = _origin(inertial.find("origin"))[:3, 3]
    elements = el.findall("collision") or el.findall("visual")
    link.shapes = [_shape(c, mesh_file, where) for c in elements]
    return link


def _joint(el: ET.Element) -> Joint:
    limit = el.find("limit")

    def attr(key: str, minimum: float | None = None) -> float | None:
        if limit is None or limit.get(key) is None:
            return None
        return _number(limit, key, f"<limit {key}>", minimum)

    axis_el = el.find("axis")
    axis = _floats(None if axis_el is None else axis_el.get("xyz"), 3, what="<axis xyz>")
    if axis_el is None:
        axis = np.array([1.0, 0.0, 0.0])  # URDF's default
    if not np.linalg.norm(axis) > 0:
        raise ValueError("<axis xyz> is the zero vector")
    lower, upper = attr("lower"), attr("upper")
    if lower is not None and upper is not None and lower > upper:
        raise ValueError(f"<limit>: lower {lower:g} is above upper {upper:g}")
    parent, child = el.find("parent"), el.find("child")
    if parent is None or child is None:
        raise ValueError("no <parent> or no <child>")
    return Joint(
        name=el.get("name", ""),
        kind=el.get("type", ""),
        parent=parent.get("link", ""),
        child=child.get("link", ""),
        origin=_origin(el.find("origin")),
        axis=axis / np.linalg.norm(axis),
        lower=lower,
        upper=upper,
        velocity=attr("velocity", 0.0),
        mimic=el.find("mimic") is not None,
    )


def mesh_reader(urdf: Path, package_dirs: Sequence[Path] = ()) -> MeshReader:
    """A function (filename, where) -> vertices (n, 3) [file units] of a URDF mesh.

    ``package://pkg/path`` is looked for under each of ``package_dirs`` and the URDF's
    folders upward (as ``pkg/path``, or ``path`` in a folder named ``pkg``); ``file://`` and
    plain names are paths (relative to the URDF's folder).
    """

    def read(filename: str, where: str) -> FloatArray:
        import trimesh

        candidates: list[Path] = []
        if filename.startswith("package://"):
            pkg, _, rel = filename[len("package://") :].partition("/")
            for folder in [*package_dirs, *urdf.resolve().parents]:
                candidates += [Path(folder) / pkg / rel]
                if Path(folder).name == pkg:
                    candidates += [Path(folder) / rel]
        else:
            path = Path(filename.removeprefix("file://"))
            candidates = [path if path.is_absolute() else urdf.parent / path]
        found = next((c for c in candidates if c.is_file()), None)
        if found is None:
            raise MmstabError(f"{where}: mesh {filename} not found (--package-dir)")
        try:
            mesh = trimesh.load(found, force="mesh")
            return np.array(mesh.vertices, dtype=np.float64)  # type: ignore[attr-defined]
        except Exception as e:  # any reader's failure is the file's
            raise MmstabError(f"{where}: mesh {found}: cannot be read ({e})") from None

    return read


def read_urdf(path: Path, mesh_file: MeshReader) -> tuple[dict[str, Link], dict[str, Joint]]:
    """The links by name and the joints by child link name of a URDF file.

    Raises:
        MmstabError: not a URDF file, or a malformed element (named).
    """
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as e:
        raise MmstabError(f"{path}: not a readable URDF file ({e})") from None
    if root.tag != "robot":
        raise MmstabError(f"{path}: not a URDF file (root <{root.tag}>, not <robot>)")
    links: dict[str, Link] = {}
    for el in root.findall("link"):
        where = f"{path}: link {el.get('name', '')}"
        try:
            links[el.get("name", "")] = _link(el, mesh_file, where)
        except ValueError as e:
            raise MmstabError(f"{where}: {e}") from None
    joints = []
    for el in root.findall("joint"):
        try:
            joints.append(_joint(el))
        except ValueError as e:
            raise MmstabError(f"{path}: joint {el.get('name', '')}: {e}") from None
        for role in ("parent", "child"):
            name = getattr(joints[-1], role)
            if name not in links:
                raise MmstabError(
                    f"{path}: joint {joints[-1].name}: {role} {name!r} is no link of the file"
                    f"{did_you_mean(name, list(links))}"
                )
    return links, {j.child: j for j in joints}


# ------------------------------------------------------------------------------ geometry
def _dh_step(
    o: FloatArray, x: FloatArray, z: FloatArray, p: FloatArray, w: FloatArray
) -> tuple[FloatArray, FloatArray, tuple[float, float, float, float]]:
    """Frame i (origin, x) from frame i-1 (o, x, z) and axis i+1 (point p, direction w).

    Returns the origin, x axis and the DH row (a, alpha, d, theta) at q = 0.
    """
    cross = np.cross(z, w)
    if np.linalg.norm(cross) > 1e-9:  # skew or meeting: the common normal
        # closest points o + s z and p + t w of the two lines
        r = p - o
        A = np.array([[1.0, -z @ w], [z @ w, -1.0]])
        s, t = np.linalg.solve(A, [r @ z, r @ w])
        c1, c2 = o + s * z, p + t * w
        gap = c2 - c1
        if np.linalg.norm(gap) > 1e-9:
            x_new = gap / np.linalg.norm(gap)
        else:
            x_new, c2 = cross / np.linalg.norm(cross), c1
    else:  # parallel (or one line): the normal through p, so R_i sits at p
        c1, c2 = o + ((p - o) @ z) * z, p
        gap = c2 - c1
        x_new = gap / np.linalg.norm(gap) if np.linalg.norm(gap) > 1e-9 else x
    d = float((c1 - o) @ z)
    a = float((c2 - c1) @ x_new)
    theta = math.atan2(float(np.cross(x, x_new) @ z), float(x @ x_new))
    alpha = math.atan2(float(np.cross(z, w) @ x_new), float(z @ w))
    return c2, x_new, (a, alpha, d, theta)


def _frame(o: FloatArray, x: FloatArray, z: FloatArray) -> FloatArray:
    return homogeneous(np.column_stack([x, np.cross(z, x), z]), o)


def _shape_points(shape: Shape) -> tuple[FloatArray, float]:
    """Points of a shape in its frame (n, 3) [m] and how far the shape reaches past them [m]."""
    if shape.kind == "box":
        h = shape.size / 2
        return np.array(
            [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
        ) * h, 0.0
    if shape.kind == "cylinder":
        r, length = shape.size
        phi = np.linspace(0, 2 * np.pi, RIM_POINTS, endpoint=False)
        rim = np.c_[r * np.cos(phi), r * np.sin(phi)]
        pts = np.r_[
            np.c_[rim, np.full(RIM_POINTS, -length / 2)],
            np.c_[rim, np.full(RIM_POINTS, length / 2)],
        ]
        return pts, r * (1 - math.cos(math.pi / RIM_POINTS))
    if shape.kind == "sphere":
        import trimesh

        ball = trimesh.creation.icosphere(subdivisions=2, radius=float(shape.size[0]))
        inner = float(
            np.min(np.abs(np.einsum("ij,ij->i", ball.face_normals, ball.triangles[:, 0])))
        )
        return np.asarray(ball.vertices), float(shape.size[0]) - inner
    assert shape.points is not None
    return shape.points, 0.0


def _geometry(shapes: list[tuple[Shape, FloatArray]]) -> Geometry:
    """One collision shape in R_i for a link's shapes (each with its pose in R_i)."""
    if len(shapes) == 1 and shapes[0][0].kind == "box":
        shape, T = shapes[0]
        return Box(shape.size.copy(), T[:3, 3].copy(), matrix_to_rpy(T[:3, :3]))
    clouds, reach = [], 0.0
    for shape, T in shapes:
        pts, r = _shape_points(shape)
        clouds.append(pts @ T[:3, :3].T + T[:3, 3])
        reach = max(reach, r)
    return enclosing_capsule(np.concatenate(clouds), reach)


# --------------------------------------------------------------------------------- chain
def _path_up(joints: dict[str, Joint], tip: str, base: str) -> list[Joint] | None:
    """The joints from ``base`` down to ``tip``, or None where ``tip`` is not below it."""
    chain: list[Joint] = []
    at = tip
    while at != base:
        if at not in joints or len(chain) > len(joints):  # the root, or a loop
            return None
        chain.append(joints[at])
        at = joints[at].parent
    return chain[::-1]


def _chain(
    links: dict[str, Link], joints: dict[str, Joint], base: str | None, tip: str | None
) -> list[Joint]:
    """The joints from ``base`` to ``tip``; without them, the file's root and its one tip.

    The tip, when not given, is the leaf link below the most revolute joints, reached through
    revolute, continuous and fixed joints only (a gripper's prismatic finger is no tip).
    """
    for role, name in (("--base", base), ("--tip", tip)):
        if name is not None and name not in links:
            raise MmstabError(f"{role}: no link {name!r}{did_you_mean(name, list(links))}")
    if base is None:
        roots = sorted(n for n in links if n not in joints)
        if len(roots) != 1:
            raise MmstabError(f"--base: the file has {len(roots)} root links; give one")
        base = roots[0]
    if tip is None:
        parents = {j.parent for j in joints.values()}
        paths = {n: _path_up(joints, n, base) for n in links if n not in parents}
        arms = {n: c for n, c in paths.items()
                if c and all(j.kind in (*MOVING, "fixed") and not j.mimic for j in c)}  # fmt: skip
        most = max((sum(j.kind in MOVING for j in c) for c in arms.values()), default=0)
        tips = sorted(n for n, c in arms.items() if sum(j.kind in MOVING for j in c) == most)
        if most == 0 or len(tips) != 1:
            listed = ", ".join(tips) or "none"
            raise MmstabError(
                f"--tip: no single tip below {base!r} (candidates: {listed}); give one"
            )
        tip = tips[0]
    chain = _path_up(joints, tip, base)
    if chain is None:
        raise MmstabError(f"--tip: link {tip!r} does not hang below --base {base!r}")
    return chain


def build_arm(
    path: str | Path,
    base: str | None = None,
    tip: str | None = None,
    package_dirs: Sequence[str | Path] = (),
) -> Arm:
    """The arm of a URDF file from link ``base`` to link ``tip``, in DH (module docstring).

    Without ``base``, the file's root link; without ``tip``, the one leaf link below the most
    revolute joints (refused, listing them, where several tie).

    Raises:
        MmstabError: a missing file or link (with the closest name), no chain between the
            two, a joint on it that is not revolute, continuous or fixed, a mimic joint, a
            joint without a velocity limit, a mesh that cannot be found or read.
    """
    path = Path(path)
    if not path.is_file():
        raise MmstabError(f"{path}: no such URDF file")
    links, joints = read_urdf(path, mesh_reader(path, [Path(p) for p in package_dirs]))
    chain = _chain(links, joints, base, tip)
    if not chain:
        raise MmstabError(f"{path}: no joint between {base} and {tip}")
    base, tip = chain[0].parent, chain[-1].child  # found, where not given
    for j in chain:
        if j.kind not in (*MOVING, "fixed"):
            raise MmstabError(
                f"{path}: joint {j.name} is {j.kind!r}: mmstab's arm has revolute joints only"
            )
        if j.kind in MOVING and j.mimic:
            raise MmstabError(f"{path}: joint {j.name} mimics another: not an independent joint")
        if j.kind in MOVING and j.velocity is None:
            raise MmstabError(f"{path}: joint {j.name}: no <limit velocity=...> [rad/s]")
    moving = [j for j in chain if j.kind in MOVING]
    if not moving:
        raise MmstabError(f"{path}: no revolute joint between {base} and {tip}")
    # every link's pose in the base link at q = 0, along the chain and its fixed branches
    pose = {base: np.eye(4)}
    for j in chain:
        pose[j.child] = pose[j.parent] @ j.origin
    children: dict[str, list[Joint]] = {}
    for j in joints.values():
        children.setdefault(j.parent, []).append(j)
    on_chain = {j.child for j in chain} | {base}
    notes: list[str] = []

    def group(first: str) -> list[str]:
        """``first`` and the links fixed to it, not along the chain's next moving joint."""
        out, todo = [], [first]
        while todo:
            name = todo.pop()
            out.append(name)
            for j in children.get(name, []):
                if j.child in on_chain and j.kind in MOVING:
                    continue
                pose.setdefault(j.child, pose[name] @ j.origin)
                if j.kind == "fixed":
                    todo.append(j.child)
                elif j.child not in on_chain:
                    notes.append(
                        f"link {j.child} (joint {j.name}, {j.kind}) left out: not on the chain"
                    )
        return out

    # the joints' axes at q = 0 and the DH frames
    axes = [(pose[j.child][:3, 3], pose[j.child][:3, :3] @ j.axis) for j in moving]
    z0 = axes[0][1]
    hint = np.array([1.0, 0.0, 0.0]) if abs(z0[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x0 = hint - (hint @ z0) * z0
    o, x, z = axes[0][0], x0 / np.linalg.norm(x0), z0
    base_T_R0, rows = _frame(o, x, z), []
    for i, j in enumerate(moving):
        p, w = axes[i + 1] if i + 1 < len(moving) else (pose[tip][:3, 3], z)
        o, x, (a, alpha, d, theta) = _dh_step(o, x, z, p, w)
        z = w
        R_i = _frame(o, x, z)
        members = group(j.child)
        mass = sum(links[m].mass for m in members)
        coms = [pose[m][:3, :3] @ links[m].com + pose[m][:3, 3] for m in members]
        if mass > 0:
            com_base = sum(links[m].mass * c for m, c in zip(members, coms, strict=True)) / mass
        else:
            mass, com_base = MASSLESS_KG, R_i[:3, 3]
            notes.append(f"link {j.child} has no mass: {MASSLESS_KG:g} kg at its frame's origin")
        inv = np.linalg.inv(R_i)
        com = (inv @ np.r_[com_base, 1.0])[:3]
        shapes = [(s, inv @ pose[m] @ s.link_T_shape) for m in members for s in links[m].shapes]
        if shapes:
            geometry = _geometry(shapes)
        else:
            geometry = Capsule(0.01, com.copy(), com.copy())
            notes.append(f"link {j.child} has no shapes: a 1 cm sphere at its CoM")
        lower, upper = (j.lower, j.upper) if j.kind == "revolute" else (-math.pi, math.pi)
        rows.append(
            ArmLink(
                name=j.child, a=a, alpha=alpha, d=d, theta_offset=theta, mass=float(mass),
                com=com, geometry=geometry,
                lower=float(lower if lower is not None else -math.pi),
                upper=float(upper if upper is not None else math.pi),
                velocity=float(j.velocity),  # type: ignore[arg-type]
            )
        )  # fmt: skip
    return Arm(base_T_R0, tuple(rows), tuple(notes), chain[0].parent, chain[-1].child)


def _clean(v: ArrayLike) -> list[float]:
    """Numbers for the file: 1e-12 and below as 0, 12 significant digits."""
    return [0.0 if abs(x) < 1e-12 else float(f"{x:.12g}") for x in np.ravel(np.asarray(v, float))]


def arm_section(arm: Arm, B_T_base: ArrayLike | None = None) -> dict[str, Any]:
    """The robot file's ``arm:`` section of an imported arm.

    Args:
        arm: :func:`build_arm`'s answer.
        B_T_base: the URDF base link's pose in the body frame B (4, 4) [m]; None: B itself.
    """
    B_T_R0 = (np.eye(4) if B_T_base is None else np.asarray(B_T_base, float)) @ arm.base_T_R0
    links = []
    for r in arm.rows:
        shape = r.geometry
        g: dict[str, Any]
        if isinstance(shape, Box):
            g = {"type": "box", "size": _clean(shape.size), "center": _clean(shape.center),
                 "rpy": _clean(shape.rpy)}  # fmt: skip
        else:
            g = {"type": "capsule", "radius": float(f"{shape.radius:.12g}"),
                 "p0": _clean(shape.p0), "p1": _clean(shape.p1)}  # fmt: skip
        a, alpha, d, theta = _clean([r.a, r.alpha, r.d, r.theta_offset])
        links.append({
            "name": r.name, "dh": {"a": a, "alpha": alpha, "d": d, "theta_offset": theta},
            "mass": float(f"{r.mass:.12g}"), "com": _clean(r.com), "geometry": g,
            "limits": {"lower": r.lower, "upper": r.upper, "velocity": r.velocity},
        })  # fmt: skip
    stowed = [float(np.clip(0.0, r.lower, r.upper)) for r in arm.rows]
    return {
        "mount": {"xyz": _clean(B_T_R0[:3, 3]), "rpy": _clean(matrix_to_rpy(B_T_R0[:3, :3]))},
        "links": links,
        "stowed": stowed,
    }
