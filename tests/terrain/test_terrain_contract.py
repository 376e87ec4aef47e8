"""The contract every :class:`mmstab.terrain.Terrain` implementation keeps.

Parametrised over the implementations: to check a new ground, add a factory to
``TERRAINS`` (a name and a zero-argument callable returning the terrain). Every test draws
its poses and points from a seeded generator.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from mmstab.terrain import (
    GRAVITY_G,
    Ramp,
    Terrain,
    local_transforms,
    place_local,
    placement_function,
)


def rough_heightmap():
    """Rough ground (a generated 6 m map) bound to the default robot."""
    from conftest import ROBOT_YAML

    from mmstab.model.robot import load_robot
    from mmstab.terrain import HeightmapTerrain
    from mmstab.terrain.generators import generate

    settings = {
        "kind": "rough",
        "seed": 4,
        "size": [6.0, 6.0],
        "resolution": 0.05,
        "amplitude": 0.03,
        "correlation_length": 0.4,
        "hill_height": 0.5,
        "hill_radius": 1.0,
        "slope": 0.2,
        "azimuth": 0.5,
    }
    return HeightmapTerrain(generate(settings)).with_robot(load_robot(ROBOT_YAML))


#: (id, factory) of every terrain the contract runs against.
TERRAINS = [
    ("ramp_flat", lambda: Ramp(0.0)),
    ("ramp_0.1", lambda: Ramp(0.1)),
    ("ramp_0.35", lambda: Ramp(0.35)),
    ("ramp_1.0", lambda: Ramp(1.0)),
    ("heightmap_rough", rough_heightmap),
]
#: How close a contact of ``support`` lies to the ground surface [m], by kind: exact on a
#: plane; within the resting pose's contact tolerance on a heightmap.
CONTACT_TOL = {"ramp": 1e-9, "heightmap": 5e-4}


@pytest.fixture(params=[f for _, f in TERRAINS], ids=[n for n, _ in TERRAINS])
def terrain(request) -> Terrain:
    return request.param()


def poses(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.column_stack([rng.uniform(-2, 2, (n, 2)), rng.uniform(-np.pi, np.pi, n)])


def assert_rigid(T: np.ndarray) -> None:
    T = np.atleast_3d(T).reshape(-1, 4, 4)
    R = T[:, :3, :3]
    np.testing.assert_allclose(
        R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    np.testing.assert_allclose(T[:, 3], np.broadcast_to([0, 0, 0, 1.0], (len(T), 4)), atol=0)


def test_is_a_terrain(terrain):
    assert isinstance(terrain, Terrain)
    assert isinstance(terrain.kind, str) and terrain.label


def test_frames_orthonormal_and_composed(terrain, rng):
    P = poses(rng, 20)
    assert_rigid(terrain.G_T_M())
    assert_rigid(terrain.M_T_B(P))
    assert_rigid(terrain.G_T_B(P))
    np.testing.assert_allclose(terrain.G_T_B(P), terrain.G_T_M() @ terrain.M_T_B(P), atol=1e-12)
    # the yaw is the heading of the body x axis about M's z
    x_M = terrain.M_T_B(P)[:, :3, 0]
    np.testing.assert_allclose(np.arctan2(x_M[:, 1], x_M[:, 0]), P[:, 2], atol=1e-9)


def test_local_ground_reproduces_the_resting_pose(terrain, rng):
    P = poses(rng, 20)
    np.testing.assert_allclose(
        local_transforms(P, terrain.local_ground(P)), terrain.M_T_B(P), atol=1e-12
    )


def test_gravity_body_is_G_gravity_rotated_into_B(terrain, rng):
    P = poses(rng, 20)
    R = terrain.G_T_B(P)[:, :3, :3]
    g = terrain.gravity_body(P)
    np.testing.assert_allclose(g, np.einsum("nji,j->ni", R, GRAVITY_G), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), 9.81, atol=1e-12)


def test_place_numeric_equals_symbolic_and_M_T_B(terrain, rng):
    P, X = poses(rng, 10), rng.normal(size=(10, 3))
    placed = terrain.place(P, X)
    T = terrain.M_T_B(P)
    np.testing.assert_allclose(
        placed, np.einsum("nij,nj->ni", T[:, :3, :3], X) + T[:, :3, 3], atol=1e-12
    )
    # the symbolic placement the controller uses: the one placement with the local ground
    ground = terrain.local_ground(P)
    f = placement_function()
    for k in range(len(P)):
        got = np.asarray(f(P[k], ground[k], X[k])[0]).ravel()
        np.testing.assert_allclose(got, placed[k], atol=1e-12)
    # the terrain's own place_sx: exact on a plane, exact at its reference pose elsewhere
    pose, point = ca.SX.sym("pose", 3), ca.SX.sym("point", 3)
    if terrain.kind == "heightmap":
        terrain = terrain.at(P[0])
        P, placed = P[:1], placed[:1]
    g = ca.Function("g", [pose, point], [terrain.place_sx(pose, point)])
    for k in range(len(P)):
        np.testing.assert_allclose(np.asarray(g(P[k], X[k])).ravel(), placed[k], atol=1e-12)


def test_batched_equals_single(terrain, rng):
    P, X = poses(rng, 6), rng.normal(size=(6, 3))
    for k in range(len(P)):
        np.testing.assert_allclose(terrain.M_T_B(P[k]), terrain.M_T_B(P)[k], atol=0)
        np.testing.assert_allclose(terrain.G_T_B(P[k]), terrain.G_T_B(P)[k], atol=0)
        np.testing.assert_allclose(
            terrain.gravity_body(P[k])[0], terrain.gravity_body(P)[k], atol=0
        )
        np.testing.assert_allclose(terrain.place(P[k], X[k])[0], terrain.place(P, X)[k], atol=1e-15)
        np.testing.assert_allclose(
            terrain.local_ground(P[k])[0], terrain.local_ground(P)[k], atol=0
        )
    # one body point for many poses broadcasts
    np.testing.assert_allclose(terrain.place(P, X[0]), terrain.place(P, np.tile(X[0], (6, 1))))


def test_placement_is_a_rigid_motion_of_body_points(terrain, rng):
    """Moving the body points rigidly moves their placement by the same motion."""
    pose = poses(rng, 1)[0]
    X = rng.normal(size=(8, 3))
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    Q *= np.sign(np.linalg.det(Q))  # a rotation
    t = rng.normal(size=3)
    placed = terrain.place(np.tile(pose, (8, 1)), X)
    moved = terrain.place(np.tile(pose, (8, 1)), X @ Q.T + t)
    R = terrain.M_T_B(pose)[:3, :3]
    np.testing.assert_allclose(moved - placed, (X @ Q.T + t - X) @ R.T, atol=1e-12)
    d = np.linalg.norm(placed[:, None] - placed[None], axis=-1)
    np.testing.assert_allclose(d, np.linalg.norm(X[:, None] - X[None], axis=-1), atol=1e-12)


def test_placement_jacobians_equal_finite_differences(terrain, rng):
    P, X = poses(rng, 5), rng.normal(size=(5, 3))
    ground = terrain.local_ground(P)
    pl = place_local(P, ground, X)
    h = 1e-6
    for k in range(len(P)):
        fd = np.stack(
            [
                (
                    place_local(P[k] + h * e, ground[k], X[k]).points[0]
                    - place_local(P[k] - h * e, ground[k], X[k]).points[0]
                )
                / (2 * h)
                for e in np.eye(3)
            ],
            axis=1,
        )
        np.testing.assert_allclose(pl.d_pose[k], fd, atol=1e-8)
        np.testing.assert_allclose(pl.d_point[k], terrain.M_T_B(P[k])[:3, :3], atol=1e-12)
    assert placement_function().n_out() == 3


def test_support_contacts_are_the_body_contacts_placed(terrain, robot, rng):
    pose = poses(rng, 1)[0]
    contacts_B = robot.base.support_points()
    s = terrain.support(robot, pose)
    np.testing.assert_allclose(s.G_T_B, terrain.G_T_B(pose), atol=1e-12)
    assert len(s.polygon_G) >= 3
    if terrain.kind == "ramp":  # a plane: exactly the base's support points
        assert len(s.contacts_G) == len(contacts_B)
    # every polygon vertex is a bearing contact; every touching contact bears load
    bearing = s.bearing()
    for v in s.polygon_G:
        assert np.min(np.linalg.norm(bearing - v, axis=1)) < 1e-12
    for v in s.contacts_G:
        assert np.min(np.linalg.norm(bearing - v, axis=1)) < 1e-12
    # the bearing contacts are on the ground or within the tracks' compliance above it
    b_M = (np.linalg.inv(terrain.G_T_M()) @ np.c_[bearing, np.ones(len(bearing))].T).T
    gap = bearing[:, 2] - terrain.surface_G(b_M[:, 0], b_M[:, 1])[:, 2]
    assert gap.min() >= -1e-9 and gap.max() <= 0.02 + 1e-9
    # the contacts rest on the ground
    pts_M = (np.linalg.inv(terrain.G_T_M()) @ np.c_[s.contacts_G, np.ones(len(s.contacts_G))].T).T
    ground = terrain.surface_G(pts_M[:, 0], pts_M[:, 1])
    np.testing.assert_allclose(s.contacts_G, ground, atol=CONTACT_TOL[terrain.kind])


def test_ramp_is_invariant_under_motions_along_its_plane(rng):
    """On a plane, moving the pose along it changes neither gravity in B nor the local ground."""
    for slope in (0.0, 0.2, 0.6):
        ramp = Ramp(slope)
        P = poses(rng, 10)
        shifted = P + np.c_[rng.uniform(-5, 5, (10, 2)), np.zeros(10)]
        np.testing.assert_allclose(ramp.gravity_body(shifted), ramp.gravity_body(P), atol=1e-12)
        np.testing.assert_allclose(ramp.local_ground(shifted), ramp.local_ground(P), atol=0)
        # uphill is +y_M: the body z is the plane normal, tilted by the slope from vertical
        np.testing.assert_allclose(ramp.G_T_B(P)[:, 2, 2], np.cos(slope), atol=1e-12)


def test_from_section_builds_the_ramp_and_names_a_bad_kind(tmp_path):
    from mmstab.core.files import ConfigError
    from mmstab.terrain import from_section

    t = from_section(tmp_path / "p.yaml", {"slope": 0.2})
    assert isinstance(t, Ramp) and t.slope == 0.2
    with pytest.raises(ConfigError, match="terrain.kind"):
        from_section(tmp_path / "p.yaml", {"kind": "lava", "slope": 0.2})


def test_local_ground_angles_are_roll_and_pitch(rng):
    """A body tilted by the local ground (roll, pitch) on level ground reads them back."""
    from mmstab.terrain import roll_pitch

    class Tilted:  # M = G, the body resting at a given tilt
        def __init__(self, ground):
            self.ground = np.asarray(ground, dtype=float)

        def gravity_body(self, poses):
            R = local_transforms(poses, self.ground)[:, :3, :3]
            return np.einsum("nji,j->ni", R, GRAVITY_G)

    for _ in range(10):
        roll, pitch = rng.uniform(-0.6, 0.6, 2)
        got = roll_pitch(Tilted([0.0, roll, pitch]), [0.0, 0.0, rng.uniform(-3, 3)])
        np.testing.assert_allclose(got, (roll, pitch), atol=1e-12)
    # positive pitch lifts the nose: the body x axis points up
    T = local_transforms([0.0, 0.0, 0.0], [0.0, 0.0, 0.3])[0]
    assert T[2, 0] > 0


def test_bounds_hold_the_known_ground(terrain):
    """``bounds`` is None (no edge) or the rectangle of M where ``surface_G`` answers."""
    from mmstab.terrain import OffMapError

    b = terrain.bounds
    if terrain.kind == "ramp":
        assert b is None
        return
    x0, x1, y0, y1 = b
    assert x0 < x1 and y0 < y1
    corners = terrain.surface_G([x0, x1, x1, x0], [y0, y0, y1, y1])
    assert np.all(np.isfinite(corners))
    with pytest.raises(OffMapError, match="off the map"):
        terrain.surface_G(x0 - 0.01, y0)
