"""The support that bears load on uneven ground: the touching contacts and the compliant runs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mmstab.stability.stance import stance
from mmstab.stability.static import contact_force_angle
from mmstab.terrain import Ramp
from mmstab.terrain.base import GRAVITY_G
from mmstab.terrain.factory import from_section
from mmstab.terrain.generators import Grid, generate, plane
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

ROUGH = {
    "kind": "rough",
    "seed": 3,
    "size": [4.0, 4.0],
    "resolution": 0.05,
    "amplitude": 0.04,
    "correlation_length": 0.3,
    "hill_height": 0.3,
    "hill_radius": 1.0,
    "slope": 0.2,
    "azimuth": 0.7,
}


def random_poses(rng: np.random.Generator, n: int, half: float = 0.8) -> np.ndarray:
    return np.c_[rng.uniform(-half, half, (n, 2)), rng.uniform(-np.pi, np.pi, n)]


@pytest.mark.parametrize("slope, azimuth", [(0.0, 0.0), (0.3, 0.5), (0.5, -2.0)])
def test_on_a_plane_the_support_is_the_ramps_rectangle(robot, slope, azimuth):
    """Every bottom-run candidate touches a plane: the bearing polygon is the track
    rectangle, whatever the arm, and no arc point joins it (the compliance only adds
    bottom runs)."""
    g = Grid.of_size((4.0, 4.0), 0.05)
    t = HeightmapTerrain(plane(g, slope, azimuth)).with_robot(robot)
    rect_B = Ramp(0.0).support(robot, np.zeros(3)).polygon_G  # heading 0 on a flat floor
    pose = np.array([0.2, -0.1, 0.4])
    for q in (None, np.array([0.0, 0.6, -0.4, 0.2])):
        st = stance(t, robot, pose, arm_q=q)
        poly_B = (st.support_polygon - st.G_T_B[:3, 3]) @ st.G_T_B[:3, :3]
        assert len(poly_B) == len(rect_B)
        for v in rect_B:
            assert np.min(np.linalg.norm(poly_B - v, axis=1)) < 1e-9


def test_bearing_contacts_add_the_compliant_runs_only(robot):
    """Bearing = touching + bottom-run candidates within the compliance; zero compliance is
    the rigid rest; more support never lowers mu."""
    t = HeightmapTerrain(generate(ROUGH)).with_robot(robot)
    c = t.candidates
    rng = np.random.default_rng(1)
    poses = random_poses(rng, 60)
    r = t.rest(poses)
    assert (r.bearing >= r.touching).all()
    extra = r.bearing & ~r.touching
    assert extra.any() and (c.compliant[None, :] | ~extra).all()
    assert (r.gap[extra] <= t.settings.compliance + 1e-12).all()
    rigid = dataclasses.replace(t, settings=t.settings._replace(compliance=0.0)).rest(poses)
    np.testing.assert_array_equal(rigid.bearing, rigid.touching)
    np.testing.assert_allclose(rigid.G_T_B, r.G_T_B, atol=0)  # the rest itself is the same
    f = robot.total_mass * GRAVITY_G
    com_B = robot.overall_com(robot.arm_com(robot.stowed))
    for i in range(len(poses)):
        T = r.G_T_B[i]
        com_G = T[:3, :3] @ com_B + T[:3, 3]
        on_bearing = contact_force_angle(r.bearing_G(c.points, i), com_G, f).mu
        on_touching = contact_force_angle(r.contacts_G(c.points, i), com_G, f).mu
        assert on_bearing >= on_touching - 1e-9
        assert stance(t, robot, poses[i]).mu == pytest.approx(on_bearing, abs=1e-9)


def test_compliance_from_the_problem_file(tmp_path, robot):
    section = {"generate": ROUGH, "compliance": 0.005}
    t = from_section(tmp_path / "p.yaml", section, robot)
    assert isinstance(t, HeightmapTerrain) and t.settings.compliance == 0.005
    from mmstab.core.files import ConfigError

    with pytest.raises(ConfigError, match="terrain"):
        from_section(tmp_path / "p.yaml", {"generate": ROUGH, "compliance": -0.1}, robot)
