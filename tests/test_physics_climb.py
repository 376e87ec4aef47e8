"""The kerb in MuJoCo: the whole robot driven at a constant track speed onto a 10 cm step.

The tracks' flat run ends in wheels of radius 0.11 m (``tracks.height / 2``): at a 10 cm
kerb the front wheel meets the kerb's edge 1 cm below its axle, its contact normal 5° off
horizontal, and the step is climbed only when the rear wheels push the front up the
edge, which friction (0.7) allows only with enough of the weight on the rear. These runs
hold what ``docs/physics.md`` ("The kerb") reports: no posture climbs at a crawl (no
momentum), the stowed arm (57 % of the weight on the front half) and the arm turned back
(42 %) climb at 0.2 m/s, the arm stretched ahead and low (64 %: the planner's most stable
posture when the nose pitches up on the kerb) does not even at 0.5 m/s.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import mmstab

pytest.importorskip("mujoco")

from mmstab.physics.robot_sim import RobotSim  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
AHEAD = np.array([0.0, -0.3, 0.24, 2.2])  # the arm stretched ahead, 10 cm above the plane
BACK = np.array([3.14, -0.3, 0.24, 2.2])  # the same, turned to the rear


@pytest.fixture(scope="module")
def kerb() -> mmstab.Problem:
    return mmstab.load_problem(ROOT / "problems" / "kerb.yaml")


def _drive(problem: mmstab.Problem, q: np.ndarray, speed: float, seconds: float) -> float:
    """Body x [m] after driving at ``speed`` [m/s] from x = -0.2 m (the kerb's face at 0.49)."""
    sim = RobotSim(problem.robot, problem.terrain, pose=(-0.2, 0.0, 0.0), arm_q=q)
    sim.step((0.0, 0.0), q, 0.5)
    sim.step((speed, speed), q, seconds)
    return float(sim.data.xpos[sim.base][0])


def test_front_load_of_the_postures(kerb) -> None:
    robot = kerb.robot

    def front_share(q: np.ndarray) -> float:  # of the weight, on a level flat run
        com = robot.overall_com(robot.arm_com(q))
        return 0.5 + float(com[0]) / robot.base.tracks.length

    assert front_share(robot.stowed) == pytest.approx(0.569, abs=1e-3)
    assert front_share(AHEAD) == pytest.approx(0.638, abs=1e-3)
    assert front_share(BACK) == pytest.approx(0.424, abs=1e-3)


def test_the_stowed_arm_climbs_with_momentum_the_arm_ahead_does_not(kerb) -> None:
    # the front wheel stops at the face at x = 0.042 m (its rim 0.11 m ahead of its axle)
    assert _drive(kerb, kerb.robot.stowed, 0.05, 6.0) < 0.1  # a crawl: stuck at the face
    assert _drive(kerb, kerb.robot.stowed, 0.2, 6.0) > 0.6  # over the kerb
    assert _drive(kerb, BACK, 0.2, 6.0) > 0.6
    assert _drive(kerb, AHEAD, 0.5, 6.0) < 0.1  # stuck, its tracks spinning
