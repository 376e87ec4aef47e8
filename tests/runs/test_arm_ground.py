"""The arm against the ground where the body see-saws over a crest (mmstab.runs.arm_ground).

A roof ridge across the path, ``z = -k |x|``: a rigid base straddling it lies along the
slope its CoM is over (its bottom run along ``z = -k x`` on the far side, or ``z = k x``
on the near side), so between the samples either side of the CoM's crossing its rest turns
by ``2 atan(k)`` (a flip). Turned over the ridge (its weakest support edge) the base is
caught when its front meets the far slope: ``2 atan(k)`` again, the far side's rest.
"""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.runs.arm_ground import FLIP, ArmGround, arm_ground_along, arm_ground_verdict
from mmstab.stability.rock import STEP
from mmstab.terrain import HeightmapTerrain
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.rest import RestSettings

K = 0.1  # the ridge's slopes [-]: the rest flips by 2 atan(0.1) = 0.199 rad


def ridge(robot) -> HeightmapTerrain:
    res = 0.01
    x = np.arange(-1.5, 1.5 + 1e-9, res)
    X, _ = np.meshgrid(x, x)
    hm = Heightmap.build(-K * np.abs(X), res, [x[0], x[0]], "ridge")
    return HeightmapTerrain(hm, settings=RestSettings(compliance=0.0)).with_robot(robot)


def test_the_rest_flips_over_a_ridge_and_rocks_onto_the_far_slope(robot):
    terrain = ridge(robot)
    x = np.arange(-0.30, 0.301, 0.05)
    poses = np.c_[x, np.zeros_like(x), np.zeros_like(x)]
    q = np.broadcast_to(robot.stowed, (len(x), len(robot.stowed)))
    arm = arm_ground_along(robot, terrain, poses, q, FLIP)
    flip = 2 * np.arctan(K)
    # one pair of neighbours flips, by 2 atan(k); elsewhere the rest lies on one slope
    big = np.flatnonzero(arm.flip > FLIP)
    assert len(big) == 2 and big[1] == big[0] + 1, arm.flip
    assert arm.flip[big] == pytest.approx(flip, abs=0.01)
    assert np.delete(arm.flip, big).max() < 0.01
    # turned over the ridge: caught on the far slope, 2 atan(k) later (the near side's
    # sample; the far side's is turned back to the near slope)
    assert np.isfinite(arm.turn[big]).all()
    assert arm.turn[big] == pytest.approx(flip, abs=2 * STEP + 0.01)
    assert np.isnan(arm.rocked[np.delete(np.arange(len(x)), big)]).all()
    # the stowed arm stays above the ground at both attitudes
    assert np.nanmin(arm.height) > 0.05


def test_a_contact_is_where_the_arm_is_below_the_ground():
    s = np.arange(6) * 0.05
    rest = np.array([0.10, 0.08, 0.06, 0.07, 0.09, 0.10])
    rocked = np.array([np.nan, -0.01, -0.02, 0.03, np.nan, np.nan])
    turn = np.array([np.nan, 0.2, 0.3, 0.25, np.nan, np.nan])
    v = arm_ground_verdict(ArmGround(rest, rocked, turn, np.full(6, 0.1)), s, FLIP)
    assert v["contact"] and v["flips"] == 6 and v["rocked_samples"] == 3
    assert v["height_min_m"] == 0.06 and v["rocked_height_min_m"] == -0.02
    (x,) = v["stretches"]
    assert (x["start_s"], x["end_s"], x["at_s"]) == (0.05, 0.10, 0.10)
    assert x["worst"] == -0.02 and x["by"] == 0.02
    assert x["attitude"] == "rocked" and x["turn_rad"] == 0.3
