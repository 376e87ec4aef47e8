"""The climb limit in the route planner (``planner.climb``, ``mmstab.planner.climbing``)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

import mmstab
from mmstab import app
from mmstab.planner.climbing import ClimbPlan, climb_exclusions, climb_plan
from mmstab.runs.verdict import climb_verdict
from mmstab.stability.climb import ClimbLimit


@pytest.fixture(scope="module")
def kerb() -> mmstab.Problem:
    return mmstab.load_problem(ROOT / "problems" / "kerb.yaml")


def test_the_kerb_route_constrains_the_pose_before_the_kerb_and_the_next(kerb) -> None:
    plan = app.plan(kerb)
    poses = kerb.base_path.pose_at(plan.fractions)
    c = climb_plan(kerb.robot, kerb.terrain, poses, closed=False)
    step = np.flatnonzero(c.limit.step)
    # the front wheels (axle 0.35 m ahead, rim 0.11 m) meet the kerb's face at x = 0.48-0.5 m
    # from the body at x = 0.04 m: the pose at -0.03 m meets it before the next (0.22 m)
    assert [round(float(poses[k, 0]), 2) for k in step] == [-0.03]
    assert list(np.flatnonzero(c.constrained)) == [step[0], step[0] + 1]
    assert list(c.source[c.constrained]) == [step[0], step[0]]
    # the plan keeps both in the half-plane; the stowed arm would stall (quasi-static)
    v = climb_verdict(kerb.robot, kerb.terrain, poses, plan.target_com, False)
    assert v["stalls"] is False and v["stowed_stalls"] is True
    assert [s["planned_climbs"] for s in v["steps"]] == [True, True]
    # one step, met from the pose before it: the body there when the front wheels (axle
    # 0.35 m ahead, rim 0.11 m) meet the face, 0.46 m ahead of the body, at x = 0.48-0.5 m
    assert [s["met_from"] for s in v["steps"]] == [step[0], step[0]]
    body_x = poses[step[0], 0] + v["steps"][0]["met_after_m"]
    assert 0.48 - 0.46 - 0.02 < body_x < 0.50 - 0.46 + 0.02
    com = kerb.robot.overall_com(plan.target_com)
    assert np.all(c.climbs(com)) and np.all(com[c.constrained, 0] < 0.025)


def test_without_the_limit_the_plan_is_checked_at_the_kerb_face(kerb, tmp_path) -> None:
    """Without the climb limit the kerb's plan is only checked: on the loaded support (the
    nose on the kerb's face at the step pose) the most stable postures no longer load the
    front, so it climbs; on the tracks' rectangle they did and it stalled."""
    import yaml

    data = yaml.safe_load((ROOT / "problems" / "kerb.yaml").read_text())
    data["planner"]["climb"] = False
    data["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    path = tmp_path / "kerb.yaml"
    path.write_text(yaml.safe_dump(data))
    problem = mmstab.load_problem(path)
    plan = app.plan(problem)
    poses = problem.base_path.pose_at(plan.fractions)
    v = climb_verdict(problem.robot, problem.terrain, poses, plan.target_com, False)
    assert v["steps"] and all(s["height"] > 0.05 for s in v["steps"])  # the kerb's face, found
    assert v["stalls"] is False and v["stowed_stalls"] is True  # the stowed arm would stall


def _limit(bounds: list[float]) -> ClimbLimit:
    n = len(bounds)
    return ClimbLimit(
        step=np.asarray(bounds) < np.inf, height=np.full(n, 0.1), angle=np.full(n, 0.2),
        ahead=np.zeros(n), com_gain=np.tile([1.0, 0.0], (n, 1)), com_bound=np.array(bounds),
    )  # fmt: skip


class _Fit:
    def mu(self, com: np.ndarray) -> np.ndarray:
        return np.ones(len(com))


def test_exclusions_keep_a_pose_no_posture_climbs(kerb) -> None:
    """A pose whose step nothing climbs (a wall) keeps every row; another excludes by CoM."""
    robot = kerb.robot
    rng = np.random.default_rng(5)
    arm_com = rng.uniform([-0.6, -0.6, 0.0], [0.8, 0.6, 0.8], size=(400, 3))
    x = robot.overall_com(arm_com)[:, 0]
    plan = ClimbPlan(_limit([np.inf, 0.0, -np.inf]), np.array([-1, 1, 2]))
    eligible = rng.random(400) > 0.1
    out = climb_exclusions(robot, plan, arm_com, eligible, [_Fit()] * 3)
    assert set(out) == {1}  # pose 0: no step; pose 2: a wall, kept whole (it stalls there)
    assert np.array_equal(out[1], eligible & (x > 0.0))


@pytest.mark.filterwarnings("error::RuntimeWarning")  # no NumPy noise on stderr either
def test_the_ground_ahead_may_end_at_the_map_edge(kerb) -> None:
    """A pose whose look-ahead leaves the map (a route ending near the edge) has no step
    there, as off-map samples mean "no ground to meet"; it used to raise OffMapError."""
    from mmstab.stability.climb import climb_limit
    from mmstab.terrain.generators import generate
    from mmstab.terrain.heightmap_terrain import HeightmapTerrain

    spec = {"kind": "kerb", "seed": 0, "size": [3.0, 3.0], "resolution": 0.02}
    spec |= {"height": 0.1, "distance": 0.5, "azimuth": 0.0}  # the map ends at x = 1.5 m
    terrain = HeightmapTerrain(generate(spec)).with_robot(kerb.robot)
    poses = np.array([[-0.3, 0.0, 0.0], [0.85, 0.0, 0.0]])  # the second looks 0.4 m past it
    both = climb_limit(kerb.robot, terrain, poses, 0.7, 0.5)
    alone = climb_limit(kerb.robot, terrain, poses[:1], 0.7, 0.5)
    assert list(both.step) == [True, False] and both.com_bound[1] == np.inf
    assert both.com_bound[0] == alone.com_bound[0] and 0.05 < both.height[0] <= 0.11
