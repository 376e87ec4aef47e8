"""The tracks' belts in MuJoCo (``ModelSettings.track_belt``, issue 25).

A braked rigid robot must hold up to atan(friction) with the friction load along its
tracks as it does across them. With each road wheel spinning on its own the rigid row of
wheels hops under a load along the track (the normal force swings between 0 and several
times the weight's share); tied together as the belt does, it stands still
(docs/physics.md, "Every disagreement, why"). ``pytest -s`` prints the numbers.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import PROBLEMS

mujoco = pytest.importorskip("mujoco")

from mmstab.model.robot import load_robot  # noqa: E402
from mmstab.physics.robot_model import ModelSettings, track_wheels  # noqa: E402
from mmstab.physics.robot_sim import RobotSim  # noqa: E402
from mmstab.physics.verdict_sim import (  # noqa: E402
    SimSettings,
    Thresholds,
    planar_ground,
    sim_verdict,
)
from mmstab.terrain.base import GRAVITY_G  # noqa: E402

FRICTION = 0.7
#: The verdict grid's rigid model (problems/verdicts.yaml): stiff brakes, no suspension.
RIGID = ModelSettings(suspension_deflection=0.0, track_kv=2.0e5)
BELTED = ModelSettings(suspension_deflection=0.0, track_kv=2.0e5, track_belt=True)


@pytest.fixture(scope="module")
def cameleon():
    return load_robot(PROBLEMS / "robots" / "cameleon.yaml")


def normal_forces(robot, settings, slope, heading, hold=0.5):
    """Total contact normal force [N] at every step of ``hold`` [s] after settling."""
    sim = RobotSim(
        robot, planar_ground(slope, FRICTION), pose=(0.0, 0.0, heading), settings=settings
    )
    sim.settle(1.0)
    m, d, f6, out = sim.model, sim.data, np.zeros(6), []
    for _ in range(int(round(hold / m.opt.timestep))):
        sim.step((0.0, 0.0), None, m.opt.timestep)
        total = 0.0
        for i in range(d.ncon):
            mujoco.mj_contactForce(m, d, i, f6)
            total += f6[0]
        out.append(total)
    return np.array(out)


def test_belt_ties_each_sides_wheels(cameleon):
    """Equalities only when asked; with them a side's wheels turn as one while driving."""
    n = len(track_wheels(cameleon, BELTED).x)
    assert RobotSim(cameleon, settings=RIGID).model.neq == 0
    sim = RobotSim(cameleon, settings=BELTED)
    assert sim.model.neq == 2 * (n - 1)
    sim.step((0.3, -0.2), None, 1.0)  # a skid turn: the belts at different speeds
    m = sim.model
    for side, speed in (("left", 0.3), ("right", -0.2)):
        names = [f"wheel_{side}_{k:02d}" for k in range(n)]
        q = np.array([sim.data.qpos[m.jnt_qposadr[m.joint(j).id]] for j in names])
        r = cameleon.base.tracks.height / 2
        assert np.ptp(q) < 1e-3  # [rad]: 0.1 mm of belt
        assert q[0] * r == pytest.approx(speed * 1.0, rel=0.05)  # the belt's travel [m]


def test_rigid_wheels_hop_under_a_load_along_the_tracks(cameleon):
    """The artefact the belt removes: 0.5 deg below atan(mu), facing uphill."""
    slope = np.arctan(FRICTION) - np.radians(0.5)
    weight = cameleon.total_mass * np.linalg.norm(GRAVITY_G) * np.cos(slope)
    loose = normal_forces(cameleon, RIGID, slope, 0.5 * np.pi)
    belted = normal_forces(cameleon, BELTED, slope, 0.5 * np.pi)
    print(
        f"\nMEASURED normal force facing uphill at {np.degrees(slope):.2f} deg (weight's "
        f"normal part {weight:.1f} N): wheels alone {loose.min():.1f}..{loose.max():.1f} N, "
        f"belted {belted.min():.1f}..{belted.max():.1f} N"
    )
    assert loose.min() < 0.1 * weight and loose.max() > 2.0 * weight
    assert np.all(np.abs(belted - weight) < 0.01 * weight)


@pytest.mark.parametrize("heading_deg", [90.0, 0.0], ids=["uphill", "across"])
def test_braked_belted_robot_slides_at_the_friction_angle(cameleon, heading_deg):
    """Holds 1 deg below atan(mu), slides 1 deg above, facing uphill as across."""
    sim = SimSettings(model=BELTED)
    thresholds = Thresholds(tip_deg=10.0, slide_m=0.10)
    verdicts = {}
    for offset in (-1.0, 1.0):
        slope = np.arctan(FRICTION) + np.radians(offset)
        verdicts[offset] = sim_verdict(
            cameleon, None, cameleon.stowed, slope, np.radians(heading_deg), FRICTION, 0.0,
            sim, thresholds,
        )  # fmt: skip
    print(f"\nMEASURED heading {heading_deg:.0f}: {verdicts}")
    assert verdicts[-1.0].verdict == "holds" and verdicts[-1.0].slip_m < 0.005
    assert verdicts[-1.0].tilt_deg < 1.0
    assert verdicts[1.0].verdict == "slides"
