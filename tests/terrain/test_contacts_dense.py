"""Contacts where the physics has them: a dense check of the belts and the
chassis underside at rest on seeded rough ground, against the 5 cm candidates."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROBOT_YAML

from mmstab.model.robot import load_robot
from mmstab.terrain.contacts import contact_candidates, track_profile
from mmstab.terrain.generators import generate
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

#: Seeded rough ground with a kerb and a ditch (rough.yaml's kinds, a smaller map).
ROUGH = {
    "kind": "rough", "size": [8.0, 8.0], "resolution": 0.05, "amplitude": 0.03,
    "correlation_length": 0.4, "hill_height": 0.2, "hill_radius": 1.5, "slope": 0.3,
    "azimuth": 1.2,
    "features": {
        "ditch": {"depth": 0.12, "width": 0.3, "distance": -1.5, "azimuth": 0.0},
        "kerb": {"height": 0.10, "distance": 1.5, "azimuth": 0.3},
    },
}  # fmt: skip


def dense_base(robot, step: float = 0.005):
    """The whole belt (5 mm along, 21 rows across, 1 deg on the arcs) and the underside."""
    t, body = robot.base.tracks, robot.base.body
    prof = track_profile(t.length, t.height, step, np.radians(1.0))
    belt = np.concatenate(
        [
            np.c_[prof[:, 0], np.full(len(prof), y), prof[:, 1]]
            for yc in (t.separation / 2, -t.separation / 2)
            for y in np.linspace(yc - t.width / 2, yc + t.width / 2, 21)
        ]
    )
    xs = body.center[0] + np.linspace(-0.5, 0.5, 141) * body.size[0]
    ys = body.center[1] + np.linspace(-0.5, 0.5, 65) * body.size[1]
    X, Y = np.meshgrid(xs, ys)
    under = np.c_[X.ravel(), Y.ravel(), np.full(X.size, body.center[2] - body.size[2] / 2)]
    return belt, under


def penetration(terrain, T, pts):
    """Reach of the ground above body points placed at T, per point [m] (> 0: into it)."""
    G = pts @ T[:3, :3].T + T[:3, 3]
    return terrain.heightmap.height(G[:, :2]) - G[:, 2]


def test_candidates_are_at_most_5_cm_apart_on_the_belts():
    robot = load_robot(ROBOT_YAML)
    c = contact_candidates(robot.base)
    flat = c.points[c.compliant]
    for yc in (0.21, -0.21):
        rows = flat[np.abs(flat[:, 1] - yc) <= 0.05 + 1e-12]
        assert np.diff(np.unique(np.round(rows[:, 1], 12))).max() <= 0.05 + 1e-12
        assert np.diff(np.unique(np.round(rows[:, 0], 12))).max() <= 0.05 + 1e-12


@pytest.mark.parametrize("seed", [11, 12])
def test_belt_and_underside_against_a_dense_check(seed):
    """Between the samples the belts' flat runs sink at most the tracks' compliance (2 cm)
    and the whole belt a few mm at most poses (a kerb's sharp edge between two rows of an
    end arc reaches 2 cm: docs/terrain.md); the underside reaches into the ground only where
    the pose is flagged high-centred, or by at most 5 mm."""
    robot = load_robot(ROBOT_YAML)
    terrain = HeightmapTerrain(generate({**ROUGH, "seed": seed})).with_robot(robot)
    rng = np.random.default_rng(seed)
    poses = np.c_[rng.uniform(-3, 3, (300, 2)), rng.uniform(-np.pi, np.pi, 300)]
    r = terrain.rest(poses, strict=False)
    belt, under = dense_base(robot)
    ok = np.flatnonzero(np.isfinite(r.z) & r.converged & ~r.tips_over)
    assert ok.size > 250
    flat = belt[:, 2] == 0
    belt_pen = np.array([penetration(terrain, r.G_T_B[i], belt) for i in ok])
    under_pen = np.array([penetration(terrain, r.G_T_B[i], under).max() for i in ok])
    assert belt_pen[:, flat].max() <= terrain.settings.compliance  # the suspension's travel
    worst = belt_pen.max(axis=1)
    assert np.median(worst) < 0.003 and np.percentile(worst, 95) < 0.006
    # unflagged, the underside reaches at most 5 mm in: a bump's top between its 5 cm
    # samples (before the inner grid: 15 mm at three of these poses, none flagged)
    assert not np.any((under_pen > 0.005) & ~r.high_centred[ok])
