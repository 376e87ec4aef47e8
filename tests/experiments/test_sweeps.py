"""Fig. 5 / Fig. 6 experiments as subprocesses, and their numbers against a recomputation."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
from conftest import RAMP_YAML, ROOT

from experiments.common import circular_extrema
from mmstab.stability.static import robot_force_angle


def _run(*args: str) -> None:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    subprocess.run(
        [sys.executable, "-m", "experiments", *args],
        check=True,
        env=env,
        cwd=ROOT,
        capture_output=True,
    )


def test_circular_extrema():
    v = np.array([0, 1, 2, 1, 0, 1, 3, 3, 1])
    maxima, minima = circular_extrema(v)
    assert list(maxima) == [2, 6] and list(minima) == [0, 4]


def test_fig5_reproduces_two_unequal_maxima_on_the_lifted_side(tmp_path, problem):
    _run("fig5", str(RAMP_YAML), "-o", str(tmp_path))
    s = json.loads((tmp_path / "summary.json").read_text())
    assert (tmp_path / "fig5.png").stat().st_size > 10_000
    link0, mu = np.array(s["link0"]), np.array(s["mu"])
    assert len(link0) == problem.section("sweep")["samples"]
    # recompute one sample independently
    q = np.array([link0[7], 0, 0, 0])
    g = problem.terrain.gravity_body(s["pose"])
    assert mu[7] == robot_force_angle(problem.robot, g, problem.robot.arm_com(q)).mu[0]
    # roll lifts the left side (+y_B), so both maxima point the arm left: 0 < link0 < pi
    maxima = np.array(s["local_maxima_rad"])
    assert len(maxima) == 2 and np.all((maxima > 0) & (maxima < np.pi))
    assert maxima[0] < np.pi / 2 < maxima[1]  # one toward the front, one toward the rear
    assert s["local_maxima_mu"][0] != s["local_maxima_mu"][1]
    assert s["roll_rad"] > 0 and abs(s["pitch_rad"]) < 1e-12
    assert min(mu) > 0 and max(mu) > s["mu_arm_removed"]
    # the stretched arm passes through the raised flippers (front-left/right sectors),
    # but neither maximum is such a posture
    colliding = np.array(s["colliding_link0_rad"])
    assert len(colliding) > 0 and not np.isin(maxima, colliding).any()
    assert np.all((colliding < np.pi / 2) | (colliding > 3 * np.pi / 2))


def test_fig6_one_curve_per_pose(tmp_path, problem):
    _run("fig6", str(RAMP_YAML), "-o", str(tmp_path))
    s = json.loads((tmp_path / "summary.json").read_text())
    assert len(s["poses"]) == problem.section("sweep")["poses"] == 11
    for p in s["poses"]:
        assert len(p["local_maxima_rad"]) >= 1 and len(p["local_minima_rad"]) >= 1
        assert p["mu_min"] > 0
    assert s["poses_with_two_maxima"] >= 6
    assert (tmp_path / "problem.yaml").exists() and (tmp_path / "fig6.png").exists()
    assert (tmp_path / "fig6_poses3d.png").stat().st_size > 10_000  # Fig. 6(a) in 3-D


def test_two_maxima_need_a_mild_roll(robot):
    """docs/stability.md: 0.1 rad of roll gives the paper's two maxima; from 0.15 rad, one."""
    from experiments.sweeps import link0_sweep
    from mmstab.terrain import Ramp

    counts = {}
    for roll in (0.1, 0.15, 0.2, 0.3):
        sw = link0_sweep(robot, Ramp(roll), np.zeros((1, 3)), 100)
        maxima, _ = circular_extrema(sw.mu[0])
        counts[roll] = len(maxima)
        if len(maxima) == 1:  # the single maximum points the arm straight uphill (+y_B)
            assert abs(sw.link0[maxima[0]] - np.pi / 2) < 2 * np.pi / 100
    assert counts == {0.1: 2, 0.15: 1, 0.2: 1, 0.3: 1}
