"""python -m experiments fidelity: numbers from saved results, on a hand-made results tree."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import RAMP_YAML

from experiments.fidelity import below_intervals, fig6_fidelity, fig8_fidelity


def test_below_intervals_by_hand():
    t = np.arange(8) * 0.5
    value = np.array([5, 1, 2, 5, 5, 0, 5, 3.0])
    floor = np.full(8, 4.0)
    got = below_intervals(t, value, floor)
    assert got == [
        {"start_s": 0.5, "end_s": 1.0, "max_deficit": 3.0},
        {"start_s": 2.5, "end_s": 2.5, "max_deficit": 4.0},
        {"start_s": 3.5, "end_s": 3.5, "max_deficit": 1.0},
    ]
    assert below_intervals(t, floor + 1, floor) == []


def test_fig6_counts_and_nearness():
    summary = {
        "maxima_per_pose": [2, 3, 2],
        "poses": [
            {"local_maxima_rad": [2.1, 4.8]},  # both near the paper's 2.0 and 5.0
            {"local_maxima_rad": [0.8, 2.4, 5.6]},  # 2.4 and 5.6 are 0.4 and 0.6 away
            {"local_maxima_rad": [6.2, 1.9]},  # 6.2 is 1.2 from 5.0: not near
        ],
    }
    f = fig6_fidelity(summary)
    assert (f["poses_with_two_maxima"], f["poses_with_three_maxima"]) == (2, 1)
    assert f["poses_with_maxima_near_paper"] == 1


def test_fig8_sides_against_the_paper():
    sides = ["left"] * 4 + ["right"] * 4 + ["left"] * 2  # the paper's pattern, mirrored
    poses = [{"side": s, "front": k < 3} for k, s in enumerate(sides)]
    f = fig8_fidelity({"poses": poses})
    assert (f["sides_as_paper"], f["sides_as_paper_mirrored"]) == (0, 10)
    assert (f["poses_in_front"], f["side_switches"]) == (3, 2)


def _results_tree(root):
    (root / "fig6").mkdir(parents=True)
    (root / "fig8").mkdir()
    (root / "tracking").mkdir()
    (root / "fig6" / "summary.json").write_text(
        json.dumps({"maxima_per_pose": [2], "poses": [{"local_maxima_rad": [2.0, 5.0]}]})
    )
    (root / "fig8" / "summary.json").write_text(
        json.dumps({"poses": [{"side": "left", "front": False}], "settings": {}})
    )
    limit = 4 * np.pi
    joints = ["track_left", "link0"]
    (root / "tracking" / "summary.json").write_text(
        json.dumps(
            {
                "qdot_max_abs": {"track_left": 3.0, "link0": limit},
                "qdot_limit": dict.fromkeys(joints, limit),
                "saturated_steps": {"track_left": 0, "link0": 7},
                "last_saturated_time_s": 0.08,
            }
        )
    )
    problem = yaml.safe_load(RAMP_YAML.read_text())
    (root / "tracking" / "problem.yaml").write_text(yaml.safe_dump(problem))
    t = np.linspace(0.0, 1.0, 11)
    stowed = np.full(11, 500.0)
    mu = np.where((t > 0.25) & (t < 0.45), 490.0, 520.0)
    np.savez(
        root / "tracking" / "run.npz",
        t=t,
        mu_reconfigured=mu,
        mu_stowed=stowed,
        mu_arm_removed=stowed - 20,
    )


def test_fidelity_command_on_a_results_tree(tmp_path):
    _results_tree(tmp_path / "res")
    env = {**os.environ, "MPLBACKEND": "Agg"}
    out = tmp_path / "fid"
    cmd = [
        sys.executable,
        "-m",
        "experiments",
        "fidelity",
        str(RAMP_YAML),
        "--results",
        str(tmp_path / "res"),
        "-o",
        str(out),
    ]
    subprocess.run(cmd, check=True, env=env, capture_output=True)
    s = json.loads((out / "summary.json").read_text())
    assert s["fig6"]["poses_with_maxima_near_paper"] == 1
    assert s["fig11"]["saturates"] is True
    assert s["fig11"]["peak_over_limit"]["link0"] == pytest.approx(1.0)
    assert s["fig11"]["approach_time_s"] == 1.0
    [below] = s["fig12"]["below_stowed"]
    assert (below["start_s"], below["end_s"], below["max_deficit"]) == pytest.approx(
        (0.3, 0.4, 10.0)
    )
    assert s["fig12"]["below_arm_removed"] == []


def test_fidelity_missing_result_is_one_line_exit_2(tmp_path):
    _results_tree(tmp_path / "res")
    (tmp_path / "res" / "tracking" / "run.npz").unlink()
    cmd = [
        sys.executable,
        "-m",
        "experiments",
        "fidelity",
        str(RAMP_YAML),
        "--results",
        str(tmp_path / "res"),
        "-o",
        str(tmp_path / "fid"),
    ]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "run.npz is missing" in r.stderr
    assert "make tracking" in r.stderr
    assert not (tmp_path / "fid" / "summary.json").exists()
