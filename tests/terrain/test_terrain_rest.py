"""Resting pose on heightmaps: the ramp reproduced, invariances, a kerb by hand, flags."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from mmstab.stability.stance import stance
from mmstab.stability.static import robot_force_angle
from mmstab.terrain import Ramp, roll_pitch
from mmstab.terrain.contacts import ARC_STEP, CHASSIS, FLIPPER, TRACK, contact_candidates
from mmstab.terrain.generators import Grid, generate, kerb, plane
from mmstab.terrain.heightmap import OffMapError
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

ROUGH = {
    "kind": "rough",
    "seed": 2,
    "size": [4.0, 4.0],
    "resolution": 0.05,
    "amplitude": 0.03,
    "correlation_length": 0.3,
    "hill_height": 0.3,
    "hill_radius": 1.0,
    "slope": 0.1,
    "azimuth": 0.4,
}


@pytest.fixture(scope="module")
def rough_terrain(robot):
    return HeightmapTerrain(generate(ROUGH)).with_robot(robot)


def test_candidates_follow_the_stated_geometry(robot):
    c = contact_candidates(robot.base)
    t = robot.base.tracks
    track = c.points[c.part == TRACK]
    r = t.height / 2
    # rows across each belt, edges included, 5 cm apart (the 10 cm belt: edges and middle)
    assert set(np.round(np.unique(track[:, 1]), 9)) == {
        round(s * t.separation / 2 + e * t.width / 2, 9) for s in (-1, 1) for e in (-1, 0, 1)
    }
    flat = track[track[:, 2] == 0]
    assert flat[:, 0].min() == -t.length / 2 and flat[:, 0].max() == t.length / 2
    arc = track[np.abs(track[:, 0]) > t.length / 2]
    centre = np.c_[np.sign(arc[:, 0]) * t.length / 2, np.full(len(arc), r)]
    np.testing.assert_allclose(np.linalg.norm(arc[:, [0, 2]] - centre, axis=1), r)
    assert arc[:, 2].max() == pytest.approx(r)  # the lower half of the end arcs only
    chassis = c.points[c.part == CHASSIS]
    body = robot.base.body
    assert np.allclose(chassis[:, 2], body.center[2] - body.size[2] / 2)
    # the whole underside: every point of the face within 5 cm / sqrt(2) of a sample
    u = np.random.default_rng(0).uniform(-0.5, 0.5, (2000, 2)) * body.size[:2] + body.center[:2]
    gap = np.min(np.linalg.norm(u[:, None] - chassis[None, :, :2], axis=2), axis=1)
    assert gap.max() <= 0.05 / np.sqrt(2) + 1e-12
    flipper = c.points[c.part == FLIPPER]
    box = robot.base.flippers.box("left")
    assert flipper[:, 2].min() == pytest.approx(box.corners()[:, 2].min())


@pytest.mark.parametrize(
    ("slope", "azimuth"), [(0.0, 0.0), (0.1, np.pi / 2), (0.35, 0.3), (0.6, -2.0)]
)
def test_plane_reproduces_the_ramp(robot, slope, azimuth):
    """A plane rising toward ``azimuth`` is the ramp (uphill +y_S) turned by azimuth - 90 deg."""
    terrain = HeightmapTerrain(plane(Grid.of_size((6, 6), 0.1), slope, azimuth)).with_robot(robot)
    ramp = Ramp(slope)
    turn = np.eye(4)
    b = azimuth - np.pi / 2
    turn[:2, :2] = [[np.cos(b), -np.sin(b)], [np.sin(b), np.cos(b)]]
    rng = np.random.default_rng(0)
    poses_S = np.c_[rng.uniform(-1, 1, (5, 2)), rng.uniform(-np.pi, np.pi, 5)]
    T_ramp = np.stack([turn @ ramp.G_T_B(p) for p in poses_S])
    poses_G = np.c_[T_ramp[:, 0, 3], T_ramp[:, 1, 3], np.arctan2(T_ramp[:, 1, 0], T_ramp[:, 0, 0])]
    rest = terrain.rest(poses_G)
    assert rest.converged.all() and not rest.high_centred.any()
    np.testing.assert_allclose(rest.G_T_B, T_ramp, atol=1e-9)
    mu_ramp = robot_force_angle(robot, ramp.gravity_body(poses_S), robot.arm_com(robot.stowed)).mu
    for i, p in enumerate(poses_G):
        roll, pitch = roll_pitch(ramp, poses_S[i])
        assert rest.roll[i] == pytest.approx(roll, abs=1e-6)
        assert rest.pitch[i] == pytest.approx(pitch, abs=1e-6)
        st = stance(terrain, robot, p)
        assert st.mu == pytest.approx(mu_ramp[i], abs=1e-6)
        assert st.mu == pytest.approx(stance(ramp, robot, poses_S[i]).mu, abs=1e-6)


def test_moving_the_map_with_the_pose_moves_the_rest(robot, rough_terrain):
    rng = np.random.default_rng(1)
    poses = np.c_[rng.uniform(-0.9, 0.9, (12, 2)), rng.uniform(-np.pi, np.pi, 12)]
    a = rough_terrain.rest(poses)
    shift = np.array([0.731, -1.29])
    moved = HeightmapTerrain(rough_terrain.heightmap.translated(shift, dz=0.4)).with_robot(robot)
    b = moved.rest(poses + [*shift, 0.0])
    np.testing.assert_allclose(b.roll, a.roll, atol=1e-9)
    np.testing.assert_allclose(b.pitch, a.pitch, atol=1e-9)
    np.testing.assert_allclose(b.z, a.z + 0.4, atol=1e-9)
    # a quarter turn of the map with the pose: the grid maps onto itself, so the rest does
    # too (the issue asks <= 0.5 deg for interpolation; here it is exact to rounding)
    turned = HeightmapTerrain(rough_terrain.heightmap.rotated90()).with_robot(robot)
    c = turned.rest(np.c_[-poses[:, 1], poses[:, 0], poses[:, 2] + np.pi / 2])
    np.testing.assert_allclose(c.roll, a.roll, atol=1e-7)
    np.testing.assert_allclose(c.pitch, a.pitch, atol=1e-7)
    np.testing.assert_allclose(c.z, a.z, atol=1e-9)
    assert np.degrees(np.abs(c.roll - a.roll).max()) <= 0.5


def test_batched_equals_one_by_one(rough_terrain):
    rng = np.random.default_rng(2)
    poses = np.c_[rng.uniform(-0.9, 0.9, (9, 2)), rng.uniform(-np.pi, np.pi, 9)]
    batch = rough_terrain.rest(poses)
    for i, p in enumerate(poses):
        one = rough_terrain.rest(p)
        np.testing.assert_allclose(one.G_T_B[0], batch.G_T_B[i], atol=1e-12)
        assert one.flags(0) == batch.flags(i)
        np.testing.assert_array_equal(one.touching[0], batch.touching[i])
    # resting: the touching contacts carry the CoM (mu > 0 with them), none penetrates
    assert (batch.gap >= -1e-9).all() and (batch.touching.sum(axis=1) >= 3).all()


def test_a_large_batch_is_kept_and_answers_as_a_fresh_solve(robot, rough_terrain):
    """A run asks the rests of the same samples several times: the terrain keeps the last
    batches (read-only), keyed by the poses, the load and ``strict``."""
    from mmstab.terrain.heightmap_terrain import _KEEP_BATCHES, _KEEP_ROWS

    rng = np.random.default_rng(5)
    poses = np.c_[rng.uniform(-0.9, 0.9, (_KEEP_ROWS, 2)), rng.uniform(-np.pi, np.pi, _KEEP_ROWS)]
    terrain = HeightmapTerrain(rough_terrain.heightmap).with_robot(robot)
    first = terrain.rest(poses)
    assert terrain.rest(poses.copy()) is first  # equal poses, not the same array
    assert not first.G_T_B.flags.writeable and not first.bearing.flags.writeable
    fresh = HeightmapTerrain(rough_terrain.heightmap).with_robot(robot).rest(poses)
    for a, b in zip(first, fresh, strict=True):
        np.testing.assert_array_equal(a, b)
    # another load, strictness or pose set is another batch, solved for itself
    com = terrain.com_body + [0.05, 0.0, 0.0]
    loaded = terrain.rest(poses, com_body=com)
    assert loaded is not first and not np.allclose(loaded.pitch, first.pitch)
    assert terrain.rest(poses, strict=False) is not first
    moved = poses + [0.001, 0.0, 0.0]
    assert terrain.rest(moved) is not terrain.rest(poses)  # the oldest went: only the last kept
    assert len(terrain._kept_rests) == _KEEP_BATCHES
    # small batches are solved each time (cheap, and a loop's buffers may be reused)
    assert terrain.rest(poses[:10]) is not terrain.rest(poses[:10])


def test_kerb_pitch_by_hand(robot):
    """Track bottom on the kerb's edge, rear idler on the ground below: solve by hand.

    With the bottom point at s from the body origin resting on the edge (x_k, H) and the
    rear arc (radius r, centre L/2 behind the origin) touching z = 0, the pitch solves
    r (1 - cos p) + (L/2 + s) sin p = H, and the body origin lies at x_k - s cos p.
    """
    H, x_k, s = 0.10, 0.5, 0.25
    t = robot.base.tracks
    L, r = t.length, t.height / 2
    pitch = brentq(lambda p: r * (1 - np.cos(p)) + (L / 2 + s) * np.sin(p) - H, 0.0, 1.0)
    terrain = HeightmapTerrain(kerb(Grid.of_size((3, 3), 0.02), H, x_k, 0.0)).with_robot(robot)
    rest = terrain.rest([x_k - s * np.cos(pitch), 0.0, 0.0])
    # the rear arc is sampled every ARC_STEP: its lowest sample sits up to r(1 - cos(step/2))
    # above the true lowest point, tilting the body by up to that over the lever L/2 + s
    sag = r * (1 - np.cos(ARC_STEP / 2)) / (L / 2 + s)
    assert rest.pitch[0] == pytest.approx(pitch, abs=1.01 * sag)
    assert rest.roll[0] == pytest.approx(0.0, abs=1e-12)
    assert rest.flags(0) == ()
    contacts = rest.contacts_G(terrain.candidates.points, 0)
    # the edge: the three rows across both tracks (just below H: the face is 2 cm wide
    # under bilinear)
    assert np.isclose(contacts[:, 2], H, atol=1e-4).sum() == 6
    body = (contacts - rest.G_T_B[0, :3, 3]) @ rest.G_T_B[0, :3, :3]
    assert ((body[:, 0] < -L / 2) & (np.abs(contacts[:, 2]) < 1e-9)).sum() == 6  # rear arcs


def test_flags_high_centred_and_tipping_over(robot):
    g = Grid.of_size((3, 3), 0.02)
    _, y = g.xy()
    ridge = HeightmapTerrain(g.heightmap(np.where(np.abs(y) < 0.1, 0.12, 0.0), "ridge"))
    r = ridge.with_robot(robot).rest([0.0, 0.0, 0.0])
    assert "high_centred" in r.flags(0)
    # a side slope steeper than the CoM allows: the robot rolls over (mu < 0 on the plane)
    steep = HeightmapTerrain(plane(Grid.of_size((4, 4), 0.1), 1.1, np.pi / 2)).with_robot(robot)
    assert "tips_over" in steep.rest([0.0, 0.0, 0.0]).flags(0)
    assert stance(Ramp(1.1), robot, [0.0, 0.0, 0.0]).mu < 0
    fine = HeightmapTerrain(plane(Grid.of_size((4, 4), 0.1), 1.0, np.pi / 2)).with_robot(robot)
    assert fine.rest([0.0, 0.0, 0.0]).flags(0) == ()
    assert stance(Ramp(1.0), robot, [0.0, 0.0, 0.0]).mu > 0


def test_off_map_pose_is_a_clear_error(rough_terrain):
    with pytest.raises(OffMapError, match="off the map"):
        rough_terrain.rest([1.9, 0.0, 0.0])
    r = rough_terrain.rest([[1.9, 0.0, 0.0], [0.0, 0.0, 0.0]], strict=False)
    assert np.isnan(r.z[0]) and np.isfinite(r.z[1])


def test_terrain_interface_on_a_heightmap(robot, rough_terrain):
    import casadi as ca

    from mmstab.terrain import Terrain, from_section

    assert isinstance(rough_terrain, Terrain) and rough_terrain.kind == "heightmap"
    ramp = from_section("problems/ramp.yaml", {"slope": 0.1})
    assert isinstance(ramp, Ramp) and ramp.slope == 0.1
    np.testing.assert_array_equal(rough_terrain.G_T_M(), np.eye(4))

    poses = np.array([[0.1, -0.2, 0.3], [-0.4, 0.5, 2.0]])
    T = rough_terrain.G_T_B(poses)
    g = rough_terrain.gravity_body(poses)
    np.testing.assert_allclose(g, np.einsum("nji,j->ni", T[:, :3, :3], [0, 0, -9.81]))
    p = rough_terrain.place(poses, [0.2, 0.1, 0.3])
    np.testing.assert_allclose(p, T[:, :3, :3] @ [0.2, 0.1, 0.3] + T[:, :3, 3])
    sup = rough_terrain.support(robot, poses[0])
    np.testing.assert_allclose(sup.G_T_B, T[0])
    assert len(sup.polygon_G) >= 3
    # place_sx: exact at its reference pose (the resting plane there)
    local = rough_terrain.at(poses[0])
    pose = ca.SX.sym("pose", 3)
    f = ca.Function("f", [pose], [local.place_sx(pose, ca.DM([0.2, 0.1, 0.3]))])
    np.testing.assert_allclose(np.asarray(f(poses[0])).ravel(), p[0], atol=1e-9)


def test_lowered_flippers_lift_the_nose(robot, capsys):
    """Flippers turned 0.4 rad below straight ahead reach under the tracks: on flat ground
    the robot rests on the flipper edges and the rear track ends, nose up."""
    from mmstab.cli import main
    from mmstab.terrain.contacts import FLIPPER

    flat = HeightmapTerrain(plane(Grid.of_size((3, 3), 0.05), 0.0, 0.0))
    t = flat.with_robot(robot, flipper_angle=-0.4)
    r = t.rest([0.0, 0.0, 0.0])
    touching = t.candidates.part[r.touching[0]]
    assert (touching == FLIPPER).sum() >= 2 and (touching == TRACK).sum() >= 2
    assert r.roll[0] == pytest.approx(0.0, abs=1e-9)
    # by hand: the flipper's lowest edge on z = 0 and the rear arc (centre (-L/2, 0, r))
    # tangent to it: z0 + sin(p) x + cos(p) z = 0 at the edge, = r at the arc's centre
    fl = t.candidates.points[t.candidates.part == FLIPPER]
    tip = fl[np.argmin(fl[:, 2])]
    L, r_t = robot.base.tracks.length, robot.base.tracks.height / 2
    pitch = brentq(
        lambda q: np.sin(q) * (tip[0] + L / 2) + np.cos(q) * (tip[2] - r_t) + r_t, 0.0, 0.5
    )
    sag = r_t * (1 - np.cos(ARC_STEP / 2)) / (tip[0] + L / 2)  # arc sampled every ARC_STEP
    assert r.pitch[0] == pytest.approx(pitch, abs=1.01 * sag)
    # on the ramp the same flippers would dig into the plane: a clear error
    assert main(["rest", "problems/ramp.yaml", "--pose", "0", "0", "0", "--flipper", "-0.4"]) == 2
    assert "into the ramp" in capsys.readouterr().err


@pytest.mark.parametrize("kind", ["rough", "kerb"])
def test_fast_path_agrees_with_the_reference_path(robot, kind):
    """Each pose's highest candidates checked against all (the default) vs all candidates in
    every round (``active_candidates=0``), batched and one by one, on random poses."""
    import dataclasses

    section = (
        ROUGH
        if kind == "rough"
        else {
            "kind": "kerb",
            "seed": 0,
            "size": [3.0, 3.0],
            "resolution": 0.02,
            "height": 0.1,
            "distance": 0.0,
            "azimuth": 0.3,
        }
    )
    fast = HeightmapTerrain(generate(section)).with_robot(robot)
    assert 0 < fast.settings.active_candidates < len(fast.candidates.points)
    ref = dataclasses.replace(fast, settings=fast.settings._replace(active_candidates=0))
    rng = np.random.default_rng(7)
    n = 300
    poses = np.c_[rng.uniform(-0.7, 0.7, (n, 2)), rng.uniform(-np.pi, np.pi, n)]
    a, b = ref.rest(poses), fast.rest(poses)
    assert a.converged.mean() > 0.99
    np.testing.assert_array_equal(a.converged, b.converged)
    np.testing.assert_allclose(b.roll, a.roll, atol=1e-9)
    np.testing.assert_allclose(b.pitch, a.pitch, atol=1e-9)
    np.testing.assert_allclose(b.z, a.z, atol=1e-9)
    np.testing.assert_array_equal(b.touching, a.touching)
    for name in ("high_centred", "line_contact", "tips_over"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name))
    # batched vs one by one on the fast path
    for i in rng.choice(n, 5, replace=False):
        one = fast.rest(poses[i])
        np.testing.assert_allclose(one.G_T_B[0], b.G_T_B[i], atol=1e-12)
        assert one.flags(0) == b.flags(i)
