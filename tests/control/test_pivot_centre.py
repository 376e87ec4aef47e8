"""Where the base pivots (mmstab.control.pivot): the skid model's level pivot centre.

The centre is where the belts' sideways friction balances on level ground: at B's origin
for a CoM over it (the patch is symmetric), mirrored with the CoM, and a little beyond the
CoM (the load under the CoM's end of the belts resists more). MuJoCo's robot pivots there
too (tests/physics/test_physics_pivot.py: 6.8 cm measured on a plane, the model's 6.3 cm).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import ROOT

from mmstab.control.pivot import pivot_centre, route_pivot_centres
from mmstab.model.robot import load_robot
from mmstab.paths import SpeedLimits, route_from_waypoints, speed_profile
from mmstab.paths.route import RoutePath


@pytest.fixture(scope="module")
def robot():
    return load_robot(ROOT / "problems" / "robots" / "cameleon.yaml")


def test_the_centre_follows_the_centre_of_mass(robot) -> None:
    x = np.array([-0.1, -0.05, 0.0, 0.05, 0.1])
    c = pivot_centre(robot, np.column_stack([x, np.zeros(5), np.full(5, 0.15)]))
    assert c[2] == pytest.approx(0.0, abs=1e-9)  # over the origin: about the origin
    np.testing.assert_allclose(c[::-1], -c, atol=1e-9)  # mirrored with the CoM
    assert np.all(np.diff(c) > 0)
    # beyond the CoM, by less than a third of its offset (1.3 / 2.1 cm at 5 / 10 cm)
    assert np.all(np.abs(c[3:]) > x[3:]) and np.all(c[3:] < 1.33 * x[3:])
    stowed = robot.overall_com(robot.arm_com(robot.stowed))
    assert pivot_centre(robot, stowed)[0] == pytest.approx(0.063, abs=0.002)  # measured


def test_each_pivot_of_a_route_takes_the_plans_com_there(robot) -> None:
    """Two pivots: the arm's CoM target forward at the first, back at the second."""
    t = robot.base.tracks
    limits = SpeedLimits(0.25, 0.3, 0.3, t.sprocket_radius * t.velocity_limit, t.separation)
    route = route_from_waypoints([[0, 0], [2, 0], [2, 2], [0, 2]], 0.0, t.separation / 2)
    path = RoutePath(route, speed_profile(route, limits), limits)
    (a0, a1), (b0, b1) = path.route.pivot_spans
    fwd, back = [0.3, 0.0, 0.4], [-0.3, 0.0, 0.4]  # arm CoM in B [m]
    knots = np.r_[0.0, path.fraction_of_s([a0, a1, b0, b1]), 0.99]
    plan = SimpleNamespace(fractions=knots, target_com=np.array([fwd] * 3 + [back] * 3))
    got = route_pivot_centres(robot, path, plan)
    want = pivot_centre(robot, robot.overall_com(np.array([fwd, back])))
    np.testing.assert_allclose(got, want, atol=1e-12)
    assert got[0] > 0.05 and got[1] < -0.05


@pytest.mark.parametrize("bad", [0.8, -0.6, "centre", None])
def test_bad_pivot_centre_exits_2_naming_file_and_field(tmp_path, capsys, bad) -> None:
    from conftest import write_problem

    from mmstab.cli import main

    path = write_problem(
        tmp_path, lambda p, r: p.setdefault("physics", {}).update(pivot_centre=bad)
    )
    assert main(["simulate", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(path) in err and "physics.pivot_centre" in err
    assert not (tmp_path / "out").exists()


def test_the_loop_turns_the_routes_pivots_as_set(tmp_path) -> None:
    """``physics.pivot_centre``: read from the problem; 0 and a circle leave the path alone."""
    from conftest import write_problem

    from mmstab.control.pivot import pivoting
    from mmstab.core.problem import load_problem, problem_from_dict
    from mmstab.outputs.simulate import loop_settings

    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    assert loop_settings(load_problem(write_problem(tmp_path / "a"))).pivot_centre == "auto"
    set_ = write_problem(
        tmp_path / "b", lambda p, r: p.setdefault("physics", {}).update(pivot_centre=0.05)
    )
    ramp = load_problem(set_)
    assert loop_settings(ramp).pivot_centre == 0.05
    assert pivoting(ramp, None, 0.05) is ramp  # the ramp's circle has no pivot
    data = {
        "robot": str(ROOT / "problems" / "robots" / "cameleon.yaml"),
        "terrain": {"generate": {"kind": "plane", "slope": 0.0, "azimuth": 0.0, "seed": 1,
                                 "size": [5.0, 5.0], "resolution": 0.05}},
        "path": {"waypoints": [[-1.2, 0.0], [0.0, 0.0], [0.0, 1.2]], "speed": 0.25,
                 "turn_radius": 0.0},
    }  # fmt: skip
    problem = problem_from_dict(data, tmp_path / "route.yaml")
    stowed = problem.robot.arm_com(problem.robot.stowed)
    plan = SimpleNamespace(fractions=np.array([0.0, 0.5]), target_com=np.tile(stowed, (2, 1)))
    assert pivoting(problem, plan, 0.0) is problem
    for centre, want in ((0.1, 0.1), ("auto", 0.063)):
        turned = pivoting(problem, plan, centre).base_path
        (s0, s1), *_ = turned.route.pivot_spans
        pose = turned.route.sample([s0, s1]).pose
        np.testing.assert_allclose(pose[:, :2], [[-want, 0.0], [0.0, -want]], atol=1e-3)
        # the same time (to the speed profile's grid: 0.25 ms here)
        assert turned.duration == pytest.approx(problem.base_path.duration, abs=1e-3)
