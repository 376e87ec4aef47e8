"""MuJoCo heightfield drops of the tracked base vs hand geometry."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

pytestmark = pytest.mark.mujoco
mujoco = pytest.importorskip("mujoco")

from mmstab.core.files import MmstabError  # noqa: E402
from mmstab.model.robot import rpy_matrix  # noqa: E402
from mmstab.physics.compare import compare, distribution  # noqa: E402
from mmstab.physics.heightfield import heightmap, hfield_mjcf  # noqa: E402
from mmstab.physics.mujoco_drop import DropModel, DropSettings, build_model, drop  # noqa: E402
from mmstab.physics.plane import plane_predictor  # noqa: E402

ORIGIN = np.array([-1.5, -1.3])
RES = 0.05


# ------------------------------------------------------------ local terrain generators (tests)
def grid(shape=(53, 61), res=RES, origin=ORIGIN):
    """G (x, y) of every cell centre, grid_map layout [iy, ix]."""
    iy, ix = np.mgrid[0 : shape[0], 0 : shape[1]]
    return origin[0] + ix * res, origin[1] + iy * res


def plane(a, b, c=0.2, **kw):
    x, y = grid(**kw)
    return c + a * x + b * y


def sinusoid(amplitude=0.1, wavelength=0.8, **kw):
    x, y = grid(**kw)
    return amplitude * np.sin(2 * np.pi * x / wavelength) * np.cos(np.pi * y / wavelength) + 0.3 * y


def kerb(height, x_edge, res=0.01, shape=(121, 251), origin=(-1.0, -0.6)):
    x, _ = grid(shape, res, np.asarray(origin))
    return np.where(x >= x_edge - 1e-9, height, 0.0)


def ray_height(model, data, x, y):
    geomid = np.zeros(1, np.int32)
    dist = mujoco.mj_ray(
        model, data, np.array([x, y, 50.0]), np.array([0, 0, -1.0]), None, 1, -1, geomid
    )
    return 50.0 - dist


def hfield_only(elevation, res, origin):
    field = hfield_mjcf(heightmap(elevation, res, origin))
    xml = f"<mujoco><asset>{field.asset}</asset><worldbody>{field.geom}</worldbody></mujoco>"
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


# ------------------------------------------------------------------------- hfield conventions
def test_hfield_tilted_plane_heights_at_known_points():
    a, b, c = 0.15, -0.4, 1.2  # a y slope of the other sign than x catches a row flip
    e = plane(a, b, c, shape=(9, 13), res=0.25, origin=np.array([0.7, -2.0]))
    model, data = hfield_only(e, 0.25, [0.7, -2.0])
    for x, y in [(0.71, -1.99), (3.69, -0.01), (1.33, -1.21), (2.9, -0.13), (0.81, -0.02)]:
        assert ray_height(model, data, x, y) == pytest.approx(c + a * x + b * y, abs=1e-5)


def test_hfield_samples_sit_at_cell_centres_row_is_y():
    e = sinusoid(shape=(11, 17), res=0.1)
    x, y = grid((11, 17), 0.1)
    model, data = hfield_only(e, 0.1, ORIGIN)
    for iy, ix in [(0, 0), (0, 16), (10, 0), (3, 7), (8, 12), (10, 16)]:
        assert ray_height(model, data, x[iy, ix], y[iy, ix]) == pytest.approx(e[iy, ix], abs=1e-5)


def test_flat_hfield_and_bad_maps():
    model, data = hfield_only(np.full((5, 6), 0.42), 0.2, [0.0, 0.0])
    assert ray_height(model, data, 0.5, 0.3) == pytest.approx(0.42, abs=1e-6)
    with pytest.raises(MmstabError, match="NaN"):
        heightmap(np.array([[0.0, np.nan], [0.0, 0.0]]), 0.1, [0, 0])
    with pytest.raises(MmstabError, match="resolution"):
        heightmap(np.zeros((3, 3)), 0.0, [0, 0])


# ---------------------------------------------------------------------------- the robot model
def test_mass_and_com_equal_mmstab(robot):
    for q in (None, np.array([1.0, 0.6, -0.4, 0.3])):
        model = mujoco.MjModel.from_xml_string(
            build_model(robot, plane(0, 0), RES, ORIGIN, arm_posture=q)
        )
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base")
        q_arm = robot.stowed if q is None else q
        assert model.body_mass[body] == pytest.approx(robot.total_mass, rel=1e-9)
        np.testing.assert_allclose(
            model.body_ipos[body], robot.overall_com(robot.arm_com(q_arm)), atol=1e-9
        )
        assert np.all(model.body_inertia[body] > 0)


def test_collision_geometry_is_tracks_wheels_flippers_chassis(robot):
    t, fl = robot.base.tracks, robot.base.flippers
    model = mujoco.MjModel.from_xml_string(
        build_model(robot, plane(0, 0), RES, ORIGIN, flipper_angle=0.25)
    )
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # body at the origin, identity: geom_x* are in B

    def geom(name):
        return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)

    for side, s in (("left", 1), ("right", -1)):
        g = geom(f"track_{side}")
        np.testing.assert_allclose(data.geom_xpos[g], [0, s * t.separation / 2, t.height / 2])
        np.testing.assert_allclose(model.geom_size[g], [t.length / 2, t.width / 2, t.height / 2])
        for end, sx in (("front", 1), ("rear", -1)):
            g = geom(f"wheel_{side}_{end}")
            np.testing.assert_allclose(
                data.geom_xpos[g], [sx * t.length / 2, s * t.separation / 2, t.height / 2]
            )
            np.testing.assert_allclose(model.geom_size[g][:2], [t.height / 2, t.width / 2])
            axis = data.geom_xmat[g].reshape(3, 3)[:, 2]
            assert abs(axis[1]) == pytest.approx(1.0)
        # the flipper at 0.25 rad: its hinge is mirrored, its box turned by -angle about y
        pivot = fl.pivot * [1, s, 1]
        direction = np.array([np.cos(0.25), 0, np.sin(0.25)])
        g = geom(f"flipper_{side}")
        np.testing.assert_allclose(data.geom_xpos[g], pivot + direction * fl.length / 2, atol=1e-12)
        np.testing.assert_allclose(
            data.geom_xmat[g].reshape(3, 3), rpy_matrix([0, -0.25, 0]), atol=1e-9
        )
    g = geom("chassis")
    np.testing.assert_allclose(data.geom_xpos[g], robot.base.body.center)
    np.testing.assert_allclose(model.geom_size[g], robot.base.body.size / 2)


# --------------------------------------------------------------------------------- the drops
def test_flat_plane_rests_level(robot):
    e = np.full((53, 61), 0.3)
    poses = np.array([[0, 0, 0], [0.3, -0.2, 1.1], [-0.4, 0.1, -2.5], [0.1, 0.4, np.pi / 2]])
    r = drop(dict(robot=robot, elevation=e, resolution=RES, origin=ORIGIN), poses)
    assert np.all(r.settled)
    np.testing.assert_allclose(np.degrees(r.roll), 0, atol=0.1)
    np.testing.assert_allclose(np.degrees(r.pitch), 0, atol=0.1)
    np.testing.assert_allclose(r.z, 0.3, atol=2e-3)
    assert np.all(r.penetration < 1e-3)
    np.testing.assert_allclose(r.slip, 0, atol=1e-3)


@pytest.mark.parametrize(
    "slope, azimuth, start",
    [(0.12, 0.0, "fit"), (0.25, 2.2, "fit"), (0.35, -1.0, "fit"), (0.15, 0.7, "level")],
)
def test_tilted_planes_match_hand_geometry(robot, slope, azimuth, start):
    a, b = np.tan(slope) * np.cos(azimuth), np.tan(slope) * np.sin(azimuth)
    e = plane(a, b)
    dm = DropModel(robot, e, RES, ORIGIN, settings=DropSettings(start=start))
    poses = np.array([[0.0, 0.0, 0.0], [0.2, -0.15, 1.3], [-0.25, 0.2, -2.4]])
    r = drop(dm, poses)
    assert np.all(r.settled)
    cmp = compare(plane_predictor(e, RES, ORIGIN), r)  # predicted where it came to rest
    assert cmp.roll_deg.max() < 0.3 and cmp.pitch_deg.max() < 0.3
    assert cmp.z_m.max() < 2e-3
    assert cmp.outliers == []
    assert np.all(r.penetration < 1e-3)
    if start == "fit":  # released parallel to the ground: no slip to speak of
        assert np.all(r.slip < 5e-3) and np.all(np.abs(r.yaw_drift) < np.radians(0.5))


def test_sign_conventions_by_hand(robot):
    s = 0.2
    up_x = plane(np.tan(s), 0.0)  # ground rising toward +x
    up_y = plane(0.0, np.tan(s))  # ground rising toward +y
    r = drop(dict(robot=robot, elevation=up_x, resolution=RES, origin=ORIGIN), [[0, 0, 0]])
    assert r.pitch[0] == pytest.approx(s, abs=np.radians(0.1))  # nose uphill: nose up
    assert r.roll[0] == pytest.approx(0, abs=np.radians(0.1))
    r = drop(dict(robot=robot, elevation=up_x, resolution=RES, origin=ORIGIN), [[0, 0, np.pi / 2]])
    assert r.roll[0] == pytest.approx(-s, abs=np.radians(0.1))  # facing +y: left side downhill
    assert r.pitch[0] == pytest.approx(0, abs=np.radians(0.1))
    r = drop(dict(robot=robot, elevation=up_y, resolution=RES, origin=ORIGIN), [[0, 0, 0]])
    assert r.roll[0] == pytest.approx(s, abs=np.radians(0.1))  # left side uphill: roll > 0
    assert r.z[0] == pytest.approx(0.2, abs=2e-3)  # B's origin on the plane at (0, 0)


def test_kerb_front_on_the_edge_pitch_by_hand(robot):
    h, x_edge = 0.08, 0.15
    t = robot.base.tracks
    half, R = t.length / 2, t.height / 2
    e = kerb(h, x_edge)
    r = drop(dict(robot=robot, elevation=e, resolution=0.01, origin=(-1.0, -0.6)), [[0, 0, 0]])
    assert r.settled[0]
    x_b = r.xy[0, 0]
    # rear wheel on the ground and the flat track bottom on the edge (x_edge, h):
    # z_B = half sin(th) + R (1 - cos(th)); the bottom line reaches h at x_edge
    theta = brentq(
        lambda th: half * np.sin(th) + R * (1 - np.cos(th)) + (x_edge - x_b) * np.tan(th) - h,
        0.0,
        0.5,
    )
    assert np.degrees(theta) > 3  # a real climb, not a flat pose
    assert r.pitch[0] == pytest.approx(theta, abs=np.radians(0.3))
    assert r.roll[0] == pytest.approx(0, abs=np.radians(0.1))
    assert r.z[0] == pytest.approx(half * np.sin(theta) + R * (1 - np.cos(theta)), abs=2e-3)
    assert set(r.touching[0]) >= {"track_left", "track_right", "wheel_left_rear"}


# ------------------------------------------------------------------------------- comparison
def test_distribution_and_outliers(robot):
    assert distribution(np.arange(101.0)) == {"median": 50.0, "p95": 95.0, "max": 100.0}
    e = plane(np.tan(0.2), 0.0)
    poses = np.array([[0.0, 0.0, 0.0], [0.1, 0.1, 1.0]])
    r = drop(dict(robot=robot, elevation=e, resolution=RES, origin=ORIGIN), poses)
    good = plane_predictor(e, RES, ORIGIN)

    def biased(p):  # 3 deg too much pitch on the second pose only
        roll, pitch, z = good(p)
        return roll, pitch + np.radians([0.0, 3.0]), z

    cmp = compare(biased, r)
    assert [o["index"] for o in cmp.outliers] == [1]
    assert cmp.outliers[0]["pitch_deg"] == pytest.approx(3.0, abs=0.3)
    assert cmp.stats["pitch_deg"]["max"] == pytest.approx(3.0, abs=0.3)
    assert cmp.stats["settled"] == 2
    with pytest.raises(MmstabError, match="not a plane"):
        plane_predictor(sinusoid(), RES, ORIGIN)


def test_rest_state_hook_tells_a_second_rest_from_a_wrong_prediction(robot):
    from mmstab.physics.compare import rest_state_check

    e = plane(np.tan(0.2), 0.0)
    dm = DropModel(robot, e, RES, ORIGIN)
    r = drop(dm, [[0.1, -0.1, 0.4]])
    good = plane_predictor(e, RES, ORIGIN)

    def tilted(p):  # 3 deg of extra roll: the robot cannot stay there on a plane
        roll, pitch, z = good(p)
        return roll + np.radians(3.0), pitch, z

    errors = {"roll_deg": 3.0, "pitch_deg": 0.0, "z_m": 0.0}
    assert rest_state_check(dm, good)(0, r, errors).startswith("two rest states")
    assert rest_state_check(dm, tilted)(0, r, errors).startswith("MuJoCo does not stay")
