"""The base control point on a side slope, in MuJoCo (docs/controller.md, rough.yaml).

A skid-steer takes back a lateral error only by turning, and on a side slope each radian it
turns slides it s downhill (the skid model's slide per radian, :mod:`mmstab.stability.skid`).
A control point d ahead of the body origin moves sideways by (d − s) per radian turned: a
point closer than s first moves against the turn that steers it, and the feedback chases
its own slides. Here the robot starts 10 cm downhill of a straight path across a 31.5° plane
(rough.yaml's slope, no roughness) and takes the error back with the point 0.2 m and 0.6 m
ahead, s lying between them, without the controller's yaw-rate limit (the mechanism), and
with it (the controller as shipped: the limit keeps the correction's turns slow enough on the
slope that neither point slides).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT

from mmstab import app
from mmstab.control.controller import build_controller
from mmstab.control.limits import build_limits
from mmstab.control.reference import initial_state
from mmstab.core.problem import problem_from_dict
from mmstab.outputs.simulate import controller_settings, loop_settings, stowed_plan
from mmstab.physics.closed_loop import run_closed_loop
from mmstab.stability.skid import track_patch, turn_slide
from mmstab.stability.slip import terrain_friction

pytestmark = pytest.mark.mujoco


def _side_slope(tmp_path: Path, offset: float) -> object:
    data = yaml.safe_load((ROOT / "problems" / "rough.yaml").read_text())
    data["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    gen = data["terrain"]["generate"]
    gen.update(amplitude=0.0, size=[12.0, 6.0])
    gen.pop("features")
    data["path"] = {"waypoints": [[-4.0, 0.0], [4.0, 0.0]], "speed": 0.25, "turn_radius": 1.0,
                    "acceleration": 0.2, "lateral_acceleration": 0.2}  # fmt: skip
    data["workspace"]["grid"] = [10, 8, 8, 8]
    data["controller"]["base_offset"] = offset
    return problem_from_dict(data, tmp_path / f"side_{offset}.yaml")


#: The controller's limits without the yaw-rate limit (the mechanism it removes).
UNBOUNDED = ("joint_velocity", "joint_position")


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[float, bool], object]:
    """(offset, yaw-rate limit on) -> (problem, run)."""
    out = {}
    for offset in (0.2, 0.6):
        problem = _side_slope(tmp_path_factory.mktemp("offset"), offset)
        cs = controller_settings(problem)
        loop = dataclasses.replace(loop_settings(problem), duration=5.0)
        plan = stowed_plan(problem.robot, app.plan(problem))
        state0 = initial_state(problem.base_path, problem.robot.stowed, lateral_offset=-0.10)
        for bounded in (False, True):
            limits = None if bounded else build_limits(UNBOUNDED)
            step = build_controller(problem.robot, cs, limits=limits).step
            run = run_closed_loop(problem, plan, step, cs, loop, state0)
            out[offset, bounded] = (problem, run)
    return out


@pytest.mark.slow
def test_the_slide_per_radian_lies_between_the_two_points(runs) -> None:
    problem, _ = runs[0.2, True]
    pose = problem.base_path.pose_at(np.array([0.5]))
    gravity = problem.terrain.gravity_body(pose)
    com = problem.robot.overall_com(problem.robot.arm_com(problem.robot.stowed))
    slide = turn_slide(track_patch(problem.robot), gravity, com, [0.25], [0.3],
                       terrain_friction(problem.terrain))  # fmt: skip
    assert 0.2 < float(slide.per_radian[0]) < 0.6, slide  # 0.28 m/rad (the stowed arm)


def test_a_point_further_ahead_than_the_slide_takes_the_error_back(runs) -> None:
    """Without the yaw-rate limit."""
    near, far = runs[0.2, False][1], runs[0.6, False][1]
    for run in (near, far):
        assert run.tipped is None and int(np.sum(run.status != 0)) == 0
    late = near.t > 1.0
    # 0.2 m: the correction's turns slide the CoM 19 cm downhill within a second and the
    # point's error doubles (20 cm); 0.6 m: 5.0 cm, and the point within 2.2 cm after 1 s
    assert near.slid is not None and near.slip.max() > 0.15
    assert near.base_error[late].max() > 0.15
    assert far.slip.max() < 0.5 * near.slip.max()
    assert far.base_error[late].max() < 0.05
    assert far.base_error[-1] < 0.01


def test_the_yaw_rate_limit_keeps_the_correction_from_sliding(runs) -> None:
    """With the limit (as shipped) neither point slides; the error still goes."""
    near, far = runs[0.2, True][1], runs[0.6, True][1]
    for run, unbounded in ((near, runs[0.2, False][1]), (far, runs[0.6, False][1])):
        assert run.tipped is None and int(np.sum(run.status != 0)) == 0
        # measured 3.1 and 3.2 cm of drift in the worst second (19 and 5.0 cm unbounded)
        assert run.slid is None and run.slip.max() < 0.05
        assert run.slip.max() < unbounded.slip.max()
        assert run.base_error[-1] < 0.01  # measured 8.8 and 1.3 mm after 5 s
    late = near.t > 1.0
    # the near point's error no longer doubles (measured 11 cm after 1 s, 20 cm unbounded);
    # the far point's correction is slower (5.3 cm after 1 s, 2.2 cm unbounded)
    assert near.base_error[late].max() < 0.6 * runs[0.2, False][1].base_error[late].max()
    assert far.base_error[late].max() < near.base_error[late].max()
