"""An arm read from URDF (``mmstab arm-from-urdf``) against pinocchio reading the same file.

The URDFs are drawn by the tests: 3-6 joints whose axes point anywhere (some meeting, some
parallel, one continuous), joint origins turned by any rpy, links with a cylinder, a box, a
sphere and a box, or a mesh found through ``package://``, a tool fixed past the last joint,
and a prismatic finger off the chain. mmstab's DH arm must put every link's mass where
pinocchio does, and its one shape per link must hold all of the URDF's shapes.
"""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import SCOUT

from mmstab.cli import main
from mmstab.core.files import MmstabError
from mmstab.model.enclosing import enclosing_capsule
from mmstab.model.robot import link_extent_warnings, load_robot, robot_from_dict, rpy_matrix
from mmstab.model.urdf import write_urdf
from mmstab.model.urdf_arm import arm_section, build_arm

pin = pytest.importorskip("pinocchio")
trimesh = pytest.importorskip("trimesh")

ROOT = Path(__file__).resolve().parents[2]
#: URDF readers (urdfdom, pinocchio's) want an inertia in every inertial; mmstab reads none
INERTIA = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'


def _v(x) -> str:
    return " ".join(f"{float(v)!r}" for v in x)


def _shapes(kind: str, rng: np.random.Generator, mesh: str) -> tuple[str, list[tuple]]:
    """A link's collision XML and its shapes (kind, size, T in the link)."""

    def pose():
        return rng.uniform(-0.05, 0.05, 3), rng.uniform(-np.pi, np.pi, 3)

    out, xml = [], ""
    kinds = {"two": ["box", "sphere"]}.get(kind, [kind])
    for k in kinds:
        xyz, rpy = pose()
        if k == "box":
            size = rng.uniform(0.03, 0.2, 3)
            geom = f'<box size="{_v(size)}"/>'
        elif k == "cylinder":
            size = np.array([rng.uniform(0.02, 0.06), rng.uniform(0.1, 0.4)])
            geom = f'<cylinder radius="{size[0]:.17g}" length="{size[1]:.17g}"/>'
        elif k == "sphere":
            size = np.array([rng.uniform(0.02, 0.08)])
            geom = f'<sphere radius="{size[0]:.17g}"/>'
        else:
            size = np.zeros(0)
            geom = f'<mesh filename="{mesh}" scale="0.5 0.5 0.5"/>'
        xml += (f'<collision><origin xyz="{_v(xyz)}" rpy="{_v(rpy)}"/><geometry>{geom}'
                "</geometry></collision>")  # fmt: skip
        out.append((k, size, xyz, rpy))
    return xml, out


def random_arm_urdf(rng: np.random.Generator, folder: Path) -> tuple[Path, dict]:
    """A URDF of a base, a mounted arm, a tool and a finger; what it holds, for the checks."""
    n = int(rng.integers(3, 7))
    pkg = folder / "arm_pkg" / "meshes"
    pkg.mkdir(parents=True)
    trimesh.creation.capsule(height=0.3, radius=0.04).export(pkg / "link.stl")
    axes = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]
    kinds = ["cylinder", "box", "two", "mesh", "sphere"]
    xml = ['<robot name="drawn">',
           f'<link name="base_link"><inertial><mass value="10"/>{INERTIA}</inertial></link>',
           f'<link name="arm_base"><inertial><mass value="0.5"/>{INERTIA}</inertial></link>',
           f'<joint name="mount" type="fixed"><parent link="base_link"/><child link="arm_base"/>'
           f'<origin xyz="{_v(rng.uniform(-0.2, 0.2, 3))}" rpy="{_v(rng.uniform(-1, 1, 3))}"/>'
           "</joint>"]  # fmt: skip
    spec: dict = {"joints": [], "links": {}}
    parent = "arm_base"
    for i in range(n):
        name = f"l{i}"
        axis = axes[int(rng.integers(3))] if rng.random() < 0.6 else rng.normal(size=3)
        # some joints on the previous axis' line or turned by quarter turns: axes that meet
        # or run parallel, as real arms have
        xyz = rng.uniform(-0.25, 0.25, 3) * (rng.random() < 0.8)
        rpy = (rng.integers(-2, 3, 3) * np.pi / 2) if rng.random() < 0.5 else rng.uniform(-3, 3, 3)
        kind = "continuous" if i == 0 else "revolute"
        low, high, speed = rng.uniform(-2.5, -0.5), rng.uniform(0.5, 2.5), rng.uniform(1, 3)
        limit = (f'<limit lower="{low:.17g}" upper="{high:.17g}" effort="10" '
                 f'velocity="{speed:.17g}"/>')  # fmt: skip
        if kind == "continuous":
            limit = '<limit effort="10" velocity="2.0"/>'
        xml.append(f'<joint name="j{i}" type="{kind}"><parent link="{parent}"/>'
                   f'<child link="{name}"/><origin xyz="{_v(xyz)}" rpy="{_v(rpy)}"/>'
                   f'<axis xyz="{_v(axis)}"/>{limit}</joint>')  # fmt: skip
        shapes_xml, shapes = _shapes(
            kinds[i % len(kinds)], rng, "package://arm_pkg/meshes/link.stl"
        )
        com, mass = rng.uniform(-0.1, 0.1, 3), rng.uniform(0.5, 3)
        xml.append(f'<link name="{name}"><inertial><origin xyz="{_v(com)}"/><mass value='
                   f'"{mass:.17g}"/>{INERTIA}</inertial>{shapes_xml}</link>')  # fmt: skip
        spec["joints"].append(f"j{i}")
        spec["links"][name] = shapes
        parent = name
    tool_shapes, shapes = _shapes("sphere", rng, "")
    xml += [f'<joint name="flange" type="fixed"><parent link="{parent}"/><child link="tool"/>'
            f'<origin xyz="{_v(rng.uniform(-0.1, 0.1, 3))}" rpy="0 0.3 0"/></joint>',
            f'<link name="tool"><inertial><mass value="0.4"/>{INERTIA}</inertial>'
            f"{tool_shapes}</link>",
            f'<joint name="finger" type="prismatic"><parent link="{parent}"/>'
            '<child link="finger"/><axis xyz="0 1 0"/>'
            '<limit lower="0" upper="0.04" effort="1" velocity="0.1"/></joint>',
            '<link name="finger"><inertial><mass value="0.2"/>' + INERTIA + "</inertial></link>",
            "</robot>"]  # fmt: skip
    spec["links"]["tool"] = shapes
    spec["tip_parent"] = parent
    path = folder / "drawn.urdf"
    path.write_text("\n".join(xml))
    return path, spec


def robot_with_arm(section: dict):
    data = copy.deepcopy(SCOUT)
    data["arm"] = section
    data["name"] = "drawn"
    return robot_from_dict(data, "drawn.yaml")


def pinocchio_state(model, data, joints: list[str], q: np.ndarray) -> None:
    qp = pin.neutral(model)
    for name, qi in zip(joints, q, strict=True):
        j = model.joints[model.getJointId(name)]
        if j.nq == 2:  # a continuous joint: (cos, sin)
            qp[j.idx_q : j.idx_q + 2] = np.cos(qi), np.sin(qi)
        else:
            qp[j.idx_q] = qi
    pin.forwardKinematics(model, data, qp)
    pin.updateFramePlacements(model, data)


def shape_points(rng, kind, size, mesh_points) -> np.ndarray:
    """Points on a shape's surface in its own frame: corners, rims, a sphere, vertices."""
    if kind == "box":
        return np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * size / 2
    if kind == "cylinder":
        phi = rng.uniform(0, 2 * np.pi, 400)
        z = np.where(rng.random(400) < 0.5, -1, 1) * size[1] / 2
        return np.c_[size[0] * np.cos(phi), size[0] * np.sin(phi), z]
    if kind == "sphere":
        u = rng.normal(size=(400, 3))
        return size[0] * u / np.linalg.norm(u, axis=1, keepdims=True)
    return mesh_points


def inside(points: np.ndarray, geometry, B_T_R: np.ndarray) -> np.ndarray:
    """How far each point (in B) lies outside the link's shape (<= 0: inside) [m]."""
    local = (points - B_T_R[:3, 3]) @ B_T_R[:3, :3]
    if geometry.kind == "box":
        p = (local - geometry.center) @ rpy_matrix(geometry.rpy)
        return np.max(np.abs(p) - geometry.size / 2, axis=1)
    a, b = geometry.p0, geometry.p1
    ab = b - a
    t = np.clip((local - a) @ ab / max(ab @ ab, 1e-30), 0, 1)
    return np.linalg.norm(local - (a + np.outer(t, ab)), axis=1) - geometry.radius


@pytest.mark.parametrize("seed", [1, 2, 4])
def test_a_drawn_arm_puts_its_mass_and_shapes_where_pinocchio_does(seed, tmp_path):
    rng = np.random.default_rng(seed)
    path, spec = random_arm_urdf(rng, tmp_path)
    arm = build_arm(path, "base_link", "tool")
    assert any("finger" in note for note in arm.notes)  # the prismatic finger: left out
    robot = robot_with_arm(arm_section(arm))
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    chain = [model.getJointId(j) for j in spec["joints"]]
    assert [r.name for r in arm.rows] == list(spec["links"])[:-1]
    mesh = np.asarray(trimesh.load(tmp_path / "arm_pkg" / "meshes" / "link.stl").vertices) * 0.5
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (20, robot.arm_joints))
    frames = robot.kinematics.link_frames(q)
    for k, qk in enumerate(q):
        pinocchio_state(model, data, spec["joints"], qk)
        # the arm's CoM: pinocchio's inertias of the chain's joints (the tool folded into
        # the last one; the finger's joint and the base's links are not the arm)
        mass = sum(model.inertias[j].mass for j in chain)
        com = sum(model.inertias[j].mass * (data.oMi[j].act(model.inertias[j].lever))
                  for j in chain) / mass  # fmt: skip
        np.testing.assert_allclose(robot.arm_com(qk), com, rtol=0, atol=1e-9)
        # the tip frame R_n sits at the tool's origin
        tool = data.oMf[model.getFrameId("tool")].translation
        np.testing.assert_allclose(frames[k, -1, :3, 3], tool, rtol=0, atol=1e-9)
        # every URDF shape lies inside its link's one shape (the tool inside the last's)
        for name, shapes in spec["links"].items():
            i = len(arm.rows) - 1 if name == "tool" else int(name[1:])
            oMf = data.oMf[model.getFrameId(name)]
            for kind, size, xyz, rpy in shapes:
                pts = shape_points(rng, kind, size, mesh) @ rpy_matrix(rpy).T + xyz
                world = pts @ oMf.rotation.T + oMf.translation
                gap = inside(world, robot.links[i].geometry, frames[k, i])
                assert gap.max() <= 1e-9, (name, kind, gap.max())
    # the limits as the file gives them; the continuous joint gets one turn
    assert robot.links[0].lower == -math.pi and robot.links[0].upper == math.pi
    assert robot.links[0].velocity == 2.0


def test_mmstabs_own_export_comes_back(robot, rng, tmp_path):
    """The Cameleon through ``mmstab urdf`` and back: the same DH rows, masses and shapes."""
    path = write_urdf(robot, tmp_path / "c.urdf")
    # base_link is the body frame B: the section's mount is the export's arm_mount
    back = robot_with_arm(arm_section(build_arm(path, "base_link", "arm_frame_3")))
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (200, 4))
    np.testing.assert_allclose(back.kinematics.link_frames(q), robot.kinematics.link_frames(q),
                               rtol=0, atol=1e-9)  # fmt: skip
    np.testing.assert_allclose(back.arm_com(q), robot.arm_com(q), rtol=0, atol=1e-9)
    for mine, theirs in zip(robot.links, back.links, strict=True):
        assert (theirs.mass, theirs.lower, theirs.upper) == (mine.mass, mine.lower, mine.upper)
        assert theirs.geometry.kind == mine.geometry.kind
        if mine.geometry.kind == "capsule":  # a cylinder and two spheres, fitted again
            assert mine.geometry.radius <= theirs.geometry.radius <= mine.geometry.radius + 1e-3
            ends = sorted([theirs.geometry.p0.tolist(), theirs.geometry.p1.tolist()])
            want = sorted([mine.geometry.p0.tolist(), mine.geometry.p1.tolist()])
            np.testing.assert_allclose(ends, want, atol=1e-6)


def test_the_capsule_is_the_least_one_for_points_on_a_capsule(rng):
    """Points drawn on a tilted capsule's surface give that capsule back."""
    a, b, r = rng.normal(size=3), rng.normal(size=3), 0.07
    u = rng.normal(size=(3000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    t = rng.uniform(0, 1, 3000)[:, None]
    axis = (b - a) / np.linalg.norm(b - a)
    radial = u - np.outer(u @ axis, axis)
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    pts = np.r_[a + t * (b - a) + r * radial, a + r * u[:500], b + r * u[500:1000]]
    cap = enclosing_capsule(pts)
    assert r <= cap.radius <= r + 1e-3
    ends = sorted([cap.p0.tolist(), cap.p1.tolist()])
    np.testing.assert_allclose(ends, sorted([a.tolist(), b.tolist()]), atol=2e-3)


def test_the_command_writes_a_section_a_robot_file_takes(tmp_path, capsys):
    path, _ = random_arm_urdf(np.random.default_rng(7), tmp_path)
    out = tmp_path / "arm.yaml"
    argv = ["arm-from-urdf", str(path), "--base", "base_link", "--tip", "tool", "-o", str(out),
            "--mount", "0.1", "0", "0.2", "0", "0", "0.5"]  # fmt: skip
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "finger" in captured.err and "arm-from-urdf: " in captured.out
    robot = copy.deepcopy(SCOUT)
    robot["arm"] = yaml.safe_load(out.read_text())["arm"]
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(robot))
    loaded = load_robot(tmp_path / "r.yaml")
    alone = robot_with_arm(arm_section(build_arm(path, "base_link", "tool")))
    q = np.zeros(loaded.arm_joints)
    # the mount moves the whole arm: the base link 0.1 m ahead, 0.2 m up, turned 0.5 rad
    c, s = math.cos(0.5), math.sin(0.5)
    turned = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ alone.arm_com(q) + [0.1, 0, 0.2]
    np.testing.assert_allclose(loaded.arm_com(q), turned, atol=1e-9)


def test_without_base_and_tip_the_root_and_the_one_tip_are_read(tmp_path, capsys):
    path, _ = random_arm_urdf(np.random.default_rng(5), tmp_path)
    arm = build_arm(path)  # leaves: the tool, and the finger behind its prismatic joint
    assert (arm.base, arm.tip) == ("base_link", "tool")
    assert arm_section(arm) == arm_section(build_arm(path, "base_link", "tool"))
    assert main(["arm-from-urdf", str(path)]) == 0
    assert capsys.readouterr().out.startswith(
        f"# The arm of {path} from link base_link to link tool"
    )
    ur5 = ur5_urdf(tmp_path)  # a camera fixed beside the flange: two tips tie
    ur5.write_text(ur5.read_text().replace("</robot>", '<joint name="cam" type="fixed">'
                   '<parent link="wrist_3"/><child link="camera"/></joint><link name="camera"/>'
                   "</robot>"))  # fmt: skip
    assert main(["arm-from-urdf", str(ur5)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("mmstab: error: --tip: no single tip below 'base_link' "
                   "(candidates: camera, tool0); give one")  # fmt: skip


def test_meshes_of_a_package_elsewhere_are_found_with_package_dir(tmp_path, capsys):
    urdf_dir, packages = tmp_path / "robot", tmp_path / "src"
    urdf_dir.mkdir()
    packages.mkdir()
    path, _ = random_arm_urdf(np.random.default_rng(3), urdf_dir)
    beside = arm_section(build_arm(path, "base_link", "tool"))  # the package beside the URDF
    (urdf_dir / "arm_pkg").rename(packages / "arm_pkg")
    argv = ["arm-from-urdf", str(path), "--base", "base_link", "--tip", "tool"]
    assert main(argv) == 2
    assert "mesh package://arm_pkg/meshes/link.stl not found" in capsys.readouterr().err
    assert main([*argv, "--package-dir", str(packages)]) == 0
    assert yaml.safe_load(capsys.readouterr().out)["arm"] == beside


@pytest.mark.parametrize(
    ("edit", "args", "message"),
    [
        (None, ["--tip", "tol"], "--tip: no link 'tol'; did you mean 'tool'?"),
        (None, ["--tip", "base_link", "--base", "tool"], "does not hang below --base"),
        (("finger", "tool"), ["--tip", "finger"], "joint finger is 'prismatic'"),
        (("arm_pkg", "no_pkg"), [], "mesh package://no_pkg/meshes/link.stl not found"),
        (('velocity="2.0"', ""), [], "joint j0: no <limit velocity=...> [rad/s]"),
        (("<robot", "<rob"), [], "not a readable URDF file"),
        (None, ["--mount", "0", "0", "0.3", "0", "0", "90"], "--mount: yaw: 90 looks like degrees"),
    ],
)
def test_bad_input_is_one_line_and_nothing_written(tmp_path, capsys, edit, args, message):
    path, _ = random_arm_urdf(np.random.default_rng(3), tmp_path)
    if edit is not None and edit[0] != "finger":
        path.write_text(path.read_text().replace(*edit))
    out = tmp_path / "arm.yaml"
    argv = ["arm-from-urdf", str(path), "--base", "base_link", "--tip", "tool", *args]
    assert main([*argv, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not out.exists()


def test_a_chain_without_a_revolute_joint_is_refused(tmp_path):
    robot = load_robot(ROOT / "problems" / "robots" / "cameleon.yaml")
    path = write_urdf(robot, tmp_path / "c.urdf")
    with pytest.raises(MmstabError, match="no revolute joint"):
        build_arm(path, "base_link", "body")  # a fixed link of the base: no arm there


def ur5_urdf(folder: Path) -> Path:
    """A UR5's kinematics as ROS describes it (joint origins from its published geometry),
    each link a cylinder about its body, a fixed ``tool0`` at the flange."""
    joints = [  # name, parent, child, xyz, rpy, axis
        ("shoulder_pan", "base_link", "shoulder", "0 0 0.089159", "0 0 0", "0 0 1"),
        ("shoulder_lift", "shoulder", "upper_arm", "0 0.13585 0", "0 1.5707963267948966 0",
         "0 1 0"),
        ("elbow", "upper_arm", "forearm", "0 -0.1197 0.425", "0 0 0", "0 1 0"),
        ("wrist_1", "forearm", "wrist_1", "0 0 0.39225", "0 1.5707963267948966 0", "0 1 0"),
        ("wrist_2", "wrist_1", "wrist_2", "0 0.093 0", "0 0 0", "0 0 1"),
        ("wrist_3", "wrist_2", "wrist_3", "0 0 0.09465", "0 0 0", "0 1 0"),
    ]  # fmt: skip
    bodies = {"shoulder": (0.06, 0.15, "0 0 0"), "upper_arm": (0.06, 0.425, "0 0 0.2125"),
              "forearm": (0.05, 0.39, "0 0 0.196"), "wrist_1": (0.045, 0.1, "0 0 0"),
              "wrist_2": (0.045, 0.1, "0 0 0"), "wrist_3": (0.04, 0.05, "0 0 0")}  # fmt: skip
    masses = {"shoulder": 3.7, "upper_arm": 8.393, "forearm": 2.275, "wrist_1": 1.219,
              "wrist_2": 1.219, "wrist_3": 0.1879}  # fmt: skip
    xml = ['<robot name="ur5">', f'<link name="base_link"><inertial><mass value="4"/>{INERTIA}'
           "</inertial></link>"]  # fmt: skip
    for name, parent, child, xyz, rpy, axis in joints:
        xml.append(f'<joint name="{name}" type="revolute"><parent link="{parent}"/>'
                   f'<child link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/>'
                   f'<axis xyz="{axis}"/><limit lower="-6.2831853" upper="6.2831853" '
                   'effort="150" velocity="3.15"/></joint>')  # fmt: skip
        r, length, at = bodies[child]
        xml.append(f'<link name="{child}"><inertial><mass value="{masses[child]}"/>{INERTIA}'
                   f'</inertial><collision><origin xyz="{at}"/><geometry><cylinder radius='
                   f'"{r}" length="{length}"/></geometry></collision></link>')  # fmt: skip
    xml += ['<joint name="flange" type="fixed"><parent link="wrist_3"/><child link="tool0"/>'
            '<origin xyz="0 0.0823 0" rpy="-1.5707963267948966 0 0"/></joint>',
            '<link name="tool0"/>', "</robot>"]  # fmt: skip
    path = folder / "ur5.urdf"
    path.write_text("\n".join(xml))
    return path


def ur5_flange(q: np.ndarray) -> np.ndarray:
    """The UR5's flange in its base by the published DH table (by hand), in ROS's base_link.

    d = (0.089159, 0, 0, 0.10915, 0.09465, 0.0823), a = (0, -0.425, -0.39225, 0, 0, 0),
    alpha = (pi/2, 0, 0, pi/2, -pi/2, 0); ROS's base_link is the DH base turned by pi.
    """
    d = [0.089159, 0, 0, 0.10915, 0.09465, 0.0823]
    a = [0, -0.425, -0.39225, 0, 0, 0]
    alpha = [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]
    T = np.diag([-1.0, -1.0, 1.0, 1.0])  # Rz(pi)
    for qi, di, ai, al in zip(q, d, a, alpha, strict=True):
        c, s, ca, sa = np.cos(qi), np.sin(qi), np.cos(al), np.sin(al)
        T = T @ np.array([[c, -s * ca, s * sa, ai * c], [s, c * ca, -c * sa, ai * s],
                          [0, sa, ca, di], [0, 0, 0, 1]])  # fmt: skip
    return T[:3, 3]


def test_a_ur5_gives_its_published_flange_and_no_off_segment_link(tmp_path, rng):
    arm = build_arm(ur5_urdf(tmp_path), "base_link", "tool0")
    robot = robot_with_arm(arm_section(arm))
    q = rng.uniform(-np.pi, np.pi, (100, 6))
    flange = robot.kinematics.link_frames(q)[:, -1, :3, 3]
    np.testing.assert_allclose(flange, [ur5_flange(qi) for qi in q], rtol=0, atol=1e-9)
    # its links sit off their DH segments only along the joint axes (shoulder, elbow offsets)
    assert link_extent_warnings(robot) == []


#: What a mutation writes into one attribute of a URDF.
MUTATIONS = ("", "abc", "nan", "1e309", "0 0", "-1")


@pytest.mark.parametrize("seed", range(8))
def test_a_mutated_urdf_gives_a_loadable_arm_or_one_line(seed, tmp_path, capsys):
    """One attribute replaced (and sometimes an element dropped) in a drawn URDF or the UR5:
    exit 0 with a section a robot file takes, or exit 2 with one line naming the file."""
    rng = np.random.default_rng([2026, seed])
    if seed % 2:
        path, tip = random_arm_urdf(np.random.default_rng(seed % 5), tmp_path)[0], "tool"
    else:
        path, tip = ur5_urdf(tmp_path), "tool0"
    text = path.read_text()
    attrs = list(re.finditer(r'(\w+)="([^"]*)"', text))
    m = attrs[rng.integers(len(attrs))]
    text = text[: m.start(2)] + MUTATIONS[rng.integers(len(MUTATIONS))] + text[m.end(2) :]
    if rng.random() < 0.3:
        tags = list(re.finditer(r"<(origin|axis|limit|mass|geometry|parent|child)[^>]*/>", text))
        t = tags[rng.integers(len(tags))]
        text = text[: t.start()] + text[t.end() :]
    path.write_text(text)
    out = tmp_path / "arm.yaml"
    status = main(["arm-from-urdf", str(path), "--base", "base_link", "--tip", tip, "-o", str(out)])
    err = [ln for ln in capsys.readouterr().err.splitlines() if "note:" not in ln]
    if status == 0:
        robot_with_arm(yaml.safe_load(out.read_text())["arm"])  # loads, or raises
    else:
        assert status == 2 and len(err) == 1 and str(path) in err[0], err
        assert not out.exists()
