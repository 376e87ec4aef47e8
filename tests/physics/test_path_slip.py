"""simulate's "the path slides" flag is the plan's turn verdict on the controller's reference.

A 90 deg pivot in one second (the reference as the controller gets it: the control point
0.2 m ahead of B's origin, the arm stowed) on the ramp tilted to 20 deg slides by the plan's
turn verdict (:func:`mmstab.runs.verdict.turn_slip`) and is flagged over exactly that turn's
samples; on level ground, and driven straight on the slope, nothing is flagged.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import yaml

from mmstab.control.layout import StepReference
from mmstab.core.problem import problem_from_dict
from mmstab.physics.loop_checks import predicted_path_slip
from mmstab.runs.verdict import TurnCheck, turn_slip

ROOT = Path(__file__).resolve().parents[2]
DT, OFFSET, EVERY, WINDOW, DISTANCE = 0.004, 0.2, 25, 1.0, 0.05


def _problem(slope: float):
    data = yaml.safe_load((ROOT / "problems" / "ramp.yaml").read_text())
    data = copy.deepcopy(data)
    data["terrain"]["slope"] = slope
    return problem_from_dict(data, ROOT / "problems" / "ramp.yaml")


def _reference(robot, turn: float) -> np.ndarray:
    """Still 1 s, a pivot of ``turn`` [rad] in 1 s, still 1 s (B's origin at (0, 0))."""
    t = np.arange(int(round(3.0 / DT))) * DT
    heading = turn * np.clip(t - 1.0, 0.0, 1.0)
    rate = np.where((t >= 1.0) & (t < 2.0), turn, 0.0)
    n, arm = len(t), len(robot.stowed)
    xi = np.zeros((n, 6))
    xi[:, 0], xi[:, 1], xi[:, 2] = OFFSET * np.cos(heading), OFFSET * np.sin(heading), heading
    xi_dot = np.zeros((n, 6))
    xi_dot[:, 0], xi_dot[:, 1] = -OFFSET * rate * np.sin(heading), OFFSET * rate * np.cos(heading)
    xi_dot[:, 2] = rate
    q = np.broadcast_to(robot.stowed, (n, arm))
    return StepReference(xi, xi_dot, q, np.zeros((n, arm)), np.zeros((n, 3))).pack()


def _flags(problem, ref: np.ndarray) -> np.ndarray:
    return predicted_path_slip(problem, ref, DT, OFFSET, WINDOW, DISTANCE, every=EVERY)


def test_a_sliding_pivot_is_flagged_over_the_plans_sliding_turn() -> None:
    slope = _problem(np.radians(20.0))
    ref = _reference(slope.robot, np.pi / 2)
    flags = _flags(slope, ref)
    # the plan's verdict on the same poses, times and arm
    idx = np.arange(0, len(ref), EVERY)
    r = StepReference.unpack(ref)
    xi = np.asarray(r.xi_des)[idx]
    poses = np.c_[xi[:, 0] - OFFSET * np.cos(xi[:, 2]), xi[:, 1] - OFFSET * np.sin(xi[:, 2]),
                  xi[:, 2]]  # fmt: skip
    np.testing.assert_allclose(poses[:, :2], 0.0, atol=1e-12)  # a pivot about B's origin
    arm = np.atleast_2d(slope.robot.arm_com(np.asarray(r.q_ref)[idx]))
    check = TurnCheck(slope.robot, arm, idx * DT, DISTANCE, WINDOW)
    turns = turn_slip(slope.terrain, poses, check)["sliding_turns"]
    assert len(turns) == 1 and turns[0]["slide_in_window_m"] > DISTANCE
    expected = np.zeros(len(idx), bool)
    expected[turns[0]["first"] : turns[0]["last"] + 1] = True
    np.testing.assert_array_equal(flags, np.repeat(expected, EVERY)[: len(ref)])
    # within the pivot's second (and the window after it), not while standing before it
    assert flags.any() and not flags[: int(1.0 / DT)].any()


def test_level_ground_and_a_straight_drive_are_not_flagged() -> None:
    level = _problem(0.0)
    assert not _flags(level, _reference(level.robot, np.pi / 2)).any()
    slope = _problem(np.radians(20.0))
    assert not _flags(slope, _reference(slope.robot, 0.0)).any()
