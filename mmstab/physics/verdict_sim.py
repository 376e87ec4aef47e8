"""MuJoCo's verdict on one static or slowly driven case: tips, holds or slides.

A case is the whole robot (:class:`~mmstab.physics.robot_sim.RobotSim`) on a ramp of a
given slope and friction, at a heading, with an arm posture and a payload. It is set down
quasi-statically (:meth:`RobotSim.settle`: gravity turned from the ground normal to
vertical), then held for ``hold`` seconds with the arm servoed at the posture and the
tracks braked (speed 0) or driven slowly straight ahead (the speed ramped up over
``ramp``). Every ``sample`` seconds the run records

- the tilt of z_B off the plane's normal [deg] (tipping lifts one side or end off it),
- the slip: how far B's origin moved down the slope, in the plane, beyond what the belts'
  own motion explains (the tracks' travel relative to the chassis, from the wheel angles):
  the tracks' sliding over the ground [m]. A braked track is a velocity servo and creeps
  under load (the load over ``kv``); a driven one moves the robot: neither is a slide,
- whether an arm body touches the ground.

:func:`classify` turns that into the verdict: ``tips`` if the tilt passes
``Thresholds.tip_deg``, ``slides`` if the slip passes ``Thresholds.slide_m``, whichever
comes first; else ``holds``. The thresholds and why they are where they are:
``docs/verdicts.md``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.payload import Payload
from mmstab.model.robot import FloatArray, Robot
from mmstab.physics.robot_model import ModelSettings
from mmstab.physics.robot_sim import RobotSim, RobotState
from mmstab.terrain.base import Terrain
from mmstab.terrain.factory import planar_terrain

VERDICTS = ("holds", "slides", "tips")


class Thresholds(NamedTuple):
    """When a simulated case counts as tipped or slid.

    Attributes:
        tip_deg: tilt of z_B off the plane's normal beyond which it tips [deg].
        slide_m: slip down the slope beyond which it slides [m].
    """

    tip_deg: float = 10.0
    slide_m: float = 0.05


class SimSettings(NamedTuple):
    """Durations and drive of a simulated case.

    Attributes:
        settle: :meth:`RobotSim.settle` duration [s].
        hold: time held (braked or driven) after settling [s].
        sample: recording interval [s].
        ramp: time over which a driven case's track speed rises to ``speed``, updated every
            integration step [s].
        model: the MuJoCo model's numbers (e.g. ``suspension_deflection`` 0: rigid wheels).
    """

    settle: float = 1.0
    hold: float = 2.5
    sample: float = 0.05
    ramp: float = 1.0
    model: ModelSettings = ModelSettings()


class Trajectory(NamedTuple):
    """What one simulated case recorded, from the end of settling on.

    Attributes:
        time: sample times after settling (T,) [s].
        tilt_deg: tilt of z_B off the plane's normal (T,) [deg].
        slip_m: slip of B's origin down the slope beyond the commanded motion (T,) [m].
        arm_ground: an arm body touched the ground at the sample (T,).
    """

    time: FloatArray
    tilt_deg: FloatArray
    slip_m: FloatArray
    arm_ground: np.ndarray


class SimVerdict(NamedTuple):
    """MuJoCo's verdict on one case.

    Attributes:
        verdict: ``tips``, ``slides`` or ``holds``.
        time: when the deciding threshold was passed [s after settling] (the hold's end
            when it holds).
        tilt_deg: largest tilt off the plane recorded [deg].
        slip_m: largest slip down the slope recorded [m].
        arm_ground: an arm body touched the ground before the verdict.
    """

    verdict: str
    time: float
    tilt_deg: float
    slip_m: float
    arm_ground: bool


def planar_ground(angle: float, friction: float) -> Terrain:
    """The planar ramp of a case: slope ``angle`` [rad], Coulomb ``friction`` [-]."""
    return planar_terrain(angle, friction)


def first_crossing(time: FloatArray, values: FloatArray, threshold: float) -> float:
    """The first time [s] ``values`` exceed ``threshold`` (inf if never)."""
    over = np.flatnonzero(np.asarray(values) > threshold)
    return float(np.asarray(time)[over[0]]) if len(over) else float("inf")


def classify(trajectory: Trajectory, thresholds: Thresholds) -> SimVerdict:
    """The verdict of a recorded case: the first threshold passed, else ``holds``."""
    t = np.asarray(trajectory.time, dtype=float)
    t_tip = first_crossing(t, trajectory.tilt_deg, thresholds.tip_deg)
    t_slide = first_crossing(t, trajectory.slip_m, thresholds.slide_m)
    if np.isinf(t_tip) and np.isinf(t_slide):
        verdict, when = "holds", float(t[-1]) if len(t) else 0.0
    elif t_tip <= t_slide:
        verdict, when = "tips", t_tip
    else:
        verdict, when = "slides", t_slide
    before = t <= when
    return SimVerdict(
        verdict=verdict,
        time=when,
        tilt_deg=float(np.max(trajectory.tilt_deg, initial=0.0)),
        slip_m=float(np.max(trajectory.slip_m, initial=0.0)),
        arm_ground=bool(np.any(np.asarray(trajectory.arm_ground)[before])),
    )


def _arm_ground_contact(sim: RobotSim, arm_bodies: set[int], ground: int) -> bool:
    """Whether a contact joins an arm body's geom and the ground geom."""
    d, m = sim.data, sim.model
    for c in d.contact[: d.ncon]:
        g1, g2 = int(c.geom1), int(c.geom2)
        if ground in (g1, g2) and int(m.geom_bodyid[g2 if g1 == ground else g1]) in arm_bodies:
            return True
    return False


def _wheel_angles(sim: RobotSim) -> Callable[[], float]:
    """A reader of the wheels' mean hinge angle [rad] (their belts' common travel / r)."""
    m = sim.model
    names = [m.joint(j).name for j in range(m.njnt)]
    rows = [
        m.jnt_qposadr[j] for j, n in enumerate(names) if n.startswith("wheel_") and "_z" not in n
    ]
    adr = np.array(rows)
    return lambda: float(np.mean(sim.data.qpos[adr]))


def _drive(
    sim: RobotSim, q: FloatArray, speed: float, ramp: float, t0: float, duration: float, dt: float
) -> RobotState:
    """Advance ``duration`` [s] from ``t0`` [s], the track speed rising to ``speed`` [m/s].

    It rises linearly over ``ramp`` [s], the command updated every step ``dt`` [s].

    A stiff velocity servo turns a jump of its command into a large rim force: a jump of
    a few mm/s per sample saturates the contacts' friction along the track, which an
    elliptic cone takes from the friction across it (the robot slides sideways).
    """
    if speed == 0 or t0 >= ramp:
        return sim.step((speed, speed), q, duration)
    state = sim.state()
    for j in range(1, max(1, int(round(duration / dt))) + 1):
        v = speed * min(1.0, (t0 + j * dt) / ramp)
        state = sim.step((v, v), q, dt)
    return state


def simulate_case(
    robot: Robot,
    payload: Payload | None,
    posture: ArrayLike,
    slope: float,
    heading: float,
    friction: float,
    speed: float,
    settings: SimSettings,
    stop: Callable[[float, float], bool] | None = None,
) -> Trajectory:
    """Settle, then hold (``speed`` 0) or drive straight at ``speed`` [m/s]; record.

    Args:
        robot: the robot (without the payload).
        payload: at the wrist, or None.
        posture: arm joint angles held throughout (4,) [rad].
        slope: ramp slope [rad].
        heading: base heading on it [rad] (0: across, left side uphill).
        friction: Coulomb coefficient of every contact [-].
        speed: track speed after the ramp-up [m/s] (0: braked).
        settings: durations.
        stop: ``stop(tilt_deg, slip_m)`` ends the run early when true (a verdict is in).
    """
    ramp = planar_ground(slope, friction)
    q = np.asarray(posture, dtype=float)
    pose = (0.0, 0.0, heading)
    sim = RobotSim(robot, ramp, payload=payload, pose=pose, arm_q=q, settings=settings.model)
    m = sim.model
    ground = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "terrain")
    arm_bodies = {
        mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"arm_{link.name}") for link in robot.links
    }
    arm_bodies |= {int(b) for b in range(m.nbody) if int(m.body_parentid[b]) in arm_bodies}
    wheel_angle, radius = _wheel_angles(sim), robot.base.tracks.height / 2
    state = sim.settle(settings.settle)
    normal, uphill = ramp.G_T_M()[:3, 2], ramp.G_T_M()[:3, 1]
    position, angle, slip = state.G_T_B[:3, 3].copy(), wheel_angle(), 0.0
    n = max(1, int(round(settings.hold / settings.sample)))
    rows = []
    dt = float(m.opt.timestep)
    for k in range(1, n + 1):
        t = k * settings.sample
        state = _drive(sim, q, speed, settings.ramp, t - settings.sample, settings.sample, dt)
        belt = radius * (wheel_angle() - angle) * state.G_T_B[:3, 0]  # belts' travel [m]
        moved = state.G_T_B[:3, 3] - position
        slip -= float((moved - belt) @ uphill)
        position, angle = state.G_T_B[:3, 3].copy(), wheel_angle()
        z = state.G_T_B[:3, 2]
        tilt = float(np.degrees(np.arccos(np.clip(z @ normal, -1.0, 1.0))))
        rows.append((t, tilt, slip, _arm_ground_contact(sim, arm_bodies, ground)))
        if stop is not None and stop(tilt, slip):
            break
    t_, tilt_, slip_, arm_ = (np.array(c) for c in zip(*rows, strict=True))
    return Trajectory(t_, tilt_, slip_, arm_.astype(bool))


def sim_verdict(
    robot: Robot,
    payload: Payload | None,
    posture: ArrayLike,
    slope: float,
    heading: float,
    friction: float,
    speed: float,
    settings: SimSettings,
    thresholds: Thresholds,
) -> SimVerdict:
    """:func:`classify` of :func:`simulate_case`, stopped as soon as a threshold is passed."""

    def decided(tilt: float, slip: float) -> bool:
        return tilt > thresholds.tip_deg or slip > thresholds.slide_m

    trajectory = simulate_case(
        robot, payload, posture, slope, heading, friction, speed, settings, decided
    )
    return classify(trajectory, thresholds)
