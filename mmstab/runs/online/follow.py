"""The online loop (``mmstab follow``): one update per elevation map, as on the robot.

Per map (:meth:`Follower.update`), on that map alone:

1. **where the robot is**: the odometry's (x, y, yaw), its progress ``s`` along the route
   (the nearest route point, searched near the last one, so a route that passes a place
   twice is not confused);
2. **rest**: the base rests on the map at the odometry pose (μ of the arm's posture now);
3. **re-plan** the horizon (:class:`~mmstab.runs.online.horizon.HorizonPlanner`): the
   route's planned poses from behind the robot to ``online.horizon`` ahead, each re-planned
   only when new or when the map changed its ground; what the map does not cover ahead is
   reported (``covered_ahead``), not guessed;
4. **step** the controller once: the task reference at ``s`` (base point on the route, the
   planned arm CoM interpolated between the horizon's poses, their postures as the posture
   task), the controller period set to the time since the last map; the arm's joint speeds
   are the command, and the arm's posture advances by them (the follower's own integration:
   a recording carries no joint states);
5. **verdicts**: the state's support on the map (its flags: high-centred), the arm's
   height above the map's ground, the rock check where μ < 0: with μ and the tilt, the
   answer. The work that can wait (queued re-plans, moves ahead) runs after the answer, in
   the map's spare time (:meth:`Follower.spare`).

Deterministic: the planner's generator is seeded (``planner.seed``) and no decision depends
on the clock, so the same recording gives the same commands and μ; only the latencies [s]
(wall time from the map to the command and to the answer, map decoding excluded) differ
between runs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from mmstab.control.controller import ControllerSettings, build_controller
from mmstab.control.controller.step import Controller
from mmstab.core.files import MmstabError
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray
from mmstab.paths.route import DEFAULT_SPACING, RoutePath, route_samples
from mmstab.planner.ground.arm_pieces import arm_surface
from mmstab.planner.plan import problem_region
from mmstab.planner.settings import PlannerSettings
from mmstab.runs.arm_ground import arm_heights
from mmstab.runs.online.horizon import HorizonPlanner, HorizonUpdate, Rested, rested_rows
from mmstab.runs.online.roadmap_horizon import RoadmapHorizon, pursue
from mmstab.runs.online.stream import MapUpdate
from mmstab.runs.tip_rule import RockCheck
from mmstab.stability.slip import support_tilt, terrain_friction
from mmstab.stability.support import state_load, support_on_rests
from mmstab.terrain.heightmap_terrain import HeightmapTerrain, rest_support
from mmstab.workspace import Workspace

#: The arm is led along the roadmap's checked moves, from its posture at the start through
#: each planned pose's in turn: the posture reference this far ahead of the arm on them
#: [rad], no further than the plan has it at the robot's progress, and the arm-CoM target
#: that posture's. A reference that jumps to the plan's posture at the progress while the
#: arm lags (the start, a long move) is cut across in the arm-CoM task: the turret stays,
#: the shoulder and elbow fold, the arm went up to 22 cm into the ground on the seeded
#: validation routes.
WAY_AHEAD = 0.2
#: The arm has made a move within this of its end [rad] (norm over the joints).
WAY_TOL = 0.05
#: Arc-length step of the route's samples for the progress search [m].
PROGRESS_STEP = 0.01
#: How far behind / ahead of the last progress the next one is searched [m].
PROGRESS_BACK, PROGRESS_AHEAD = 0.5, 3.0


class FollowSettings(NamedTuple):
    """The ``online`` section's loop settings.

    Attributes:
        map_topic: GridMap topic.
        odom_topic: Odometry topic.
        horizon: planned poses this far ahead of the robot [m].
        replan_tol: gravity change that re-plans a pose [rad].
        planner: ``"roadmap"`` (postures on the posture roadmap,
            :mod:`~mmstab.runs.online.roadmap_horizon`) or ``"warm"`` (CMA-ES in V,
            :mod:`~mmstab.runs.online.horizon`).
        joints_topic: the arm's measured ``sensor_msgs/JointState`` topic; None: the arm's
            posture is the loop's own integration of its commands.
    """

    map_topic: str
    odom_topic: str
    horizon: float
    replan_tol: float
    planner: str
    joints_topic: str | None

    @classmethod
    def of(cls, problem: Problem) -> FollowSettings:
        """The problem's ``online`` section (defaults filled in)."""
        o = problem.section("online")
        return cls(
            o["map_topic"], o["odom_topic"], float(o["horizon"]), float(o["replan_tol"]),
            str(o["planner"]), o["joints_topic"],
        )  # fmt: skip


class FollowStep(NamedTuple):
    """The loop's answer to one map.

    Attributes:
        time: the map's time from the recording's start [s].
        s: the robot's progress along the route [m].
        pose: the odometry pose (x, y, yaw) [m, m, rad].
        covered: the map covers the robot's own footprint.
        mu: μ now, the arm at ``q`` [N rad] (NaN when not covered).
        mu_planned: the horizon's planned μ at ``s`` (interpolated) [N rad].
        q: the arm's posture when the map arrived [rad].
        qdot: the command: joint speeds (tracks, arm) [rad/s].
        status: the controller's QP status (0 = solved).
        replanned: horizon poses re-planned on this map.
        uncovered: horizon poses the map does not cover.
        covered_ahead: the route planned on this map ahead of the robot [m].
        latency: wall time from the map to the answer [s]: the command and the verdicts
            (μ, tilt, the support's flags, the arm's height, the rock check; the command's
            callback excluded, the spare time's work after the answer too, :meth:`Follower.spare`).
        G_T_B: the state's resting pose on the map, under its own CoM (4, 4) (NaN when not
            covered): the rest its μ is computed on.
        polygon: the support polygon in the map frame (m, 3) [m] (empty when not covered).
        tilt: the support's tilt on the map (gravity against -z_B) [rad] (NaN when not
            covered); the tracks slide beyond atan(friction) (:mod:`mmstab.stability.slip`).
        gravity_body: gravity in B at rest on the map, as ``mu`` used it [m/s^2] (NaN when
            not covered).
        measured: ``q`` is the recording's joint state (else the loop's own integration).
        q_ref: the planned posture the step steered toward [rad] (None: none planned yet).
        flags: the resting pose's flags on the map (``high_centred``, ``line_contact``, ...)
            (empty when not covered).
        rocks: μ < 0 here, and the robot pushed by the route's acceleration rocks onto a
            support of this map that holds it: not tipping (:mod:`mmstab.runs.tip_rule`);
            computed only where μ < 0.
        arm_height: the arm's least height above the map's ground, the body at ``G_T_B``
            and the arm at ``q`` [m] (< 0: in the ground; NaN: not covered, or the arm over
            an unknown cell); :func:`mmstab.runs.arm_ground.arm_heights`, the measure
            ``plan`` and ``track`` take.
        command_latency: wall time from the map to the command [s] (part of ``latency``).
    """

    time: float
    s: float
    pose: FloatArray
    covered: bool
    mu: float
    mu_planned: float
    q: FloatArray
    qdot: FloatArray
    status: int
    replanned: int
    uncovered: int
    covered_ahead: float
    latency: float
    G_T_B: FloatArray
    polygon: FloatArray
    tilt: float
    gravity_body: FloatArray
    measured: bool
    q_ref: FloatArray | None = None
    flags: tuple[str, ...] = ()
    rocks: bool = False
    arm_height: float = math.nan
    command_latency: float = math.nan


class Follower:
    """The loop's state between maps (module text); build with :func:`build_follower`."""

    def __init__(
        self,
        problem: Problem,
        route: RoutePath,
        horizon: HorizonPlanner | RoadmapHorizon,
        controller: Controller,
        settings: FollowSettings,
    ) -> None:
        self.problem, self.route, self.horizon = problem, route, horizon
        self.controller, self.settings = controller, settings
        self.robot = problem.robot
        self.friction = terrain_friction(problem.terrain)
        self.rock = RockCheck(self.robot, route)  # the runs' tip rule
        self.arm_surface = arm_surface(self.robot)  # the arm against the ground, once
        self.s_fine = np.arange(0.0, route.length + PROGRESS_STEP, PROGRESS_STEP)
        # the route's poses there (the reference pose at a progress: as sampled alone)
        self.pose_fine = route.route.sample(np.minimum(self.s_fine, route.length)).pose
        self.xy_fine = self.pose_fine[:, :2]
        self.s: float | None = None
        self.q = np.array(self.robot.stowed, dtype=float)
        self.last_time: float | None = None
        self.period = float(controller.params.dt)
        self.ground = np.zeros((1, 3))  # local ground (z, roll, pitch) last used [m, rad, rad]
        #: called with the command (tracks, arm) [rad/s] and the planned posture [rad] (None:
        #: none yet) as soon as the step has them, before the answer's verdicts (the
        #: live node publishes the command there: mmstab.runs.online.node)
        self.on_command: Callable[[FloatArray, FloatArray | None], None] | None = None
        #: the loop thread's processor time of the last update's answer [s] (as ``latency``)
        self.cpu_time = 0.0
        #: the last update's spare time is still to run (:meth:`spare`)
        self._spare_due = False
        #: the planned pose whose move the arm is on, the move's nodes, the way made on it [rad]
        self.way: tuple[int, tuple[int | None, int], float] | None = None
        #: moves that could not be made (the arm's posture reached no roadmap node)
        self.no_way: set[tuple[int, tuple[int | None, int]]] = set()

    def progress(self, xy: FloatArray) -> float:
        """Arc length [m] of the route point nearest ``xy``, near the last progress."""
        return float(min(self.s_fine[self._nearest(xy)], self.route.length))

    def _nearest(self, xy: FloatArray) -> int:
        """Index in :attr:`s_fine` of the route point nearest ``xy``, near the last progress."""
        if self.s is None:
            lo, hi = 0, len(self.s_fine)
        else:  # s_fine ascends: the window [s - back, s + ahead] is one slice
            lo = int(np.searchsorted(self.s_fine, self.s - PROGRESS_BACK, side="left"))
            hi = int(np.searchsorted(self.s_fine, self.s + PROGRESS_AHEAD, side="right"))
        d = np.linalg.norm(self.xy_fine[lo:hi] - xy, axis=1)
        return lo + int(np.argmin(d))

    def update(self, u: MapUpdate) -> FollowStep:
        """One map (module text)."""
        t0, cpu0 = time.perf_counter(), time.thread_time()
        terrain = HeightmapTerrain(u.grid.heightmap, self.robot, friction=self.friction)  # bound
        pose = u.odometry.pose
        at = self._nearest(pose[:2])
        self.s = s = float(min(self.s_fine[at], self.route.length))
        if u.joints is not None:  # the arm as measured, not as commanded
            self.q = np.array(u.joints.q, dtype=float)
        q = self.q.copy()
        ks = self.horizon.window(s, self.settings.horizon)
        ref_pose = self.pose_fine[at : at + 1]  # the route's pose at s
        arm_com = np.asarray(self.robot.arm_com(q), dtype=float)
        # one rest for all: the robot, its reference pose, the horizon's poses (under the
        # bound robot's CoM), and the state now under its own (its μ's loaded support)
        P = np.vstack([pose[None], ref_pose, self.horizon.poses_grid[ks]])
        mass, com_now, wrench = state_load(self.robot, arm_com, q[None], 1)
        com = np.vstack([np.broadcast_to(terrain.com_body, (len(P), 3)), com_now])
        rests = terrain.rest(np.vstack([P, pose[None]]), strict=False, com_body=com)
        rested = rested_rows(rests, len(P))
        horizon = Rested(
            rested.covered[2:], rested.gravity_body[2:], rested.ground[2:], rested.G_T_B[2:]
        )
        changes = self.horizon.update(terrain, ks, horizon, u.time, arm_com, q)
        covered = bool(rested.covered[0])
        g_now = rested.gravity_body[0]
        mu = float("nan")
        if covered:  # the one μ: this state's loaded support on this map (loaded_mu's)
            now = support_on_rests(terrain, rests, np.array([len(P)]), mass, com_now, wrench)
            mu = float(now.mu[0])
        tilt = float(support_tilt(g_now)[0]) if covered else float("nan")
        for i in (1, 0):  # the reference pose's ground, else the robot's, else the last
            if rested.covered[i]:
                self.ground = rested.ground[i : i + 1]
                break
        target, q_ref, mu_planned = self.horizon.reference(s, self._spacing())
        way = self._way(q, s)
        if way is not None:
            q_ref, target = way, np.asarray(self.robot.arm_com(way), dtype=float)
        com_target = arm_com if target is None else target  # None: hold the arm's CoM
        qdot, status = self._step(pose, ref_pose, q, com_target, q_ref, u.time)
        command_latency = time.perf_counter() - t0
        self._spare_due = True  # the spare time's work runs after the answer (:meth:`spare`)
        callback, callback_cpu = 0.0, 0.0
        if self.on_command is not None:  # out at once, before the verdicts (not timed)
            t1, cpu1 = time.perf_counter(), time.thread_time()
            self.on_command(qdot, None if q_ref is None else np.array(q_ref))
            callback, callback_cpu = time.perf_counter() - t1, time.thread_time() - cpu1
        G_T_B, polygon = np.full((4, 4), np.nan), np.zeros((0, 3))
        flags: tuple[str, ...] = ()
        arm_height = math.nan
        # the state under its own CoM may rest on an unknown cell where the bound robot's
        # CoM did not (its row NaN above); its support is the rest its μ was computed on
        if covered and np.isfinite(rests.G_T_B[len(P)]).all():
            support = rest_support(rests, len(P), terrain.candidates.points)
            G_T_B, polygon, flags = support.G_T_B, support.polygon_G, tuple(support.flags)
            h = arm_heights(self.robot, terrain, G_T_B[None], q[None], self.arm_surface)
            arm_height = float(h[0])
        rocks = covered and mu < 0 and bool(self.rock.holds(terrain, pose[None], arm_com[None])[0])
        latency = time.perf_counter() - t0 - callback
        self.cpu_time = time.thread_time() - cpu0 - callback_cpu
        return FollowStep(
            u.time, s, pose, covered, mu, mu_planned, q, qdot, status, len(changes.replanned),
            len(changes.uncovered), self._covered_ahead(s, ks, changes), latency, G_T_B, polygon,
            tilt, g_now, u.joints is not None, None if q_ref is None else np.array(q_ref), flags,
            rocks, arm_height, command_latency,
        )  # fmt: skip

    def spare(self) -> float:
        """The last map's spare time, after its answer: the queued re-plans, the moves ahead.

        Within its budget (``replan_jobs.SPARE_BUDGET`` of processor time; one re-plan step
        at least): what the answer does not wait for. Runs once per :meth:`update` (again:
        nothing). Returns its wall time [s].
        """
        due, self._spare_due = self._spare_due, False
        if not due or not isinstance(self.horizon, RoadmapHorizon):
            return 0.0
        t0 = time.perf_counter()
        # no budget: the re-plans are computed on their maps, only the moves ahead are left
        self.horizon.spare(time.thread_time() + (self.horizon.jobs.budget or 0.0))
        return time.perf_counter() - t0

    def _way(self, q: FloatArray, s: float) -> FloatArray | None:
        """The posture reference along the planned moves (:data:`WAY_AHEAD`; None: no plan).

        A roadmap horizon's move into each planned pose is checked against the robot and the
        ground (:meth:`RoadmapHorizon.move`); the arm is led along the moves in turn
        (:func:`pursue`), up to where the plan has it at progress ``s`` [m]. Where the arm's
        posture at a chain's start reaches no roadmap node (no checked move from it), that
        move is passed over: the plan's posture at ``s`` is the reference until the next
        planned pose's move.
        """
        h = self.horizon
        if not isinstance(h, RoadmapHorizon) or not h.plans:
            return None
        at = h.schedule(s, self._spacing())
        if at is None:
            return None
        k_now, share = at
        if self.way is None or self.way[0] not in h.plans or self.way[0] > k_now:
            ks = [k for k in h.plans if k <= k_now and (k, h.move_key(k)) not in self.no_way]
            if not ks:
                return None
            self.way = (min(ks), h.move_key(min(ks)), 0.0)
        for _ in range(len(h.plans)):
            k, key, made = self.way
            if h.move_key(k) != key:  # re-planned: the new move, from its nearest point
                key, made = h.move_key(k), 0.0
            try:
                path = h.move(k)
            except MmstabError:  # the arm's posture then reaches no node: not tried again
                self.no_way.add((k, key))
                self.way = None
                return None
            cap = share if k == k_now else 1.0
            total = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
            q_ref, made = pursue(path, q, made, WAY_AHEAD, cap * total)
            self.way = (k, key, made)
            later = [j for j in h.plans if k < j <= k_now]
            if not later or float(np.linalg.norm(q - path[-1])) > WAY_TOL:
                return q_ref
            self.way = (min(later), h.move_key(min(later)), 0.0)
        return q_ref

    def _spacing(self) -> float:
        grid = self.horizon.s_grid
        return float(grid[1] - grid[0]) if len(grid) > 1 else DEFAULT_SPACING

    def _step(
        self,
        pose: FloatArray,
        ref_pose: FloatArray,
        q: FloatArray,
        target: FloatArray | None,
        q_ref: FloatArray | None,
        now: float,
    ) -> tuple[FloatArray, int]:
        """One controller step toward the references at ``ref_pose``; advance the posture.

        Args:
            pose: the robot's pose (x, y, yaw) [m, m, rad].
            ref_pose: the route's pose at the robot's progress (1, 3).
            q: the arm's posture [rad].
            target: the planned arm CoM there, body frame [m] (None: hold the arm's).
            q_ref: the planned posture there [rad] (None: hold).
            now: the map's time [s].
        """
        dt = self.period if self.last_time is None else max(now - self.last_time, 1e-3)
        self.last_time = now
        if abs(dt - self.controller.params.dt) > 1e-9:
            self.controller.set_params(self.controller.params._replace(dt=dt))
        com_body = self.robot.arm_com(q) if target is None else target
        xi_des = step_target(self.controller.settings, ref_pose, self.ground, com_body)
        state = np.concatenate([pose, [0.0, 0.0], q])
        result = self.controller.solve(state, xi_des, None, q_ref, None, self.ground[0])
        self.q = q + result.qdot[2:] * dt  # qdot: the two tracks, then the arm's joints
        return result.qdot, int(result.status)

    def _covered_ahead(self, s: float, ks: list[int], changes: HorizonUpdate) -> float:
        """The route ahead of ``s`` [m] up to the first horizon pose the map does not cover."""
        missing = [self.horizon.s_grid[k] for k in changes.uncovered if self.horizon.s_grid[k] > s]
        end = float(self.horizon.s_grid[ks[-1]]) if ks else s
        return max(min(missing, default=end) - s, 0.0)


def step_target(
    settings: ControllerSettings, ref_pose: FloatArray, ground: FloatArray, com_body: FloatArray
) -> FloatArray:
    """ξ_des (6,) of one online step: the base point and heading, and the arm CoM.

    Args:
        settings: the controller settings (``base_offset`` [m], ``arm_com_frame``).
        ref_pose: the route's pose (1, 3) [m, m, rad] in M.
        ground: its local ground (1, 3) [m, rad, rad].
        com_body: the arm-CoM target in B (3,) [m]; placed with ``ref_pose`` in M unless the
            controller tracks it in B (``arm_com_frame: body``).
    """
    points = np.array([[settings.base_offset, 0.0, 0.0], com_body])
    placed = place_two(ref_pose[0], ground[0], points)  # place_local's, to the bit
    com = com_body if settings.arm_com_frame == "body" else placed[1]
    return np.concatenate([placed[0, :2], ref_pose[0, 2:], com])


def place_two(pose: FloatArray, ground: FloatArray, points_body: FloatArray) -> FloatArray:
    """Two body points (2, 3) [m] placed in M at ``pose`` on its local ``ground``.

    :func:`~mmstab.terrain.place_local`'s placement (``place_local_sx``: ``[x, y, z] +
    Rz(yaw) Ry(-pitch) Rx(roll) p``) in scalar arithmetic, its products and sums in the
    expression's order: the same numbers to the bit (tested), without its Jacobians and
    CasADi's call (50 -> 3 us per map).

    Args:
        pose: (x, y, yaw) (3,) [m, m, rad] in M.
        ground: its local ground (z, roll, pitch) (3,) [m, rad, rad].
        points_body: (2, 3) in B [m].
    """
    x, y, yaw = (float(v) for v in pose)
    z, roll, pitch = (float(v) for v in ground)
    cy, sy = math.cos(yaw), math.sin(yaw)
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), -math.sin(pitch)  # Ry(-pitch), as local_rotation_sx
    R = (
        (cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
        (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
        (-sp, cp * sr, cp * cr),
    )
    o = (x, y, z)
    return np.array(
        [
            [o[i] + (R[i][0] * p[0] + R[i][1] * p[1] + R[i][2] * p[2]) for i in range(3)]
            for p in np.asarray(points_body, dtype=float).tolist()
        ]
    )


def build_follower(problem: Problem, workspace: Workspace | None = None) -> Follower:
    """The loop for a route problem: V (cached), the planning grid, the IK, the controller.

    Raises:
        MmstabError: the problem's path is not a route, or V is empty.
    """
    from mmstab.workspace.ik import PostureSolver
    from mmstab.workspace.roadmap import load_or_build_roadmap

    route = problem.route
    if route is None:
        raise MmstabError(f"{problem.path}: path: not a route (waypoints or file)")
    ws, region = problem_region(problem, workspace, False)
    section = problem.section("planner")
    s_grid = route_samples(route.length, float(section.get("spacing", DEFAULT_SPACING)))
    settings = FollowSettings.of(problem)
    planner = PlannerSettings.from_section(section, problem.section("physics"))
    poses = route.route.sample(s_grid).pose
    horizon: HorizonPlanner | RoadmapHorizon
    if settings.planner == "roadmap":
        roadmap = load_or_build_roadmap(problem.robot, ws)
        horizon = RoadmapHorizon(
            problem.robot, roadmap, planner, s_grid, poses, settings.replan_tol
        )
        horizon.warm_up()
    else:
        horizon = HorizonPlanner(
            problem.robot, region, planner, s_grid, poses,
            PostureSolver(problem.robot, ws).realise, settings.replan_tol,
        )  # fmt: skip
    ctrl = build_controller(
        problem.robot, ControllerSettings.from_section(problem.section("controller"))
    )
    return Follower(problem, route, horizon, ctrl, settings)
