"""The controller in the loop on the whole robot in MuJoCo (``mmstab simulate``).

The tracking run of :mod:`mmstab.runs.tracking`, with MuJoCo as the plant instead of the
kinematic one: every control period ``physics.control_dt`` the controller's step (the
interpreted CasADi Function, or the generated C through ``casadi.external``) reads the
state MuJoCo produced, the base pose (x, y, heading) in the terrain's map frame M from the
simulated chassis and the arm's joint angles from its joints, against the same references
as the kinematic run (:func:`mmstab.control.approach.run_reference`; the arm CoM in the frame
of ``controller.arm_com_frame``, the errors reported in M). Its joint speeds drive
the model (:mod:`mmstab.physics.robot_sim`):

- tracks: each side's wheels at the drive layer's belt speed (:mod:`mmstab.stability.drive`):
  the twist the sprocket rates θ̇ mean, its yaw rate raised by 1 / ``physics.turn_ratio``
  (η = 1: the sprocket's surface speed r·θ̇ [m/s]); the slip verdict's commanded motion
  stays the controller's θ̇ through the kinematic plant (what it intended);
- arm: the position servos' targets advance by q̇·dt from where they were (a velocity
  command through a position loop, as joint controllers run it).

Per control period the run records the simulated state, the commanded speeds, the task
errors, mmstab's predicted μ at the simulated pose (the base rested on the terrain, the arm
as simulated) and the **simulated μ**: the force-angle measure of the contacts MuJoCo loads
(contact points with a positive normal force, their hull along gravity) with the simulated
overall CoM and m·g. Verdicts: **tipped** when the physics loses the robot: MuJoCo's contacts
stop supporting it (their μ ≤ 0, or none, for ``tip_hold`` seconds) or its attitude passes
the point of no return (the vertical through the CoM leaves the tracks' footprint); the
chassis' tilt off its resting attitude on the terrain beyond ``disagreement_angle`` is a
**disagreement** with mmstab's resting pose, reported, not a tip; **slid** when, over any
``slip_window`` seconds, the robot's CoM (projected on the support plane) moved more than
``slip_distance`` *down the slope* beyond what the tracks commanded (the kinematic plant's
motion from each simulated state; :func:`downhill_drift`).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from mmstab.control.approach import arm_references, run_reference
from mmstab.control.layout import ControllerParams
from mmstab.control.pivot import pivoting
from mmstab.control.plant import build_plant
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray
from mmstab.paths.route import RoutePath
from mmstab.physics.governor import GovernorSettings, ReferenceClock
from mmstab.physics.loop_checks import (
    TipCheck,
    downhill_drift,
    predicted_path_slip,
    run_end,
    stall_record,
)
from mmstab.physics.robot_model import ModelSettings
from mmstab.physics.robot_sim import RobotSim, RobotState
from mmstab.stability.drive import DriveLayer, resolve_turn_ratio
from mmstab.stability.slip import slip_limit, terrain_friction
from mmstab.stability.support import loaded_mu


@dataclass(frozen=True)
class LoopSettings:
    """The ``physics:`` section of a problem.

    Attributes:
        control_dt: control period [s] (a whole number of MuJoCo steps).
        duration: simulated time [s]; None: the controller's (a route's driving time).
        disagreement_angle: chassis tilt off its predicted resting attitude that is reported
            as a disagreement with mmstab's rest (not a verdict) [rad].
        tip_hold: how long MuJoCo's contacts may lose the support (their μ ≤ 0, or no
            contact) before the robot counts as tipped [s].
        slip_distance: uncommanded downhill displacement that counts as sliding [m].
        slip_window: the window over which it is measured [s].
        check_dt: period of the tip check and the simulated μ [s] (reports, not control).
        backend: ``interpreted`` or ``generated`` (the C step).
        wheel: the road wheels' collision shape (:data:`~mmstab.physics.robot_model.WHEEL_SHAPES`).
        timestep: MuJoCo's integration step [s] (the contacts' time constant is kept at
            2.5 steps at least: MuJoCo needs 2).
        arm: ``planned`` (the plan's postures) or ``stowed`` (the arm held stowed).
        turn_ratio: the drive layer's η [-] in (0, 1], or ``auto``: the skid model's level
            pivot (:mod:`mmstab.stability.drive`); 1: the belts at r θ̇.
        governor: the reference waits for a base that falls behind
            (:mod:`mmstab.physics.governor`); None: the reference runs on time.
        suspension_travel: how far each road wheel may drop below its bump stop [m]
            (:class:`~mmstab.physics.robot_model.ModelSettings`; 0: stiff wheels; a
            problem's ``auto``: :func:`mmstab.outputs.simulate.suspension_travel`).
        pivot_centre: where a route's pivots turn: ``auto``, about the skid model's pivot
            centre for the plan's CoM there (:mod:`mmstab.control.pivot`), or a distance
            ahead of B's origin [m] (0: about the origin, as the planned route).
    """

    control_dt: float = 0.004
    duration: float | None = None
    disagreement_angle: float = 0.35
    tip_hold: float = 0.8
    slip_distance: float = 0.05
    slip_window: float = 1.0
    check_dt: float = 0.02
    backend: str = "interpreted"
    wheel: str = "sphere"
    timestep: float = 0.004
    arm: str = "planned"
    turn_ratio: float | str = 1.0
    governor: GovernorSettings | None = GovernorSettings()
    suspension_travel: float = 0.0
    pivot_centre: float | str = "auto"

    def model_settings(self) -> ModelSettings:
        """The MuJoCo model's numbers with this section's wheel shape, step and travel."""
        base = ModelSettings()
        solref = (max(base.solref[0], 2.5 * self.timestep), base.solref[1])
        return ModelSettings(wheel=self.wheel, timestep=self.timestep, solref=solref,
                             suspension_travel=self.suspension_travel)  # fmt: skip


@dataclass
class PhysicsRun:
    """A closed-loop run in MuJoCo (arrays per control period, N + 1 samples).

    Attributes:
        t: times [s].
        state: simulated controller states (x, y, heading in M, sprockets, arm) (N+1, 5+n).
        qdot: commanded joint speeds (N, 2+n) [rad/s].
        status: the controller's QP status per period (N,).
        base_error: base control point's distance from its reference [m].
        arm_com_error: arm CoM's distance from its reference in M [m] (whichever frame the
            controller tracks it in, ``controller.arm_com_frame``).
        mu_predicted: mmstab's μ at the simulated pose and posture [N rad].
        mu_simulated: μ of MuJoCo's loaded contacts [N rad] (every ``check_dt``; NaN between
            and where no contact is loaded).
        tilt_error: chassis tilt off the terrain's resting attitude [rad] (every ``check_dt``).
        slip: uncommanded downhill displacement over the last ``slip_window`` [m].
        tipped: time it tipped [s] (its support lost, or overturned), or None.
        slid: time it slid [s], or None.
        real_time_factor: simulated time / wall time (controller included) [-].
        wall_seconds: wall time of the loop [s].
        left_map: time the simulated robot left the terrain's map [s] (the run ends at the
            check before), or None.
        slip_predicted: mmstab's slip check at each simulated pose (its resting support
            tilted beyond atan(friction); :mod:`mmstab.stability.slip`) (N + 1,) bool.
        path_slip_predicted: mmstab's prediction that the path slides there: its turns (the
            skid-steer model on the reference) or its pose beyond the friction cone
            (:func:`~mmstab.physics.loop_checks.predicted_path_slip`) (N + 1,) bool.
        cpu_seconds: CPU time of this process in the loop [s]: simulated time / it is the
            real-time factor on a core of one's own (a shared machine slows the wall time).
        arm_ground: 1 where an arm link touches the ground, 0 where none does (every
            ``check_dt``; NaN between): mmstab's workspace checks the arm against the
            robot's body only, so a planned posture may reach into the ground.
        base_origin_error: the body origin's distance from the reference pose's in M's x-y
            plane [m] (a route's pivots about their centres, ``pivot_centre``): the
            controller tracks the control point ``base_offset`` ahead, so a base that drives
            crabbed (its heading turned off the path's to hold a side slope) has its origin
            off the path by about offset · sin(crab) more.
        timing: the arm's time law's report (:meth:`mmstab.control.timing.TimeLaw.summary`),
            None when ``controller.dynamic_fraction`` is null.
        reference_wait_s: how long the reference waited for the base in all [s]
            (:mod:`mmstab.physics.governor`; 0 when it never fell behind that far).
        base_wait_s: how long the base waited at the path's start for the arm to unfold
            onto the plan's first posture [s] (:attr:`mmstab.control.approach.ArmReferences.hold`).
        stalled: time the run ended with its reference unfinished, having waited
            ``governor.wait_limit`` [s], or None.
        stall: where it stalled, what held it (:func:`mmstab.physics.loop_checks.stall_record`:
            ``cause``, ``high-centred`` or ``stuck``, and the parts ``touching`` the ground),
            or None.
        tip_cause: ``support lost`` (MuJoCo's contacts' μ ≤ 0 for ``tip_hold``) or
            ``overturned`` (past the point of no return), None when it did not tip.
        body_G_T_B: the simulated body's pose in G (N+1, 4, 4) at every ``check_dt`` (NaN
            between): the attitude MuJoCo gave it, for a replay (``simulate --gif``).
        disagreement: first time the tilt off the predicted rest passed
            ``disagreement_angle`` [s], or None (a report: mmstab's rest and the simulated
            attitude disagree there; not a tip).
        heading_reference: the reference heading the controller tracked at each sample
            (ξ_des's heading row, the time law's and the governor's waits included) (N+1,)
            [rad], or None.
    """

    t: FloatArray
    state: FloatArray
    qdot: FloatArray
    status: FloatArray
    base_error: FloatArray
    arm_com_error: FloatArray
    mu_predicted: FloatArray
    mu_simulated: FloatArray
    tilt_error: FloatArray
    slip: FloatArray
    tipped: float | None
    slid: float | None
    real_time_factor: float
    wall_seconds: float
    left_map: float | None = None
    arm_ground: FloatArray | None = None
    cpu_seconds: float | None = None
    slip_predicted: FloatArray | None = None
    path_slip_predicted: FloatArray | None = None
    base_origin_error: FloatArray | None = None
    timing: dict[str, Any] | None = None
    reference_wait_s: float = 0.0
    base_wait_s: float = 0.0
    stalled: float | None = None
    stall: dict[str, Any] | None = None
    tip_cause: str | None = None
    disagreement: float | None = None
    body_G_T_B: FloatArray | None = None
    heading_reference: FloatArray | None = None


def map_pose(state: RobotState, M_T_G: FloatArray) -> FloatArray:
    """The simulated base pose (x, y, heading) in the terrain's map frame M."""
    M_T_B = M_T_G @ state.G_T_B
    return np.array([M_T_B[0, 3], M_T_B[1, 3], np.arctan2(M_T_B[1, 0], M_T_B[0, 0])])


def read_back(
    sim: RobotSim, M_T_G: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """(pose (x, y, heading) in M, G_T_B (4, 4), arm angles, M_T_B (4, 4)) now.

    :meth:`RobotSim.state`'s part the loop needs, without its attitude and velocities (it
    runs every control period).
    """
    d, b = sim.data, sim.base
    G_T_B = np.eye(4)
    G_T_B[:3, :3], G_T_B[:3, 3] = d.xmat[b].reshape(3, 3), d.xpos[b]
    M_T_B = M_T_G @ G_T_B
    pose = np.array([M_T_B[0, 3], M_T_B[1, 3], np.arctan2(M_T_B[1, 0], M_T_B[0, 0])])
    return pose, G_T_B, d.qpos[sim.arm_qpos], M_T_B


class BufferedStep:
    """The controller step called through CasADi's buffers: no conversion per call.

    ``step(state, reference, params) -> (qdot, status, objective)`` as a CasADi Function
    (interpreted or the generated C through ``casadi.external``); a plain callable is
    called as it is. CasADi's call converts every argument to a DM and back (42 µs a call
    for the generated step); its buffer evaluation reads and writes NumPy arrays in place
    (1 µs).
    """

    def __init__(self, step: Any, n_state: int, n_ref: int, params: FloatArray):
        self.step, self.params = step, np.ascontiguousarray(params, dtype=float)
        self.state, self.ref = np.zeros(n_state), np.zeros(n_ref)
        self.qdot, self.status, self.objective = np.zeros(n_state - 3), np.zeros(1), np.zeros(1)
        self.evaluate = None
        if hasattr(step, "buffer"):
            buf, self.evaluate = step.buffer()
            for i, a in enumerate((self.state, self.ref, self.params)):
                buf.set_arg(i, a.data)
            for i, a in enumerate((self.qdot, self.status, self.objective)):
                buf.set_res(i, a.data)
            self._buf = buf  # keeps the buffers alive

    def __call__(self, state: FloatArray, ref: FloatArray) -> tuple[FloatArray, float]:
        """(qdot (2 + n,) [rad/s], QP status) at ``state`` against ``ref``."""
        if self.evaluate is None:
            qd, st, _ = self.step(state, ref, self.params)
            return np.asarray(qd, dtype=float).ravel(), float(st)
        self.state[:], self.ref[:] = state, ref
        self.evaluate()
        return self.qdot.copy(), float(self.status[0])


def build_sim(problem: Problem, state0: FloatArray, settings: ModelSettings | None) -> RobotSim:
    """The robot at the run's start pose on the problem's terrain, settled."""
    n = problem.robot.arm_joints
    sim = RobotSim(
        problem.robot, problem.terrain, pose=state0[:3], arm_q=state0[-n:], settings=settings
    )
    sim.step((0.0, 0.0), state0[-n:], 0.5)  # set down at rest
    return sim


def run_closed_loop(
    problem: Problem,
    plan: Any,
    step: Any,
    ctrl_settings: Any,
    loop: LoopSettings,
    state0: FloatArray,
    model_settings: ModelSettings | None = None,
) -> PhysicsRun:
    """Track the problem's path in MuJoCo with the controller in the loop (module text).

    Args:
        problem: the problem (robot, terrain, path).
        plan: the arm plan (``fractions``, ``target_com``, ``postures``).
        step: the controller step ``(state, reference, params) -> (qdot, status, objective)``.
        ctrl_settings: the controller settings (gains, limits, ``base_offset``, lap time).
        loop: this loop's settings.
        state0: the start state (x, y, heading in M, sprockets, arm) [m, rad].
        model_settings: the MuJoCo model's numbers (default: ``loop.model_settings()``).
    """
    robot, n = problem.robot, problem.robot.arm_joints
    pivoted = pivoting(problem, plan, loop.pivot_centre)
    if pivoted is not problem:  # the route's period and length, as settings_for_path sets them
        old, new = problem.base_path, pivoted.base_path
        assert isinstance(old, RoutePath) and isinstance(new, RoutePath)
        own = ctrl_settings.lap_time == old.lap_time  # a route's own period, not a setting's
        period = new.lap_time if own else ctrl_settings.lap_time
        length = new.duration if ctrl_settings.duration == old.duration else ctrl_settings.duration
        ctrl_settings = dataclasses.replace(ctrl_settings, lap_time=period, duration=length)
        problem = pivoted
    sim = build_sim(problem, state0, model_settings or loop.model_settings())
    substeps = max(int(round(loop.control_dt / sim.model.opt.timestep)), 1)
    dt = substeps * sim.model.opt.timestep
    duration = ctrl_settings.duration if loop.duration is None else loop.duration
    ground = (problem.base_path, problem.terrain)
    nominal = dataclasses.replace(ctrl_settings, duration=duration)  # the time law's window
    arm_refs = arm_references(robot, plan, state0[-n:], nominal, None, ground)
    steps = max(int(round(arm_refs.real_time(duration) / dt)), 1)  # with the time law's added
    refs = run_reference(robot, *ground, plan, state0[-n:], ctrl_settings,
                         np.arange(steps + 1) * dt, arm=arm_refs)  # fmt: skip
    clock = ReferenceClock(refs.control.pack(), refs.step.pack(), ctrl_settings.base_offset,
                           loop.governor, dt)  # fmt: skip
    steps, t = clock.max_steps, np.arange(clock.max_steps + 1) * dt  # waits included
    params = np.asarray(ControllerParams.from_settings(robot, ctrl_settings)._replace(dt=dt).pack())
    M_T_G = np.asarray(np.linalg.inv(problem.terrain.G_T_M()), dtype=np.float64)
    drive = DriveLayer.of(robot, resolve_turn_ratio(robot, loop.turn_ratio))
    every = max(int(round(loop.check_dt / dt)), 1)  # μ and tilt: reports, not control
    states, ref_map = np.zeros((steps + 1, 5 + n)), np.zeros((steps + 1, clock.tables[1].shape[1]))
    qdots, status, clock_t = np.zeros((steps, 2 + n)), np.zeros(steps), np.zeros(steps + 1)
    checks, positions = TipCheck(problem), []
    controller = BufferedStep(step, 5 + n, ref_map.shape[1], params)
    pose, G_T_B, arm_q, M_T_B = read_back(sim, M_T_G)
    state = np.concatenate([pose, [0.0, 0.0], arm_q])
    target = state[-n:].copy()
    t0, cpu0 = time.perf_counter(), time.process_time()
    for k in range(steps + 1):
        states[k], clock_t[k] = state, clock.row * dt
        ref, ref_map[k] = clock.rows(M_T_B)
        last = clock.done or clock.stalled(k) or k == steps
        if k % every == 0 or last:
            positions.append(sim.data.qpos.copy())  # contacts and μ after the run
            if checks.record(k, state[:3], G_T_B, last, sim.data.subtree_com[0]) or last:
                break
        qdots[k], status[k] = controller(state, ref)
        clock.advance()
        target = target + qdots[k, 2:] * dt
        sim.advance(drive.belts(qdots[k, :2]), target, substeps, qdots[k, 2:])
        sprockets = state[3:5] + qdots[k, :2] * dt
        pose, G_T_B, arm_q, M_T_B = read_back(sim, M_T_G)
        state = np.concatenate([pose, sprockets, arm_q])
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    m = (checks.end[0] if checks.end else k) + 1
    m, mu_sim, tilt, arm, end, cause = run_end(sim, checks, positions, m, t, loop.tip_hold)
    tau = arm_refs.nominal(clock_t).value if arm_refs.retimed else clock_t  # references' [s]
    run = _finish(problem, ctrl_settings, loop, t[:m], states[:m], qdots[: m - 1],
                  status[: m - 1], ref_map[:m], mu_sim, tilt, None, wall, dt, tau[:m])  # fmt: skip
    cut = end is not None and end[2] in ("tipped", "left_map")
    stalled = not (clock.done or cut)
    stall = stall_record(sim, positions, every * dt) if stalled else None
    return dataclasses.replace(
        run,
        tipped=float(t[end[1]]) if end and end[2] == "tipped" else None,
        left_map=float(t[end[1]]) if end and end[2] == "left_map" else None,
        arm_ground=arm,
        cpu_seconds=cpu,
        timing=refs.arm.timing_summary(float(clock_t[m - 1])),
        reference_wait_s=float(t[m - 1] - clock_t[m - 1]),
        base_wait_s=float(refs.arm.hold),
        stalled=float(t[m - 1]) if stalled else None,
        stall=stall,
        tip_cause=cause,
        body_G_T_B=frames_at_checks(checks, m),
    )


def frames_at_checks(checks: TipCheck, m: int) -> FloatArray:
    """The checks' simulated body poses G_T_B on the run's ``m`` periods (m, 4, 4), NaN between."""
    out = np.full((m, 4, 4), np.nan)
    for k, G_T_B in zip(checks.index, checks.frames, strict=False):
        if k < m:
            out[k] = G_T_B
    return out


def _finish(
    problem: Problem,
    ctrl_settings: Any,
    loop: LoopSettings,
    t: FloatArray,
    states: FloatArray,
    qdots: FloatArray,
    status: FloatArray,
    ref: FloatArray,
    mu_sim: FloatArray,
    tilt: FloatArray,
    tipped: float | None,
    wall: float,
    dt: float,
    tau: FloatArray | None = None,
) -> PhysicsRun:
    """Errors, predicted μ and the slip verdict of a finished loop.

    ``tau``: the references' nominal times at ``t`` [s] (the arm's time law); None: ``t``.
    """
    from mmstab.control.reference import circle_pose
    from mmstab.control.tasks import build_task_model
    from mmstab.runs.tracking.run import task_batch

    robot, n = problem.robot, problem.robot.arm_joints
    model = build_task_model(robot, ctrl_settings.base_offset)
    xi, _ = task_batch(model, problem.terrain, states)
    xi_des = ref[:, :6]
    gravity = problem.terrain.gravity_body(states[:, :3])
    # mmstab's one μ at the simulated pose and posture (the loaded support of that state)
    q = states[:, -n:]
    arm_com = robot.arm_com(q)
    mu_pred = loaded_mu(robot, problem.terrain, states[:, :3], arm_com, q, strict=False)
    window = int(round(loop.slip_window / dt))
    com = robot.overall_com(arm_com)[: len(qdots)]  # the slide is the CoM's
    slip = downhill_drift(build_plant(robot), gravity, states, qdots, dt, window, com)
    over = np.flatnonzero(slip > loop.slip_distance)
    off_rest = np.flatnonzero(np.nan_to_num(tilt) > loop.disagreement_angle)
    tau = t if tau is None else tau
    origin_ref = circle_pose(problem.base_path, tau / ctrl_settings.lap_time).value[:, :2]
    return PhysicsRun(
        t=t, state=states, qdot=qdots, status=status,
        base_error=np.linalg.norm(xi_des[:, :2] - xi[:, :2], axis=1),
        arm_com_error=np.linalg.norm(xi_des[:, 3:] - xi[:, 3:], axis=1),
        mu_predicted=np.asarray(mu_pred), mu_simulated=mu_sim, tilt_error=tilt, slip=slip,
        tipped=tipped, slid=float(t[over[0]]) if len(over) else None,
        slip_predicted=slip_limit(gravity, terrain_friction(problem.terrain)).slides,
        path_slip_predicted=predicted_path_slip(
            problem, ref, dt, ctrl_settings.base_offset, loop.slip_window, loop.slip_distance,
            turn_ratio=resolve_turn_ratio(robot, loop.turn_ratio),
            shear_modulus=float(problem.section("physics")["shear_modulus"])),
        real_time_factor=float(t[-1] / wall) if wall > 0 else float("inf"), wall_seconds=wall,
        base_origin_error=np.linalg.norm(states[:, :2] - origin_ref, axis=1),
        disagreement=float(t[off_rest[0]]) if len(off_rest) else None,
        heading_reference=np.asarray(ref[:, 2], dtype=float),
    )  # fmt: skip
