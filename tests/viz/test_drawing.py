"""3-D drawing of the robot and the fig. 6(a) 3-D panel."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from mmstab.model.robot import Box, Capsule  # noqa: E402
from mmstab.stability.static import base_polygon  # noqa: E402
from mmstab.terrain import Ramp  # noqa: E402
from mmstab.viz.drawing import (  # noqa: E402
    box_faces,
    capsule_faces,
    draw_ground,
    draw_poses_on_ground,
    draw_robot,
    robot_meshes,
    support_polygon_G,
)

BODIES = [
    "body",
    "track_left",
    "track_right",
    "flipper_left",
    "flipper_right",
    *(f"arm_link_{i}" for i in range(4)),
]


@pytest.fixture
def ax3d():
    fig = plt.figure()
    yield fig.add_subplot(projection="3d")
    plt.close(fig)


def test_draw_robot_draws_five_base_and_four_arm_bodies(ax3d, robot):
    artists = draw_robot(ax3d, robot, [0.3, 0.2, -0.4, 0.1])
    assert [a.get_gid() for a in artists] == BODIES
    assert all(isinstance(a, Poly3DCollection) for a in artists)
    assert len(ax3d.collections) == 9
    more = draw_robot(ax3d, robot, robot.stowed, support=True)
    assert len(more) == 10 and more[-1].get_gid() == "support_polygon"
    assert len(ax3d.collections) == 19
    ax3d.figure.canvas.draw()  # the layered collections project and sort without error
    # autoscaled to the robot (a ragged polygon list once made these limits garbage)
    for lo, hi in (ax3d.get_xlim(), ax3d.get_ylim(), ax3d.get_zlim()):
        assert -2.0 < lo < hi < 2.0


def test_box_faces_are_the_boxs_corners(robot):
    box = robot.base.flippers.box("left")
    faces = box_faces(box)
    assert len(faces) == 6
    np.testing.assert_allclose(
        np.unique(np.concatenate(faces), axis=0), np.unique(box.corners(), axis=0)
    )
    for f in faces:  # planar quads
        normal = np.cross(f[1] - f[0], f[2] - f[0])
        assert abs(normal @ (f[3] - f[0])) < 1e-12


def test_capsule_faces_lie_on_the_capsule_surface():
    cap = Capsule(radius=0.05, p0=np.array([0.1, -0.2, 0.3]), p1=np.array([-0.3, 0.1, 0.5]))
    pts = np.concatenate(capsule_faces(cap, sides=8))
    axis = cap.p1 - cap.p0
    s = np.clip((pts - cap.p0) @ axis / (axis @ axis), 0, 1)
    dist = np.linalg.norm(pts - (cap.p0 + s[:, None] * axis), axis=1)
    np.testing.assert_allclose(dist, cap.radius, atol=1e-12)
    assert len(capsule_faces(cap, sides=8)) == 8 * 5
    assert {f.shape for f in capsule_faces(cap, sides=8)} == {(4, 3)}  # not ragged


def test_robot_meshes_follow_the_link_frames_and_the_base_pose(robot, rng):
    q = rng.uniform(robot.joint_lower, robot.joint_upper)
    G_T_B = Ramp(0.2).G_T_B([0.5, -1.0, 0.7])
    meshes = robot_meshes(robot, q, G_T_B)
    assert list(meshes) == BODIES
    B_T_R = robot.kinematics.link_frames(q)
    for i, link in enumerate(robot.links):
        G_T_R = G_T_B @ B_T_R[i]
        pts_R = (np.concatenate(meshes[f"arm_link_{i}"]) - G_T_R[:3, 3]) @ G_T_R[:3, :3]
        if isinstance(link.geometry, Box):
            expected = np.unique(link.geometry.corners(), axis=0)
            np.testing.assert_allclose(np.unique(pts_R.round(12), axis=0), expected, atol=1e-12)
        else:  # every vertex at the radius from the segment
            g = link.geometry
            axis = g.p1 - g.p0
            s = np.clip((pts_R - g.p0) @ axis / (axis @ axis), 0, 1)
            d = np.linalg.norm(pts_R - (g.p0 + s[:, None] * axis), axis=1)
            np.testing.assert_allclose(d, g.radius, atol=1e-12)
    track = np.concatenate(meshes["track_left"])
    expected = robot.base.collision_boxes()["track_left"].corners() @ G_T_B[:3, :3].T + G_T_B[:3, 3]
    np.testing.assert_allclose(np.unique(track, axis=0), np.unique(expected, axis=0), atol=1e-12)


def test_support_polygon_lies_on_the_ramp(robot):
    ramp = Ramp(0.15)
    G_T_B = ramp.G_T_B([0.2, 0.3, 1.0])
    poly_G = support_polygon_G(robot, G_T_B)
    assert len(poly_G) == len(base_polygon(robot).vertices)
    # height above the slope plane: the small lift only
    normal_G = ramp.G_T_M()[:3, 2]
    np.testing.assert_allclose(poly_G @ normal_G, 2e-3, atol=1e-12)


def test_draw_ground_and_poses(ax3d, robot):
    ramp = Ramp(0.1)
    artists = draw_ground(ax3d, ramp, (-1.0, 1.0, -0.5, 0.5), grid=0.5)
    assert [a.get_gid() for a in artists] == ["ground", "ground_grid"]
    ax3d.figure.canvas.draw()
    assert len(artists[1].get_segments()) == 5 + 3  # projected grid lines, x then y
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 1.0], [-1.0, 0.5, 2.0]])
    drawn = draw_poses_on_ground(ax3d, robot, ramp, poses, np.zeros((3, 4)), labels=["a", "b", "c"])
    assert [len(d) for d in drawn] == [9, 9, 9]
    assert [t.get_text() for t in ax3d.texts] == ["a", "b", "c"]


def test_draw_ground_keeps_to_the_map(ax3d):
    """A patch reaching past a heightmap's edge is cut to it: no sample off the map."""
    from mmstab.terrain import Heightmap, HeightmapTerrain
    from mmstab.viz.drawing import clip_to_ground

    hm = Heightmap.build(np.zeros((21, 41)), 0.1, (-2.0, -1.0))  # x -2 .. 2, y -1 .. 1 m
    terrain = HeightmapTerrain(hm)
    asked = (-3.0, 0.5, 0.2, 4.0)
    assert clip_to_ground(terrain, asked) == (-2.0, 0.5, 0.2, 1.0)
    assert clip_to_ground(Ramp(0.1), asked) == asked  # a plane has no edge

    class Spy:  # the terrain, recording where drawing samples it
        bounds = terrain.bounds
        sampled: list[np.ndarray] = []

        def surface_G(self, x, y):
            self.sampled.append(np.stack(np.broadcast_arrays(x, y), axis=-1).reshape(-1, 2))
            return terrain.surface_G(x, y)

    spy = Spy()
    artists = draw_ground(ax3d, spy, asked, grid=0.5)
    assert [a.get_gid() for a in artists] == ["ground", "ground_grid"]
    xy = np.concatenate(spy.sampled)
    assert xy.min(axis=0) == pytest.approx([-2.0, 0.2]) and xy.max(axis=0) == pytest.approx(
        [0.5, 1.0]
    )
    assert draw_ground(ax3d, spy, (2.5, 3.0, 0.0, 1.0)) == []  # nothing of it on the map
