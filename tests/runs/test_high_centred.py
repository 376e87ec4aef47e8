"""Where a path high-centres the robot (mmstab.runs.high_centred)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

from mmstab.core.problem import load_problem
from mmstab.runs.high_centred import high_centred_verdict, path_samples
from mmstab.terrain import Heightmap, HeightmapTerrain, Ramp


def block_field(height: float) -> Heightmap:
    """A level 4 m x 2 m field with a 12 cm x 20 cm block of ``height`` [m] at x 0.2-0.4 m,
    |y| <= 6 cm: between the tracks (their inner edges 16 cm off the centre line)."""
    x = np.arange(-2.0, 2.0 + 1e-9, 0.02)
    y = np.arange(-1.0, 1.0 + 1e-9, 0.02)
    X, Y = np.meshgrid(x, y)
    block = (X >= 0.2 - 1e-9) & (X <= 0.4 + 1e-9) & (np.abs(Y) <= 0.06 + 1e-9)
    return Heightmap.build(np.where(block, height, 0.0), 0.02, (-2.0, -1.0))


def test_a_block_between_the_tracks_high_centres_only_where_it_lies(robot):
    # 10 cm: higher than the chassis's 5 cm clearance; the robot drives along x over it
    terrain = HeightmapTerrain(block_field(0.10)).with_robot(robot)
    s = np.arange(0.0, 2.41, 0.05)
    poses = np.c_[s - 1.2, np.zeros_like(s), np.zeros_like(s)]
    v = high_centred_verdict(terrain, poses, s)
    assert v["high_centred"] and v["samples"] == len(s)
    (stretch,) = v["stretches"]
    # the chassis (0.70 m long, centred on B) is over the block for body x in 0.2 - 0.35 ..
    # 0.4 + 0.35 m, i.e. s in 1.05 .. 1.95 m (samples 5 cm apart)
    assert stretch["start_s"] == pytest.approx(1.05, abs=0.051)
    assert stretch["end_s"] == pytest.approx(1.95, abs=0.051)
    low = HeightmapTerrain(block_field(0.03)).with_robot(robot)  # under the 5 cm clearance
    assert not high_centred_verdict(low, poses, s)["high_centred"]


def test_a_plane_never_high_centres(robot):
    poses = np.c_[np.linspace(-1, 1, 9), np.zeros(9), np.linspace(0, 3, 9)]
    v = high_centred_verdict(Ramp(0.3), poses, np.linspace(0, 2, 9))
    assert not v["high_centred"] and v["stretches"] == []


@pytest.mark.mujoco
def test_the_dem_lap_high_centres_where_mujoco_stalls():
    """``dem.yaml``: MuJoCo's robot stops dead at (1.47, -0.38) m, its chassis on the ditch's
    edge (docs/physics.md): the rested path says so there."""
    problem = load_problem(ROOT / "problems" / "dem.yaml")
    poses, s = path_samples(problem.base_path)
    assert len(poses) == len(s) and s[1] - s[0] == pytest.approx(0.05, abs=2e-3)
    v = high_centred_verdict(problem.terrain, poses, s)
    stall = np.argmin(np.linalg.norm(poses[:, :2] - [1.47, -0.38], axis=1))
    assert any(x["start_s"] <= s[stall] <= x["end_s"] for x in v["stretches"])
