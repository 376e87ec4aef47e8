"""The closed loop's checks on the simulated robot (:mod:`mmstab.physics.closed_loop`).

The overturn and off-map checks and the tilt off the predicted rest (:class:`TipCheck`); the
contact set the simulated μ is measured on, the μ itself and where it loses the support
(:func:`support_lost`); whether the arm touches the ground; what touches it where a run stalls
(:func:`stall_record`).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from mmstab.core.masks import true_runs
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray
from mmstab.physics.robot_sim import RobotSim
from mmstab.stability.static import base_polygon, contact_force_angle, padded_axis_angles
from mmstab.terrain.base import GRAVITY_G
from mmstab.terrain.polygon_batch import hulls_along_batch

#: Wheels this close to the ground [m] count as support in the simulated μ.
NEAR_GROUND = 0.001
#: A stalled run's contacts are read over its last this long [s] (:func:`stall_record`).
STALL_WINDOW = 1.0
#: A chassis contact whose normal is within this of the vertical bears weight [rad].
RESTING_ANGLE = float(np.radians(45.0))
#: The robot's parts by their geoms' name prefixes (:mod:`mmstab.physics.robot_model`).
PARTS = {"chassis": ("chassis",), "tracks": ("wheel_", "track_"), "flippers": ("flipper_",),
         "arm": ("arm_", "payload")}  # fmt: skip


def contact_points(sim: RobotSim, wheels: list[int]) -> FloatArray:
    """MuJoCo's contact points now and the wheels' within ``NEAR_GROUND``, (n, 3) in G [m].

    Every active contact counts (touching or penetrating, loaded or not this instant), and
    every wheel geom (ids ``wheels``) within 1 mm of the ground at its nearest point: the
    soft contacts open and close step to step as the wheels bounce at the sub-millimetre
    scale (a sphere wheel's single contact most, when the arm presses on the ground), the
    set of wheels within 1 mm does not.
    """
    m, d = sim.model, sim.data
    points = [np.array(d.contact.pos[: d.ncon])]
    fromto = np.zeros(6)
    for g in wheels:
        if mujoco.mj_geomDistance(m, d, g, sim.terrain, NEAR_GROUND, fromto) < NEAR_GROUND:
            points.append(fromto[3:].copy()[None])
    return np.concatenate(points)


def contact_records(
    sim: RobotSim, positions: list[FloatArray]
) -> Iterator[tuple[FloatArray, FloatArray, bool]]:
    """(contact points (n, 3) [m], CoM (3,) [m], arm on the ground) at recorded ``qpos``.

    After a run: the loop records the generalized positions at its checks only, and the
    contacts (:func:`contact_points`) and the overall CoM are found here from each, by
    MuJoCo's position stage (kinematics and collision) on the simulation's data, which
    they overwrite: the reports cost the loop nothing.
    """
    m, d = sim.model, sim.data
    wheels = [g for g in range(m.ngeom) if m.geom(g).name.startswith("wheel_")]
    for qpos in positions:
        d.qpos[:] = qpos
        mujoco.mj_fwdPosition(m, d)
        yield contact_points(sim, wheels), d.subtree_com[0].copy(), arm_touches_ground(sim)


def touching_contacts(sim: RobotSim) -> NDArray[np.intp]:
    """The contacts touching now: not the ones MuJoCo lists within the contact gap."""
    return np.flatnonzero(sim.data.contact.dist[: sim.data.ncon] <= 0)


def touching_geoms(sim: RobotSim) -> set[str]:
    """The names of the geoms touching now (robot geoms collide with the ground only)."""
    d, m = sim.data, sim.model
    touching = touching_contacts(sim)
    geoms = np.concatenate([d.contact.geom1[touching], d.contact.geom2[touching]])
    return {str(m.geom(g).name) for g in set(geoms.tolist())}


def arm_touches_ground(sim: RobotSim) -> bool:
    """Whether an arm link's geom touches the ground now."""
    return any(name.startswith("arm_") for name in touching_geoms(sim))


def touching_parts(sim: RobotSim) -> tuple[set[str], bool]:
    """The robot's parts (:data:`PARTS`) touching the ground now, and whether the chassis rests.

    The chassis rests on the ground where one of its contacts' normals is within
    :data:`RESTING_ANGLE` of the vertical (it bears weight there, not a face it runs into).
    """
    d, m = sim.data, sim.model
    names, rests = set(), False
    for i in touching_contacts(sim):
        pair = {str(m.geom(d.contact.geom1[i]).name), str(m.geom(d.contact.geom2[i]).name)}
        names |= pair
        rests |= "chassis" in pair and abs(d.contact.frame[i][2]) >= np.cos(RESTING_ANGLE)
    parts = {part for part, prefixes in PARTS.items() if any(n.startswith(prefixes) for n in names)}
    return parts, bool(rests)


def stall_record(sim: RobotSim, positions: list[FloatArray], dt: float) -> dict[str, Any]:
    """What held a stalled robot: the parts on the ground over its last :data:`STALL_WINDOW`.

    Args:
        sim: the simulation (its data are overwritten: after the run).
        positions: ``qpos`` at the run's checks, ``dt`` [s] apart, the last one at the stall.
        dt: the checks' spacing [s].

    Returns:
        ``touching``: per part (:data:`PARTS`), the share of those checks it touched the
        ground at; ``chassis_resting``: the share the chassis rested on it at
        (:func:`touching_parts`); ``cause``: ``high-centred`` where it rested at half of them or
        more (it carries the robot, as the plan's high-centred limit says), else ``stuck``
        (the tracks on the ground could not drive it on: a wall, a climb, a slope).
    """
    last = positions[-max(int(round(STALL_WINDOW / dt)), 1) :]
    seen, rests = dict.fromkeys(PARTS, 0), 0
    for qpos in last:
        sim.data.qpos[:] = qpos
        mujoco.mj_fwdPosition(sim.model, sim.data)
        parts, chassis_rests = touching_parts(sim)
        rests += chassis_rests
        for part in parts:
            seen[part] += 1
    share = {part: seen[part] / len(last) for part in PARTS}
    cause = "high-centred" if rests >= 0.5 * len(last) else "stuck"
    return {"cause": cause, "touching": share, "chassis_resting": rests / len(last)}


def simulated_mu(points: FloatArray, com: FloatArray, mass: float) -> float:
    """μ of MuJoCo's contacts: their hull along gravity, the CoM [m], m·g [N rad].

    Args:
        points: the active contact points (n, 3) in G [m] (:func:`contact_points`).
        com: the robot's overall CoM in G (3,) [m].
        mass: the robot's mass [kg].
    """
    if len(points) == 0:
        return float("nan")
    return contact_force_angle(points, com, mass * GRAVITY_G).mu


def simulated_mus(points: list[FloatArray], coms: FloatArray, mass: float) -> FloatArray:
    """:func:`simulated_mu` of many records at once (K,) [N rad].

    The hulls of all contact sets at once (:func:`hulls_along_batch`); a set the batch does
    not settle (a line, a close pair, a point on an edge) goes through :func:`simulated_mu`.

    Args:
        points: each record's contact points (n_k, 3) in G [m] (:func:`contact_points`).
        coms: the overall CoMs in G (K, 3) [m].
        mass: the robot's mass [kg].
    """
    k = len(points)
    mu = np.full(k, np.nan)
    if k == 0:
        return mu
    size = np.array([len(p) for p in points])
    width = max(int(size.max()), 1)
    padded = np.zeros((k, width, 3))
    for i, p in enumerate(points):
        padded[i, : len(p)] = p
    mask = np.arange(width)[None, :] < size[:, None]
    force = mass * GRAVITY_G
    hulls = hulls_along_batch(padded, mask, force)
    coms = np.asarray(coms, dtype=float)
    ok = hulls.ok
    theta = padded_axis_angles(hulls.vertices[ok], hulls.n_vertices[ok], coms[ok], force)
    mu[ok] = np.min(theta, axis=1) * np.linalg.norm(force)
    for j in np.flatnonzero(~ok):
        mu[j] = simulated_mu(points[j], coms[j], mass)
    return mu


def tilts_off_rest(problem: Problem, poses: FloatArray, G_T_B: FloatArray) -> FloatArray:
    """Angles between simulated chassis z axes and their resting ones on the terrain [rad].

    Batched: poses (N, 3) (x, y, heading in M), simulated G_T_B (N, 4, 4). NaN where the
    pose's ground is off the terrain's map.
    """
    rest = getattr(problem.terrain, "rest", None)
    if rest is not None:  # a heightmap: off-map poses come back NaN
        z_rest = rest(poses, strict=False).G_T_B[:, :3, 2]
    else:
        z_rest = np.asarray(problem.terrain.G_T_B(poses)).reshape(-1, 4, 4)[:, :3, 2]
    c = np.clip(np.einsum("ni,ni->n", z_rest, G_T_B[:, :3, 2]), -1.0, 1.0)
    return np.asarray(np.arccos(c))


def beyond_no_return(ring_B: FloatArray, G_T_B: FloatArray, com_G: FloatArray) -> bool:
    """Whether the body's attitude is past the point of no return: it overturns.

    The vertical through the simulated overall CoM ``com_G`` (3,) [m] leaves the tracks'
    whole footprint (the largest support the chassis can stand on; ``ring_B``, its ring in
    B's x-y plane, CCW about z_B [m]: :func:`~mmstab.stability.static.base_polygon`) at the
    body's pose ``G_T_B`` (4, 4): μ of that footprint is ≤ 0, so gravity turns the robot
    further over whatever ground carries it. A planar ring seen from above keeps its order (reversed
    when z_B points down), so inside is the same side of every edge: no hull per check.
    """
    R = G_T_B[:3, :3]
    p = (ring_B @ R.T + G_T_B[:3, 3])[:, :2]
    edge = np.roll(p, -1, axis=0) - p
    to_com = np.asarray(com_G, dtype=float)[:2] - p
    cross = edge[:, 0] * to_com[:, 1] - edge[:, 1] * to_com[:, 0]
    return not bool(np.all(np.sign(R[2, 2]) * cross > 0))


def support_lost(t: FloatArray, mu: FloatArray, hold: float) -> tuple[int, int] | None:
    """The first stretch where MuJoCo's loaded contacts lose the robot's support.

    Args:
        t: the checks' times (K,) [s].
        mu: the simulated μ at them (K,) [N rad]; ≤ 0 or NaN (no contact) is lost support.
        hold: how long the support stays lost before it is a tip [s].

    Returns:
        (first check of the stretch, check at which ``hold`` has passed), or None.
    """
    lost = ~(np.asarray(mu) > 0)
    for a, b in true_runs(lost):
        done = np.flatnonzero(t[a:b] - t[a] >= hold - 1e-9)
        if len(done):
            return int(a), int(a + done[0])
    return None


def tip_end(
    checks: TipCheck, t: FloatArray, mu: FloatArray, m: int, hold: float
) -> tuple[Any, str | None]:
    """The run's end (last period, event's, kind) and the tip's cause, after the run.

    The checks' end (overturned or off the map), unless the simulated μ ``mu`` (per period,
    NaN between checks) lost the support (:func:`support_lost`, ``hold`` [s]) before it.

    Args:
        checks: the run's checks.
        t: the periods' times [s].
        mu: MuJoCo's contacts' μ per period [N rad].
        m: periods the run kept.
        hold: the tip's hold time [s].
    """
    end = checks.end
    cause = "overturned" if end is not None and end[2] == "tipped" else None
    idx = np.asarray(checks.index[: len(checks.tilt)], dtype=int)
    idx = idx[idx < m]
    lost = support_lost(t[idx], mu[idx], hold)
    if lost is not None and (end is None or idx[lost[1]] < end[1]):  # the support went first
        return (int(idx[lost[1]]), int(idx[lost[0]]), "tipped"), "support lost"
    return end, cause


class TipCheck:
    """The overturn and off-map checks of a run; the tilt off the predicted rest beside them.

    Every ``check_dt`` the loop records the simulated pose. At each record the attitude is
    checked against the point of no return (:func:`beyond_no_return`, cheap); the tilts off
    the terrain's resting attitude (a rest solve) are evaluated ``batch`` records at once
    (and at an overturn or the run's last record). The run stops at the first record off the
    map or overturned; the periods simulated after it (at most a batch) are dropped. The tilt
    off the predicted rest decides nothing: it is the run's disagreement with mmstab's
    resting pose (reported, not a tip).
    """

    def __init__(self, problem: Problem, batch: int = 25):
        self.problem, self.batch = problem, batch
        self.ring_B = base_polygon(problem.robot).vertices
        self.index: list[int] = []
        self.poses: list[FloatArray] = []
        self.frames: list[FloatArray] = []
        self.tilt: list[float] = []
        self.end: tuple[int, int, str] | None = None  # (last period, event's, kind)

    def record(
        self,
        k: int,
        pose: FloatArray,
        G_T_B: FloatArray,
        last: bool,
        com_G: FloatArray | None = None,
    ) -> bool:
        """Record period ``k``; True when the run must stop (overturned or off its map).

        Args:
            k: the control period.
            pose: the simulated base pose (x, y, heading in M) [m, rad].
            G_T_B: the simulated body pose (4, 4).
            last: the run's last record (evaluate what is pending).
            com_G: the simulated overall CoM in G (3,) [m]; None: no overturn check.
        """
        self.index.append(k)
        self.poses.append(pose)
        self.frames.append(G_T_B)
        over = com_G is not None and beyond_no_return(self.ring_B, G_T_B, com_G)
        if len(self.index) - len(self.tilt) >= self.batch or last or over:
            new = tilts_off_rest(self.problem, np.array(self.poses[len(self.tilt) :]),
                                 np.array(self.frames[len(self.tilt) :]))  # fmt: skip
            for j, value in enumerate(new, start=len(self.tilt)):
                if not np.isfinite(value):  # off the map: the run ends at the check before
                    self.end = (self.index[max(j - 1, 0)], self.index[j], "left_map")
                    self.index, self.tilt = self.index[:j], self.tilt[:j]
                    return True
                self.tilt.append(float(value))
        if over:
            self.end = (k, k, "tipped")
            return True
        return False


def run_end(
    sim: RobotSim,
    checks: TipCheck,
    positions: list[FloatArray],
    m: int,
    t: FloatArray,
    hold: float,
) -> tuple[int, FloatArray, FloatArray, FloatArray, Any, str | None]:
    """The checks' records of a run of ``m`` periods, cut where the support was lost.

    (periods kept, simulated μ, tilt off rest, arm on the ground, the end, the tip's cause);
    ``hold``: the tip's hold time [s] (:func:`tip_end`).
    """
    mu_sim, tilt, arm = check_records(sim, checks, positions, m)
    end, cause = tip_end(checks, t, mu_sim, m, hold)
    if cause == "support lost":  # the run ends once the support was lost tip_hold
        m = end[0] + 1
    return m, mu_sim[:m], tilt[:m], arm[:m], end, cause


def check_records(
    sim: RobotSim, checks: TipCheck, positions: list[FloatArray], m: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(simulated μ, tilt off rest, arm on the ground) at the checks of a run of ``m`` periods."""
    mu_sim, tilt, arm = np.full(m, np.nan), np.full(m, np.nan), np.full(m, np.nan)
    mass = float(sim.model.body_subtreemass[0])
    rows = list(zip(checks.index, checks.tilt, contact_records(sim, positions), strict=False))
    if not rows:
        return mu_sim, tilt, arm
    index, values, found = zip(*rows, strict=True)
    points, coms, touches = zip(*found, strict=True)
    i = np.array(index)
    tilt[i], arm[i], mu_sim[i] = values, touches, simulated_mus(list(points), np.array(coms), mass)
    return mu_sim, tilt, arm


def predicted_path_slip(
    problem: Problem,
    ref: FloatArray,
    dt: float,
    base_offset: float,
    window: float,
    distance: float,
    every: int = 25,
    turn_ratio: float = 1.0,
    shear_modulus: float = 0.0,
) -> FloatArray:
    """Whether mmstab predicts the path slides (its turns or its cone), per sample (N,) bool.

    The plan's own turn verdict (:func:`mmstab.runs.verdict.turn_slip`: the skid-steer
    model's slide at the turn rate the closed loop reaches, within ``window``) on the
    reference's base poses (B's origin, the control point ``base_offset`` [m] behind) at
    every ``every``-th sample, their times and the reference posture's arm CoM: the samples of
    a sliding turn are flagged, and a reference pose beyond the friction cone (the path's own
    prediction; the loop's cone flag, ``PhysicsRun.slip_predicted``, is at the simulated
    pose). One verdict for the plan and the run: the same function, on the path as the
    controller is given it.

    Args:
        problem: the problem (robot, terrain and its friction).
        ref: the packed step references (N, 15 + 2n) (:class:`StepReference`).
        dt: their period [s].
        base_offset: the control point ahead of B's origin [m].
        window: the slip window [s].
        distance: the slip distance [m].
        every: samples between the model's evaluations [-].
        turn_ratio: the drive layer's η [-]: the model's belts are the ones it commands.
        shear_modulus: the belts' shear modulus K [m] (``physics.shear_modulus``).
    """
    from mmstab.control.layout import StepReference
    from mmstab.runs.verdict import TurnCheck, slip_verdict

    robot, r = problem.robot, StepReference.unpack(ref)
    idx = np.arange(0, len(ref), every)
    xi = np.asarray(r.xi_des)[idx]
    c, s = np.cos(xi[:, 2]), np.sin(xi[:, 2])
    poses = np.c_[xi[:, 0] - base_offset * c, xi[:, 1] - base_offset * s, xi[:, 2]]
    arm_com = np.atleast_2d(robot.arm_com(np.asarray(r.q_ref)[idx]))
    check = TurnCheck(robot, arm_com, idx * dt, distance, window, None, turn_ratio,
                      shear_modulus)  # fmt: skip
    verdict = slip_verdict(problem.terrain, poses, check)  # the plan's: its cone and its turns
    flags = np.zeros(len(poses), dtype=bool)
    flags[[b["index"] for b in verdict["sliding_poses"]]] = True
    for turn in verdict.get("turns", {}).get("sliding_turns", []):
        flags[turn["first"] : turn["last"] + 1] = True
    return np.repeat(flags, every)[: len(ref)]


def downhill_drift(
    plant: Any,
    gravity_body: FloatArray,
    states: FloatArray,
    qdots: FloatArray,
    dt: float,
    window: int,
    com_body: FloatArray,
) -> FloatArray:
    """The CoM's downhill motion beyond the commanded one, per ``window`` periods [m].

    The point measured is the CoM's foot: the overall CoM (for each period's posture)
    projected along z_B on the support plane, a body-fixed point carried from the period's
    start to its end by the simulated base pose; the commanded motion is the kinematic
    plant's from the same simulated state, for that point (the plant driving the point
    along its heading: a command that pivots about it). Both are projected on the downhill
    direction at the pose (gravity in B, turned by the heading into M's plane) and summed
    over the last ``window`` periods: the drift is the simulated sum minus the commanded
    one, but never more than the simulated sum itself (``min(A - C, A)``). A sliding robot
    moves downhill (A > 0) beyond the command; a level pivot (about a point near the CoM)
    barely moves it; the tracks' servo lag and skid in turns move it either way; tracks
    that slip while they climb (a kerb) fall short of an uphill command (A - C > 0) while
    the base still moves uphill (A < 0): no slide.

    Args:
        plant: :func:`mmstab.control.plant.build_plant` of the robot.
        gravity_body: gravity in B at each period's start (N, 3) [m/s^2].
        states: simulated states (N + 1, 5 + n).
        qdots: commanded joint speeds (N, 2 + n) [rad/s].
        dt: control period [s].
        window: periods summed.
        com_body: the overall CoM in B at each period's start (N, 2) or (N, 3) (its x, y
            used), or one (2,) [m].
    """
    n = len(qdots)
    pred = np.array(plant(states[:n].T, qdots.T, dt)).T  # each period from its own start
    c, s = np.cos(states[:n, 2]), np.sin(states[:n, 2])
    g = gravity_body[:n]
    down = np.stack([c * g[:, 0] - s * g[:, 1], s * g[:, 0] + c * g[:, 1]], axis=1)
    norm = np.linalg.norm(down, axis=1, keepdims=True)
    down = np.divide(down, norm, out=np.zeros_like(down), where=norm > 1e-9)
    lag = np.maximum(np.arange(n + 1) - window, 0)

    def windowed(motion: FloatArray) -> FloatArray:
        acc = np.concatenate([[0.0], np.cumsum(np.sum(motion * down, 1))])
        return np.asarray(acc - acc[lag])

    p = np.asarray(com_body, dtype=float)
    p = np.broadcast_to(p[..., :2], (n, 2))
    c1, s1 = np.cos(states[1 : n + 1, 2]), np.sin(states[1 : n + 1, 2])
    start = np.c_[c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]]
    end = np.c_[c1 * p[:, 0] - s1 * p[:, 1], s1 * p[:, 0] + c1 * p[:, 1]]
    simulated = windowed(states[1 : n + 1, :2] + end - states[:n, :2] - start)
    commanded = windowed(pred[:, :2] - states[:n, :2])
    return np.minimum(simulated - commanded, simulated)
