"""The animation building block: a short synthetic run rendered to a GIF."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image, ImageChops

from mmstab.stability.static import robot_force_angle
from mmstab.terrain import Ramp
from mmstab.viz.animation import frame_indices, render_animation
from mmstab.viz.drawing import mesh_points, robot_meshes


def _run(robot, n: int):
    ramp = Ramp(0.1)
    s = np.linspace(0.0, 0.5, n)
    poses = np.stack(
        [1.5 * np.cos(np.pi * s - np.pi / 2), 1.5 + 1.5 * np.sin(np.pi * s - np.pi / 2), np.pi * s],
        axis=1,
    )
    q = np.zeros((n, 4))
    q[:, 0] = np.linspace(0.5, 2.5, n)
    q[:, 1] = np.linspace(0.0, 0.8, n)
    mu = robot_force_angle(robot, ramp.gravity_body(poses), robot.arm_com(q)).mu
    return ramp, 2.0 * s, poses, q, mu


def test_render_animation_writes_a_gif_of_every_frame(tmp_path, robot):
    ramp, t, poses, q, mu = _run(robot, 5)
    out = tmp_path / "anim" / "run.gif"
    info = render_animation(robot, ramp, t, poses, q, mu, out, size=(320, 200), progress=False)
    assert info.path == out and info.frames == 5
    assert sorted(p.name for p in out.parent.iterdir()) == ["run.gif"]  # no temp file left
    with Image.open(out) as im:
        assert im.format == "GIF" and im.size == (320, 200)
        assert im.n_frames == 5 >= 3
        im.seek(0)
        first = im.convert("RGB")
        im.seek(im.n_frames - 1)
        last = im.convert("RGB")
    assert ImageChops.difference(first, last).getbbox() is not None  # the robot moved


def test_long_runs_are_thinned(tmp_path, robot):
    ramp, t, poses, q, mu = _run(robot, 10)
    info = render_animation(
        robot,
        ramp,
        t,
        poses,
        q,
        mu,
        tmp_path / "a.gif",
        size=(240, 160),
        max_frames=4,
        progress=False,
    )
    assert list(info.indices) == [0, 3, 6, 9]
    with Image.open(info.path) as im:
        assert im.n_frames == 4


def test_frame_indices():
    assert list(frame_indices(3, 10)) == [0, 1, 2]
    assert list(frame_indices(101, 5)) == [0, 25, 50, 75, 100]
    assert list(frame_indices(7, None)) == list(range(7))


def test_inconsistent_inputs_are_refused(tmp_path, robot):
    ramp, t, poses, q, mu = _run(robot, 4)
    with pytest.raises(ValueError, match="q_arm"):
        render_animation(robot, ramp, t, poses, q[:3], mu, tmp_path / "x.gif", progress=False)
    with pytest.raises(ValueError, match="mu"):
        render_animation(robot, ramp, t, poses, q, mu[:2], tmp_path / "x.gif", progress=False)
    assert not list(tmp_path.iterdir())


def test_a_run_at_the_map_edge_is_drawn_on_the_map_only(tmp_path, robot):
    """The arm reaches past a heightmap's edge, the contacts do not: the GIF is written.

    The drawn ground patch is cut to the map (``drawing.clip_to_ground``); a pose whose
    contacts leave the map is still refused by the resting pose itself.
    """
    from mmstab.terrain import Heightmap, HeightmapTerrain, OffMapError

    # a 3 m x 3 m field with a 10 cm step, x and y in -1.5 .. 1.5 m
    x = np.linspace(-1.5, 1.5, 61)
    hm = Heightmap.build(np.tile(np.where(x > 0.5, 0.1, 0.0), (61, 1)), 0.05, (-1.5, -1.5))
    terrain = HeightmapTerrain(hm).with_robot(robot)
    poses = np.array([[-1.0, 0.0, 0.0], [-0.95, 0.2, 0.3], [-0.9, 0.6, 0.6]])
    q = np.zeros((3, 4))
    q[:, 0] = np.pi  # the arm over the rear edge
    contacts = np.vstack([terrain.support(robot, p).contacts_G for p in poses])
    assert contacts[:, 0].min() > -1.5  # every contact on the map ...
    drawn = [robot_meshes(robot, q[k], terrain.G_T_B(p)) for k, p in enumerate(poses)]
    reach = np.concatenate([mesh_points(m) for m in drawn])
    assert reach[:, 0].min() < -1.5 - 0.3  # ... the drawn robot well past its edge
    mu = robot_force_angle(robot, terrain.gravity_body(poses), robot.arm_com(q)).mu
    info = render_animation(
        robot,
        terrain,
        [0.0, 0.5, 1.0],
        poses,
        q,
        mu,
        tmp_path / "edge.gif",
        size=(240, 160),
        progress=False,
    )
    with Image.open(info.path) as im:
        assert im.n_frames == 3
    with pytest.raises(OffMapError, match="off the map"):  # contacts off the map: refused
        terrain.G_T_B([-1.2, 0.0, 0.0])
