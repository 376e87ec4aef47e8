"""The arm's height above the ground from points on its surface (mmstab.runs.arm_ground).

Checked on a plane (the analytic clearance of the arm's shapes above the support plane),
against FCL (the arm's shapes against the map's triangles, a second library), batched against
one pose at a time, and through the plan's verdicts and ``mmstab plan``'s exit status.
"""

from __future__ import annotations

import argparse

import fcl
import numpy as np
from conftest import ditch_ground, random_postures

from mmstab.cli.status import EXIT_ARM_COLLISION
from mmstab.cli.verdicts import plan_contact_status
from mmstab.model.collision import fcl_geometry, geometry_pose
from mmstab.model.plane_clearance import arm_ground_clearance
from mmstab.runs.along import limit_verdicts
from mmstab.runs.arm_ground import arm_heights
from mmstab.runs.plan_verdicts import exit_status
from mmstab.terrain import HeightmapTerrain
from mmstab.terrain.heightmap import Heightmap

#: The capsules' sampled directions find their lowest point within this [m] (arm_pieces).
SAMPLED = 0.004


def plane_pose(a: float, b: float, x: float, y: float, yaw: float) -> np.ndarray:
    """A body pose G_T_B whose z_B = 0 plane is the ground z = a x + b y, origin on it."""
    n = np.array([-a, -b, 1.0]) / np.sqrt(1.0 + a * a + b * b)
    heading = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    ex = heading - (heading @ n) * n
    ex /= np.linalg.norm(ex)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([ex, np.cross(n, ex), n])
    T[:3, 3] = [x, y, a * x + b * y]
    return T


def plane_map(a: float, b: float) -> HeightmapTerrain:
    res = 0.05
    x = np.arange(-3, 3 + 1e-9, res)
    X, Y = np.meshgrid(x, x)
    return HeightmapTerrain(Heightmap.build(a * X + b * Y, res, [x[0], x[0]], "plane"))


def test_on_a_plane_the_height_is_the_clearance_above_the_support_plane(robot, rng):
    # a point z_B above the plane is z_B / cos(tilt) above it vertically; the surface's
    # points hold the shapes' lowest points (a box's corners) or come within SAMPLED of them
    for _ in range(4):
        a, b = rng.uniform(-0.4, 0.4, 2)
        terrain = plane_map(a, b)
        q = random_postures(robot, rng, 40)
        T = np.stack([plane_pose(a, b, *rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi))
                      for _ in q])  # fmt: skip
        h = arm_heights(robot, terrain, T, q)
        want = arm_ground_clearance(robot, q) / T[:, 2, 2]
        assert np.all(h >= want - 1e-9)
        assert np.all(h <= want + SAMPLED / T[:, 2, 2])
        assert (h < 0).any() and (h > 0).any()  # some arms reach below the ground plane


def terrain_mesh(hm: Heightmap, box: tuple[float, float, float, float]) -> fcl.CollisionObject:
    """The map's cells within ``box`` (x0, x1, y0, y1) [m] as two triangles each (FCL)."""
    ny, nx = hm.shape
    i = np.flatnonzero((hm.x >= box[0]) & (hm.x <= box[1]))
    j = np.flatnonzero((hm.y >= box[2]) & (hm.y <= box[3]))
    X, Y = np.meshgrid(hm.x[i], hm.y[j])
    Z = np.asarray(hm.elevation)[np.ix_(j, i)]
    vertices = np.c_[X.ravel(), Y.ravel(), Z.ravel()]
    w = len(i)
    k = (np.arange(len(j) - 1)[:, None] * w + np.arange(w - 1)).ravel()
    triangles = np.r_[np.c_[k, k + 1, k + w + 1], np.c_[k, k + w + 1, k + w]]
    model = fcl.BVHModel()
    model.beginModel(len(vertices), len(triangles))
    model.addSubModel(vertices, triangles.astype(np.int32))
    model.endModel()
    return fcl.CollisionObject(model, fcl.Transform())


def fcl_touches(robot, mesh: fcl.CollisionObject, G_T_B: np.ndarray, q: np.ndarray) -> bool:
    frames = robot.kinematics.link_frames(np.atleast_2d(q))[0]
    for i, link in enumerate(robot.links):
        T = G_T_B @ frames[i] @ geometry_pose(link.geometry)
        shape = fcl.CollisionObject(fcl_geometry(link.geometry), fcl.Transform(T[:3, :3], T[:3, 3]))
        if fcl.collide(shape, mesh, fcl.CollisionRequest(), fcl.CollisionResult()):
            return True
    return False


def test_in_the_ground_where_fcl_finds_the_arm_on_the_map_of_a_ditch(robot, rng):
    # seeded maps with a ditch and bumps; the body rested there, the arm anywhere in its limits
    # (many reach the ground): in the ground by more than 1 cm <=> FCL finds a contact with
    # the map's triangles (1 cm: the sampling and the triangles against the bilinear cells)
    agree = 0
    for _ in range(3):
        hm = ditch_ground(rng, slope_deg=float(rng.uniform(0, 15)), bump_m=0.08)
        terrain = HeightmapTerrain(hm).with_robot(robot)
        poses = np.c_[rng.uniform(-0.8, 0.8, 30), rng.uniform(-2, 2, 30), rng.uniform(-3, 3, 30)]
        q = random_postures(robot, rng, 30)
        T = terrain.rest(poses, strict=False).G_T_B
        h = arm_heights(robot, terrain, T, q)
        for k in np.flatnonzero(np.isfinite(h) & (np.abs(h) > 0.01)):
            box = (poses[k, 0] - 1.2, poses[k, 0] + 1.2, poses[k, 1] - 1.2, poses[k, 1] + 1.2)
            assert fcl_touches(robot, terrain_mesh(hm, box), T[k], q[k]) == (h[k] < 0), k
            agree += 1
    assert agree > 50


def test_the_c_kernel_is_its_numpy_twin(robot, rng):
    # seeded ditch maps with unknown cells, rested poses (one off the map), random postures
    for _ in range(2):
        hm = ditch_ground(rng, slope_deg=float(rng.uniform(0, 15)), bump_m=0.08)
        z = np.array(hm.elevation, dtype=float)
        z[rng.integers(0, z.shape[0], 40), rng.integers(0, z.shape[1], 40)] = np.nan
        hm = Heightmap.build(z, hm.resolution, hm.origin, "holes")
        terrain = HeightmapTerrain(hm).with_robot(robot)
        xy = rng.uniform(-4.8, 4.8, (60, 2))
        poses = np.c_[xy, rng.uniform(-3, 3, 60)]
        poses[0] = [9.0, 0.0, 0.0]
        T = terrain.rest(poses, strict=False).G_T_B
        q = random_postures(robot, rng, 60)
        c = arm_heights(robot, terrain, T, q, backend="c")
        twin = arm_heights(robot, terrain, T, q, backend="numpy")
        np.testing.assert_allclose(c, twin, rtol=0, atol=1e-12)  # NaN where NaN
        assert np.isnan(c).sum() > 1 and np.isfinite(c).sum() > 30


def test_batched_is_each_pose_alone(robot, rng):
    hm = ditch_ground(rng)
    terrain = HeightmapTerrain(hm).with_robot(robot)
    poses = np.c_[rng.uniform(-1, 1, 12), rng.uniform(-2, 2, 12), rng.uniform(-3, 3, 12)]
    poses[3] = [9.0, 0.0, 0.0]  # off the map: unknown
    T = terrain.rest(poses, strict=False).G_T_B
    q = random_postures(robot, rng, 12)
    h = arm_heights(robot, terrain, T, q)
    alone = [arm_heights(robot, terrain, T[k : k + 1], q[k : k + 1])[0] for k in range(12)]
    np.testing.assert_allclose(h, alone, rtol=0, atol=1e-12)
    assert np.isnan(h[3]) and np.isfinite(np.delete(h, 3)).all()


def test_off_a_heightmap_every_height_is_unknown(robot, problem, rng):
    q = random_postures(robot, rng, 3)
    G_T_B = np.broadcast_to(np.eye(4), (3, 4, 4))
    assert np.isnan(arm_heights(robot, problem.terrain, G_T_B, q)).all()


def plan_summary(stretches: list[dict]) -> dict:
    """A route plan's summary that holds on every limit but the arm in the ground."""
    poses = [{"collision_free": True}, {"collision_free": True}]
    return {
        "s": [0.0, 2.0],
        "poses": poses,
        "stability": {"stable": True, "unstable_poses": [], "stretches": [], "mu_min": 300.0},
        "slip": {"slides": False},
        "risk": {"slides": []},
        "climb": {"stalls": False, "steps": []},
        "high_centred": {"high_centred": False, "stretches": []},
        "along_path": {"arm_in_ground": {"contact": bool(stretches), "stretches": stretches}},
    }


def test_the_arm_in_the_ground_is_an_arm_contact_with_exit_status_5(capsys):
    stretch = {"start_s": 0.8, "end_s": 1.05, "at_s": 0.95, "by": 0.113}
    s = plan_summary([stretch])
    s["verdicts"] = verdicts = limit_verdicts(s)
    want = {"verdict": "collides", "unsafe": True, "where": [[0.8, 1.05]]}
    assert verdicts["arm_contact"] == want
    assert exit_status(verdicts) == EXIT_ARM_COLLISION
    args = argparse.Namespace(allow_collision=False)
    assert plan_contact_status(s, args) == EXIT_ARM_COLLISION
    err = capsys.readouterr().err
    assert "in the ground at rest at s = 0.80-1.05 m (up to 11.3 cm in)" in err
    assert "touches the robot" not in err
    assert plan_contact_status(s, argparse.Namespace(allow_collision=True)) is None
    clear = plan_summary([])
    assert exit_status(limit_verdicts(clear)) == 0


def test_a_tracked_arm_in_the_ground_exits_5_and_says_when(capsys):
    from mmstab.cli.verdicts import arm_collision_status

    safe = {"verdict": {"safe": True}}
    ground = {"contact": True, "intervals_s": [{"start_s": 4.1, "end_s": 4.35, "by": 0.062}]}
    s = {"arm_self_collision": safe, "arm_in_ground": ground}
    assert arm_collision_status(s, argparse.Namespace(allow_collision=False)) == EXIT_ARM_COLLISION
    err = capsys.readouterr().err
    assert "in the ground at the tracked rest at t = 4.10-4.35 s (up to 6.2 cm in)" in err
    clear = {"arm_self_collision": safe, "arm_in_ground": {**ground, "contact": False}}
    assert arm_collision_status(clear, argparse.Namespace(allow_collision=False)) is None
    assert arm_collision_status({"arm_self_collision": safe}, argparse.Namespace()) is None
