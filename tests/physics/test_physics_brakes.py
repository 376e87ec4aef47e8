"""A braked rigid robot on a slope in MuJoCo: it holds up to atan(friction).

Facing uphill the friction load runs along the tracks, through the wheels' hinges, which
only their velocity servos hold. With the ``implicitfast`` integrator MuJoCo solves the
contacts without the servos' damping (it acts in the velocity update after the solve): the
rigid row of wheels hops, the total normal force swinging between 0 and several times the
weight's normal part, and the robot slides below atan(mu). The ``discrete`` integrator
solves the contacts with that damping (``ModelSettings.integrator``; docs/verdicts.md,
"Verdicts against MuJoCo"). ``pytest -s`` prints the numbers.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import PROBLEMS

pytestmark = pytest.mark.mujoco
mujoco = pytest.importorskip("mujoco")

from experiments.verdicts import load_settings, sim_settings  # noqa: E402
from mmstab.model.robot import load_robot  # noqa: E402
from mmstab.physics.robot_model import ModelSettings  # noqa: E402
from mmstab.physics.robot_sim import RobotSim  # noqa: E402
from mmstab.physics.verdict_sim import (  # noqa: E402
    SimSettings,
    Thresholds,
    planar_ground,
    sim_verdict,
)
from mmstab.terrain.base import GRAVITY_G  # noqa: E402

FRICTION = 0.7
#: The verdict grid's rigid model (problems/verdicts.yaml): stiff brakes, no suspension,
#: the discrete integrator; and the same on implicitfast.
RIGID = sim_settings(load_settings(PROBLEMS / "verdicts.yaml"))["rigid"].model
IMPLICITFAST = dataclasses.replace(RIGID, integrator="implicitfast")


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


def test_integrator_setting(cameleon):
    """The default is ``discrete`` (contacts see the brakes); the setting reaches the model."""
    assert ModelSettings().integrator == "discrete" and RIGID.integrator == "discrete"
    assert RIGID.suspension_deflection == 0.0 and RIGID.track_kv == 2.0e5
    default = RobotSim(cameleon, settings=IMPLICITFAST).model.opt.integrator
    assert default == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert RobotSim(cameleon, settings=RIGID).model.opt.integrator == (
        mujoco.mjtIntegrator.mjINT_DISCRETE
    )


def test_rigid_wheels_hop_unless_the_contacts_see_the_brakes(cameleon):
    """0.5 deg below atan(mu), facing uphill: implicitfast hops, discrete stands."""
    slope = np.arctan(FRICTION) - np.radians(0.5)
    weight = cameleon.total_mass * np.linalg.norm(GRAVITY_G) * np.cos(slope)
    hops = normal_forces(cameleon, IMPLICITFAST, slope, 0.5 * np.pi)
    stands = normal_forces(cameleon, RIGID, slope, 0.5 * np.pi)
    print(
        f"\nMEASURED normal force facing uphill at {np.degrees(slope):.2f} deg (weight's "
        f"normal part {weight:.1f} N): implicitfast {hops.min():.1f}..{hops.max():.1f} N, "
        f"discrete {stands.min():.1f}..{stands.max():.1f} N"
    )
    assert hops.min() < 0.1 * weight and hops.max() > 2.0 * weight
    assert np.all(np.abs(stands - weight) < 0.01 * weight)


CASES = [(90.0, 0.0), (0.0, 0.0), (90.0, 0.05)]  # (heading [deg], track speed [m/s])


@pytest.mark.parametrize("heading_deg, speed", CASES, ids=["uphill", "across", "driven"])
def test_rigid_robot_slides_at_the_friction_angle(cameleon, heading_deg, speed):
    """Holds 1 deg below atan(mu), slides 1 deg above: braked facing uphill or across,
    and driven uphill at 0.05 m/s (the speed ramping up over 1 s)."""
    sim = SimSettings(model=RIGID)
    thresholds = Thresholds(tip_deg=10.0, slide_m=0.10)
    verdicts = {}
    for offset in (-1.0, 1.0):
        slope = np.arctan(FRICTION) + np.radians(offset)
        verdicts[offset] = sim_verdict(
            cameleon, None, cameleon.stowed, slope, np.radians(heading_deg), FRICTION, speed,
            sim, thresholds,
        )  # fmt: skip
    print(f"\nMEASURED heading {heading_deg:.0f}, speed {speed}: {verdicts}")
    assert verdicts[-1.0].verdict == "holds" and verdicts[-1.0].slip_m < 0.005
    assert verdicts[-1.0].tilt_deg < 1.0
    assert verdicts[1.0].verdict == "slides"
