"""A tracked base without flippers: the robot file leaves ``base.flippers`` out.

Checked against a twin whose flippers are tiny boxes hidden inside the tracks (no ground
and no arm link can reach them without reaching a track first): the two rest alike and give
the same μ on seeded random maps with ditches, kerbs and bumps, and their arms collide at
the same postures. A plane gives the ramp's answer; MuJoCo's model has no flipper bodies and
the description's mass.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import SCOUT
from test_one_mu import user_ground

from mmstab.cli import main
from mmstab.core.files import ConfigError, MmstabError
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import flipper_ground_angle, robot_from_dict, with_flipper_angle
from mmstab.model.urdf import base_link_inertias, robot_to_urdf
from mmstab.planner.levers import flipper_limits
from mmstab.stability.stance import stance
from mmstab.stability.support import posture_mu
from mmstab.terrain import HeightmapTerrain, Ramp
from mmstab.terrain.contacts import FLIPPER, contact_candidates
from mmstab.terrain.generators import generate


def scout() -> dict:
    """The scout, its turret allowed to touch the body it sits on (as docs/robot.md says)."""
    return {**copy.deepcopy(SCOUT), "collision": {"allow": [["turret", "body"]]}}


def plain_file() -> dict:
    data = scout()
    del data["base"]["flippers"]
    data["name"] = "plain"
    return data


def hidden_file() -> dict:
    """The scout with 1 cm flippers at the middle of its tracks, half way up the belts."""
    data = scout()
    t = data["base"]["tracks"]
    data["base"]["flippers"] = {"length": 0.01, "width": 0.01, "thickness": 0.01,
                                "pivot": [-0.005, t["separation"] / 2, t["height"] / 2],
                                "angle": 0.0}  # fmt: skip
    return data


@pytest.fixture(scope="module")
def plain():
    return robot_from_dict(plain_file(), "plain.yaml")


@pytest.fixture(scope="module")
def hidden():
    return robot_from_dict(hidden_file(), "hidden.yaml")


def test_the_description_has_three_base_parts(plain, hidden):
    assert plain.base.flippers is None
    assert list(plain.base.collision_boxes()) == ["body", "track_left", "track_right"]
    t = plain.base.tracks
    corners = {(sx * t.length / 2, sy * (t.separation + t.width) / 2, 0.0)
               for sx in (1, -1) for sy in (1, -1)}  # fmt: skip
    assert {tuple(p) for p in plain.base.support_points()} == corners
    assert not (contact_candidates(plain.base).part == FLIPPER).any()
    assert plain.source_hash != hidden.source_hash
    # the URDF export: three base links whose masses sum to the base's at its CoM
    inertias = base_link_inertias(plain)
    assert list(inertias) == ["body", "track_left", "track_right"]
    boxes = plain.base.collision_boxes()
    mass = sum(i.mass for i in inertias.values())
    com = sum(i.mass * (boxes[n].frame_T_shape @ i.frame_T_com)[:3, 3] for n, i in inertias.items())
    assert mass == pytest.approx(plain.base.mass, rel=1e-12)
    np.testing.assert_allclose(com / mass, plain.base.com, atol=1e-12)
    urdf = robot_to_urdf(plain)
    assert "flipper" not in urdf and 'link name="track_left"' in urdf


@pytest.mark.parametrize("seed", [21, 22])
def test_rests_and_mu_as_the_hidden_flippers_on_random_ground(plain, hidden, seed):
    rng = np.random.default_rng(seed)
    hm = generate(user_ground(rng))
    poses = np.c_[rng.uniform(-1.5, 1.5, (16, 2)), rng.uniform(-np.pi, np.pi, 16)]
    q = rng.uniform(plain.joint_lower, plain.joint_upper, (16, plain.arm_joints))
    ground = {r.name: HeightmapTerrain(hm).with_robot(r) for r in (plain, hidden)}
    rests = {name: g.rest(poses) for name, g in ground.items()}
    np.testing.assert_allclose(rests["plain"].G_T_B, rests["scout"].G_T_B, rtol=0, atol=1e-9)
    mu = {r.name: posture_mu(r, ground[r.name], poses, q) for r in (plain, hidden)}
    assert np.isfinite(mu["plain"]).all()
    np.testing.assert_allclose(mu["plain"], mu["scout"], rtol=0, atol=1e-9)
    one = [stance(plain, ground["plain"], p, arm=qi).mu for p, qi in zip(poses, q, strict=True)]
    np.testing.assert_allclose(one, mu["plain"], rtol=0, atol=1e-9)


def test_a_plane_gives_the_ramps_answer(plain, rng):
    slope = np.radians(12.0)
    hm = generate({"kind": "plane", "seed": 0, "size": [6.0, 6.0], "resolution": 0.05,
                   "slope": slope, "azimuth": np.pi / 2})  # fmt: skip
    ramp, heading = Ramp(slope), rng.uniform(-np.pi, np.pi, 8)
    q = rng.uniform(plain.joint_lower, plain.joint_upper, (8, plain.arm_joints))
    # the ramp's heading in S seen from above in G (both rise toward +y)
    R = ramp.G_T_B(np.c_[np.zeros((8, 2)), heading])[:, :3, :3]
    yaw = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    on_map = posture_mu(plain, HeightmapTerrain(hm), np.c_[np.zeros((8, 2)), yaw], q)
    on_ramp = posture_mu(plain, ramp, np.c_[np.zeros((8, 2)), heading], q)
    assert np.ptp(on_ramp) > 10.0
    np.testing.assert_allclose(on_map, on_ramp, rtol=1e-6)


def test_the_arm_collides_where_the_hidden_flippers_twin_does(plain, hidden, rng):
    q = rng.uniform(plain.joint_lower, plain.joint_upper, (400, plain.arm_joints))
    a, b = CollisionChecker(plain), CollisionChecker(hidden)
    assert not any("flipper" in p.name for p in a.pairs)
    got = a.collides(q, cull=False)
    assert 0 < got.sum() < len(q)  # both answers occur among the postures
    np.testing.assert_array_equal(got, b.collides(q, cull=False))
    np.testing.assert_array_equal(a.collides(q), got)


def test_setting_flippers_it_has_not_is_refused(plain, tmp_path, capsys):
    with pytest.raises(MmstabError, match="has no flippers"):
        with_flipper_angle(plain, 0.3)
    with pytest.raises(ValueError, match="has no flippers"):
        flipper_ground_angle(plain)
    with pytest.raises(MmstabError, match="needs base.flippers.limits"):
        flipper_limits(plain)
    (tmp_path / "plain.yaml").write_text(yaml.safe_dump(plain_file()))
    problem = {"robot": "plain.yaml", "terrain": {"slope": 0.1},
               "path": {"waypoints": [[0, 0], [1, 0]], "speed": 0.2, "turn_radius": 0}}  # fmt: skip
    (tmp_path / "route.yaml").write_text(yaml.safe_dump(problem))
    route = str(tmp_path / "route.yaml")
    assert main(["rest", route, "--pose", "0", "0", "0", "--flipper", "0.2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == "mmstab: error: --flipper: robot plain has no flippers (base.flippers)"
    assert main(["rest", route, "--pose", "0", "0", "0", "--json"]) == 0
    out = capsys.readouterr().out
    assert '"flipper_angle_rad": null' in out


def test_a_flipper_section_with_a_wrong_key_still_names_it(tmp_path):
    data = plain_file()
    data["base"]["flipper"] = copy.deepcopy(SCOUT["base"]["flippers"])
    with pytest.raises(ConfigError, match="flippers"):
        robot_from_dict(data, Path(tmp_path / "typo.yaml"))


def mujoco_model_of(robot, q: np.ndarray) -> tuple[set[str], float, np.ndarray]:
    """MuJoCo's whole robot on a ramp at posture q: its geoms' names, mass and CoM in B."""
    mujoco = pytest.importorskip("mujoco")
    from test_physics_robot import mujoco_composite

    from mmstab.physics.robot_model import build_robot_mjcf

    model = mujoco.MjModel.from_xml_string(
        build_robot_mjcf(robot, Ramp(0.2), pose=(0.1, 0.2, 0.5), arm_q=q)
    )
    geom = mujoco.mjtObj.mjOBJ_GEOM
    names = {mujoco.mj_id2name(model, geom, i) or "" for i in range(model.ngeom)}
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    mass, com, _ = mujoco_composite(model, data)
    return names, mass, com


@pytest.mark.mujoco
def test_the_mujoco_robot_has_no_flipper_bodies_and_the_descriptions_mass(plain):
    q = np.array([0.4, 0.9, -0.7])
    names, mass, com = mujoco_model_of(plain, q)
    assert not any("flipper" in n for n in names) and "chassis" in names
    assert mass == pytest.approx(plain.total_mass, abs=1e-9)
    np.testing.assert_allclose(com, plain.overall_com(plain.arm_com(q)), atol=1e-9)
