"""One state, one μ: plan, rest, track, the stability map and the online loop agree.

On seeded random maps with a side slope, bumps, a ditch and a kerb (maps and postures the
tests draw), every entry point that reports μ for a base pose and an arm posture gives the
same number to 1e-9: the force-angle measure on the contacts that carry that state's load
(``mmstab.stability.support``). A heightmap that is a plane gives the ramp's μ.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from mmstab.core.problem import load_problem, problem_from_dict
from mmstab.stability.stance import stability_map, stance
from mmstab.stability.static import robot_force_angle
from mmstab.stability.support import loaded_mu, loaded_support, posture_mu, stability_along
from mmstab.terrain import HeightmapTerrain, Ramp
from mmstab.terrain.generators import generate

ROOT = Path(__file__).resolve().parents[2]
ROBOT = ROOT / "problems" / "robots" / "cameleon.yaml"
TOL = 1e-9


def user_ground(rng: np.random.Generator, size: float = 8.0) -> dict:
    """A ``terrain.generate`` section: bumps on a 0-20 deg side slope, a ditch and a kerb."""
    return {
        "kind": "rough",
        "seed": int(rng.integers(0, 2**31)),
        "size": [size, size],
        "resolution": 0.05,
        "amplitude": float(rng.uniform(0.005, 0.03)),
        "correlation_length": float(rng.uniform(0.3, 0.8)),
        "hill_height": float(rng.uniform(-0.2, 0.2)),
        "hill_radius": float(rng.uniform(1.0, 2.0)),
        "slope": float(np.radians(rng.uniform(0.0, 20.0))),
        "azimuth": float(rng.uniform(-np.pi, np.pi)),
        "features": {
            "ditch": {
                "depth": float(rng.uniform(0.08, 0.2)),
                "width": float(rng.uniform(0.4, 0.8)),
                "distance": float(rng.uniform(-0.5, 0.5)),
                "azimuth": float(rng.uniform(-np.pi, np.pi)),
            },
            "kerb": {
                "height": float(rng.uniform(0.04, 0.1)),
                "distance": float(rng.uniform(-1.5, 1.5)),
                "azimuth": float(rng.uniform(-np.pi, np.pi)),
            },
        },
    }


def ground_problem(rng: np.random.Generator, tmp: Path, robot: Path = ROBOT):
    """A problem on a random user-like ground (robot, terrain, a short route)."""
    data = {
        "robot": str(robot),
        "terrain": {"generate": user_ground(rng)},
        "path": {"waypoints": [[-1.5, -0.5], [1.5, 0.5]], "speed": 0.25, "turn_radius": 0.0},
    }
    path = tmp / "ground.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_problem(path)


def random_states(problem, rng: np.random.Generator, n: int):
    """Poses near the map centre (any yaw) and postures within the joint limits."""
    robot = problem.robot
    poses = np.c_[rng.uniform(-1.5, 1.5, (n, 2)), rng.uniform(-np.pi, np.pi, n)]
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (n, robot.arm_joints))
    return poses, q


@pytest.mark.parametrize(("seed", "drawn"), [(11, False), (12, False), (13, False), (21, True),
                                            (22, True), (28, True)])  # fmt: skip
def test_rest_track_and_the_batched_mu_agree_on_random_ground(seed, drawn, tmp_path):
    """The Cameleon, and robots drawn at random (``conftest.random_robot``: no, one or two
    flipper pairs, 3-6 joints)."""
    rng = np.random.default_rng(seed)
    robot_file = ROBOT
    if drawn:
        from conftest import random_robot

        robot_file = tmp_path / "drawn.yaml"
        robot_file.write_text(yaml.safe_dump(random_robot(rng)))
    problem = ground_problem(rng, tmp_path, robot_file)
    robot, terrain = problem.robot, problem.terrain
    poses, q = random_states(problem, rng, 12)
    batched = posture_mu(robot, terrain, poses, q)
    assert np.isfinite(batched).all()
    # rest: one pose at a time, through the command's function
    rest = np.array(
        [stance(terrain, robot, p, arm_q=qi).mu for p, qi in zip(poses, q, strict=True)]
    )
    np.testing.assert_allclose(rest, batched, rtol=0, atol=TOL)
    # track: the run's μ of states (pose, track angles, arm) and its three cases
    from mmstab.runs.tracking.simulation import mu_with_arm

    states = np.c_[poses, np.zeros((len(poses), 2)), q]
    np.testing.assert_allclose(mu_with_arm(problem, states), batched, rtol=0, atol=TOL)
    cases = stability_along(robot, terrain, poses, robot.arm_com(q))
    np.testing.assert_allclose(cases.reconfigured, batched, rtol=0, atol=TOL)
    stowed = [stance(terrain, robot, p).mu for p in poses]
    np.testing.assert_allclose(cases.stowed, stowed, rtol=0, atol=TOL)


def test_the_arm_moves_the_rest_and_the_support_on_a_bump(tmp_path):
    """Not the stowed arm's rest: the arm's CoM decides which contacts carry the load."""
    rng = np.random.default_rng(5)
    problem = ground_problem(rng, tmp_path)
    robot, terrain = problem.robot, problem.terrain
    poses, q = random_states(problem, rng, 40)
    loaded = posture_mu(robot, terrain, poses, q)
    # the old basis: the tracks' rectangle under the stowed arm's rest
    rectangle = robot_force_angle(robot, terrain.gravity_body(poses), robot.arm_com(q)).mu
    assert np.max(np.abs(loaded - rectangle) / np.abs(rectangle)) > 0.05


def test_a_plane_heightmap_gives_the_ramps_mu(robot):
    slope, azimuth = np.radians(14.0), np.radians(90.0)  # uphill +y: the ramp's S
    hm = generate(
        {"kind": "plane", "seed": 0, "size": [8.0, 8.0], "resolution": 0.05,
         "slope": slope, "azimuth": azimuth}
    )  # fmt: skip
    plane = HeightmapTerrain(hm).with_robot(robot)
    ramp = Ramp(slope)
    rng = np.random.default_rng(3)
    heading = rng.uniform(-np.pi, np.pi, 10)
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (10, robot.arm_joints))
    # the same body heading on both: the ramp's heading in S seen from above in G (the
    # ramp's uphill is +y, as the map's with azimuth pi/2)
    R = ramp.G_T_B(np.c_[np.zeros((10, 2)), heading])[:, :3, :3]
    yaw = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    on_plane = posture_mu(robot, plane, np.c_[np.zeros((10, 2)), yaw], q)
    on_ramp = posture_mu(robot, ramp, np.c_[np.zeros((10, 2)), heading], q)
    assert np.ptp(on_ramp) > 10.0  # the headings and postures differ
    np.testing.assert_allclose(on_plane, on_ramp, rtol=1e-6)


def test_the_stability_map_reads_the_same_mu_as_rest(tmp_path):
    rng = np.random.default_rng(21)
    problem = ground_problem(rng, tmp_path)
    robot = problem.robot
    terrain = problem.terrain.with_robot(robot)
    m = stability_map(terrain, spacing=1.0, n_headings=4)
    iy, ix = len(m.y) // 2, len(m.x) // 2
    for h, yaw in enumerate(m.headings):
        pose = np.array([m.x[ix], m.y[iy], yaw])
        want = stance(problem.terrain, robot, pose).mu
        assert m.mu[iy, ix, h] == pytest.approx(want, abs=TOL)


def test_arm_removed_and_nan_postures(tmp_path):
    rng = np.random.default_rng(8)
    problem = ground_problem(rng, tmp_path)
    robot, terrain = problem.robot, problem.terrain
    poses, q = random_states(problem, rng, 3)
    q[1] = np.nan  # no posture found: no state, no μ
    mu = posture_mu(robot, terrain, poses, q)
    assert np.isnan(mu[1]) and np.isfinite(mu[[0, 2]]).all()
    removed = loaded_support(robot, terrain, poses, None)
    assert np.isfinite(removed.mu).all()
    # the base alone on its own rest: the measure scales with the base's weight
    g = removed.gravity_body
    assert np.allclose(np.linalg.norm(g, axis=1), 9.81)
    off_map = np.array([[100.0, 100.0, 0.0]])
    assert np.isnan(loaded_mu(robot, terrain, off_map, robot.arm_com(robot.stowed), strict=False))[
        0
    ]


@pytest.mark.parametrize("seed", [41, 42])
def test_the_viewer_and_the_recordings_show_the_support_mu_is_computed_on(seed, tmp_path):
    """The viewer's picture of a state and a run's recorded frames rest the base under that
    state's own CoM: their μ is the one μ, the polygon's least force angle gives it, the body
    pose is ``rest``'s (the stowed arm's rest is another on this ground)."""
    from mmstab.runs.recording import frames_at
    from mmstab.viz.viewer.scene import instant

    rng = np.random.default_rng(seed)
    problem = ground_problem(rng, tmp_path)
    robot, terrain = problem.robot, problem.terrain
    poses, q = random_states(problem, rng, 20)
    want = posture_mu(robot, terrain, poses, q)
    frames = frames_at(terrain, robot, np.arange(20.0), poses, q, want)
    weight = robot.total_mass * 9.81
    moved = 0
    for i, (pose, qi) in enumerate(zip(poses, q, strict=True)):
        now, rest = instant(robot, terrain, pose, qi), stance(robot, terrain, pose, arm=qi)
        assert now.mu == pytest.approx(want[i], abs=TOL)
        assert now.angles.min() * weight == pytest.approx(want[i], abs=TOL)
        np.testing.assert_allclose(now.G_T_B, rest.G_T_B, rtol=0, atol=1e-12)
        np.testing.assert_allclose(frames.G_T_B[i], rest.G_T_B, rtol=0, atol=1e-12)
        assert {tuple(p) for p in np.round(frames.polygons[i], 9)} == {
            tuple(p) for p in np.round(now.polygon_G, 9)
        }
        moved += not np.allclose(stance(robot, terrain, pose).G_T_B, rest.G_T_B, atol=1e-6)
    assert moved > 0
    removed = instant(robot, terrain, poses[0], None)  # the arm removed: the base's own rest
    assert removed.mu == pytest.approx(loaded_support(robot, terrain, poses[0], None).mu[0])
    assert removed.angles.min() * robot.base.mass * 9.81 == pytest.approx(removed.mu, abs=TOL)


@pytest.mark.slow
def test_a_route_plan_reports_what_rest_gives_at_its_poses(tmp_path):
    """The plan's μ at each pose with its posture is ``mmstab rest``'s for that state."""
    from mmstab.app import plan as make_plan
    from mmstab.workspace import load_or_build_workspace

    rng = np.random.default_rng(31)
    data = {
        "robot": str(ROBOT),
        "terrain": {"generate": user_ground(rng)},
        "path": {
            "waypoints": [[-2.0, -0.5], [0.0, 0.3], [2.0, -0.2]],
            "speed": 0.25,
            "turn_radius": 0.0,
        },
        "workspace": {"grid": [5, 5, 5, 5]},
        "planner": {"spacing": 0.5},
    }
    problem = problem_from_dict(data, tmp_path / "p.yaml")
    ws = load_or_build_workspace(problem, progress=False, cache_dir=tmp_path / "cache")
    plan = make_plan(problem, ws=ws)
    robot = problem.robot
    found = np.isfinite(plan.postures).all(axis=1)
    assert found.sum() >= len(found) - 1
    rest = [
        stance(problem.terrain, robot, p, arm_q=q).mu
        for p, q in zip(plan.poses[found], plan.postures[found], strict=True)
    ]
    np.testing.assert_allclose(plan.mu_planned[found], rest, rtol=0, atol=TOL)
    stowed = [stance(problem.terrain, robot, p).mu for p in plan.poses]
    np.testing.assert_allclose(plan.mu_stowed, stowed, rtol=0, atol=TOL)
    # the search's own basis is kept apart, and differs on this ground
    assert plan.mu_search.shape == plan.mu_planned.shape


@pytest.mark.parametrize("wrench", [None, (15.0, -5.0, -40.0, 2.0, 1.0, -3.0)])
def test_the_batched_hulls_give_the_per_state_mu(tmp_path, monkeypatch, wrench):
    """μ along many states (hulls wrapped all at once) is the per-state hull_along's to 1e-12.

    With a tool wrench too (the dynamic measure on the batch's polygon, per state). The C
    kernel (gravity alone) is held off here and checked in the next test.
    """
    import dataclasses

    import mmstab.stability.support as support
    from mmstab.terrain.polygon_batch import hulls_along_batch

    rng = np.random.default_rng(11)
    problem = ground_problem(rng, tmp_path)
    robot, terrain = problem.robot, problem.terrain
    if wrench is not None:
        robot = dataclasses.replace(robot, tool_wrench=np.array(wrench))
    poses, q = random_states(problem, rng, 60)
    answered = []

    def spy(*args, **kwargs):
        hulls = hulls_along_batch(*args, **kwargs)
        answered.append(hulls.ok.mean())
        return hulls

    monkeypatch.setattr(support, "support_mu_c", lambda *args: None)
    monkeypatch.setattr(support, "hulls_along_batch", spy)
    batched = loaded_support(robot, terrain, poses, robot.arm_com(q), q)
    assert answered[0] > 0.8  # the batch answers most states

    def none(*args, **kwargs):  # every state through the per-state hull_along
        hulls = hulls_along_batch(*args, **kwargs)
        return hulls._replace(ok=np.zeros_like(hulls.ok))

    monkeypatch.setattr(support, "hulls_along_batch", none)
    single = loaded_support(robot, terrain, poses, robot.arm_com(q), q)
    np.testing.assert_allclose(batched.mu, single.mu, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(batched.line, single.line)
    assert np.isfinite(batched.mu).sum() > 50
    if wrench is not None:  # the wrench's measure, not gravity's alone
        plain = loaded_support(problem.robot, terrain, poses, robot.arm_com(q), q).mu
        assert np.nanmax(np.abs(plain - batched.mu)) > 1.0


@pytest.mark.parametrize("seed", [31, 32])
def test_the_c_kernel_gives_the_numpy_batchs_and_the_per_state_mu(tmp_path, monkeypatch, seed):
    """The loaded support's μ in C (``support_mu.c``) against the NumPy batch and the
    per-state hull_along, on random user-like ground: states at kerbs and ditch rims
    included, where the C kernel leaves lines and close pairs to the per-state path."""
    import mmstab.stability.support as support
    from mmstab.stability.support_kernel import support_mu_c
    from mmstab.terrain.polygon_batch import hulls_along_batch

    rng = np.random.default_rng(seed)
    problem = ground_problem(rng, tmp_path)
    robot, terrain = problem.robot, problem.terrain
    poses, q = random_states(problem, rng, 300)
    settled = []

    def spy(*args):
        out = support_mu_c(*args)
        assert out is not None  # the C compiler is there (make setup)
        settled.append(out[1].mean())
        return out

    monkeypatch.setattr(support, "support_mu_c", spy)
    in_c = loaded_support(robot, terrain, poses, robot.arm_com(q)).mu
    assert settled[0] > 0.9
    monkeypatch.setattr(support, "support_mu_c", lambda *args: None)
    in_numpy = loaded_support(robot, terrain, poses, robot.arm_com(q)).mu
    np.testing.assert_allclose(in_c, in_numpy, rtol=0, atol=1e-9)

    def none(*args, **kwargs):
        hulls = hulls_along_batch(*args, **kwargs)
        return hulls._replace(ok=np.zeros_like(hulls.ok))

    monkeypatch.setattr(support, "hulls_along_batch", none)
    single = loaded_support(robot, terrain, poses, robot.arm_com(q)).mu
    np.testing.assert_allclose(in_c, single, rtol=0, atol=1e-9)
    assert np.isfinite(in_c).sum() > 250 and (in_c < 0).sum() + (in_c > 0).sum() > 250
