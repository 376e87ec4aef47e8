"""The code-first API: :func:`plan` and :func:`track` on objects, :class:`PathPlan` back.

``mmstab.plan(robot, terrain, path, settings=None)`` plans the arm along a circle or a route
and judges the plan as ``mmstab plan`` does: the one :class:`PathPlan` it returns carries
the verdicts (tip, slide, step, high_centred, arm_contact) and ``accepted`` /
``exit_status`` (the command's exit status for the same inputs). ``mmstab.track(plan)``
drives the plan with the QP controller and returns a :class:`Tracked`, judged as ``mmstab
track`` judges it (``verdicts``, ``exit_status``). Both also take a
loaded problem in place of the objects (``mmstab.plan(problem)``), reading its settings
with :meth:`mmstab.app.settings.Settings.from_problem`.
"""

from __future__ import annotations

import dataclasses
import os
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from mmstab.app.settings import Settings
from mmstab.core.files import MmstabError
from mmstab.core.problem import Problem, Scene
from mmstab.paths.base import BasePath
from mmstab.paths.circle import CirclePath
from mmstab.paths.route import RoutePath
from mmstab.planner import Plan, RoutePlan
from mmstab.planner.plan import plan_base_path, region_of
from mmstab.runs.plan_verdicts import arm_path_check, exit_status, lap_verdicts, route_verdicts
from mmstab.runs.time_law import with_time_law
from mmstab.stability.dynamic import robot_mu
from mmstab.stability.support import stability_along
from mmstab.terrain import HeightmapTerrain
from mmstab.workspace import robot_workspace

if TYPE_CHECKING:
    from mmstab.control.controller import ControllerSettings
    from mmstab.model.robot import FloatArray, Robot
    from mmstab.runs.tracking import InitialArm, TrackingRun
    from mmstab.terrain import Terrain
    from mmstab.workspace import Workspace


@dataclass(frozen=True)
class PathPlan:
    """The plan along a path, circle or route, with its verdicts (:func:`plan`).

    Attributes:
        robot: the robot planned for.
        terrain: the ground (a heightmap bound to the robot).
        path: the base's path (:class:`~mmstab.paths.circle.CirclePath` or
            :class:`~mmstab.paths.route.RoutePath`; a route with the turns that would slide
            slowed, :mod:`mmstab.runs.time_law`).
        settings: every stage's settings used.
        s: arc length of each planned pose along the path (K,) [m].
        fractions: the path's (time) fraction at each pose (K,) [-].
        poses: base poses (K, 3) of (x [m], y [m], yaw [rad]) in the map frame.
        target_com: planned arm CoMs, body frame (K, 3) [m].
        postures: arm postures realising them (K, n) [rad], n the robot's arm joints.
        realised_com_error: |arm CoM of the posture - target| (K,) [m].
        collision_free: whether each posture is collision-free (K,).
        mu_planned: μ with the planned arm (K,) [N rad].
        mu_realised: μ with the realised posture (K,) [N rad].
        mu_stowed: μ with the arm stowed (K,) [N rad].
        mu_removed: μ with the arm removed (K,) [N rad].
        stability: the tip verdict's record (``summary.json``'s ``stability``).
        slip: the slide verdict's record (``slip``).
        climb: the climb limit's record (``climb``).
        high_centred: where the chassis rests on the ground (``high_centred``).
        verdicts: per limit (``tip``, ``slide``, ``step``, ``high_centred``, ``arm_contact``):
            ``verdict``, ``unsafe``, ``where`` (arc-length stretches [m]) as
            :func:`mmstab.runs.along.limit_verdicts` gives them.
        stage: the planner's own result (:class:`~mmstab.planner.Plan` on a circle,
            :class:`~mmstab.planner.RoutePlan` on a route).
    """

    robot: Robot
    terrain: Terrain
    path: BasePath
    settings: Settings
    s: FloatArray
    fractions: FloatArray
    poses: FloatArray
    target_com: FloatArray
    postures: FloatArray
    realised_com_error: FloatArray
    collision_free: np.ndarray
    mu_planned: FloatArray
    mu_realised: FloatArray
    mu_stowed: FloatArray
    mu_removed: FloatArray
    stability: dict[str, Any]
    slip: dict[str, Any]
    climb: dict[str, Any]
    high_centred: dict[str, Any]
    verdicts: dict[str, dict[str, Any]]
    stage: Plan | RoutePlan

    @property
    def exit_status(self) -> int:
        """``mmstab plan``'s exit status: 3 tips or under the margin, 4 slides, 5 arm contact."""
        return exit_status(self.verdicts)

    @property
    def accepted(self) -> bool:
        """Every pose holds with the margin, nothing slides, the arm touches nothing (exit 0)."""
        return self.exit_status == 0

    @property
    def unsafe(self) -> tuple[str, ...]:
        """The limits that make the plan unsafe (``tip``, ``slide``, ``arm_contact``)."""
        return tuple(k for k, v in self.verdicts.items() if v["unsafe"])

    @property
    def margin(self) -> float:
        """The margin μ must exceed (``planner.margin``) [N rad]."""
        return self.settings.verdicts.margin

    @property
    def moves(self) -> tuple[FloatArray, ...]:
        """The arm's path into each pose's posture (``method: roadmap``), else empty."""
        return self.stage.moves

    @property
    def targets(self) -> tuple[Any, ...]:
        """The planner's per-pose results (:class:`~mmstab.planner.PoseTarget`)."""
        return self.stage.targets

    @property
    def scene(self) -> Scene:
        """Robot, terrain and path (what :func:`track` drives on)."""
        return Scene(self.robot, self.terrain, self.path)


def load_robot(path: str | os.PathLike[str]) -> Robot:
    """A robot file, as a problem loads its robot (``mmstab.load_robot``).

    The pairs in contact at every sampled posture are not checked, as a problem's robot
    (:func:`mmstab.model.touching.with_touching_allowed`; ``robot.collision_allow`` lists
    them, and the command line notes them on stderr): loaded without that, a user's robot
    whose turret capsule meets its body at every angle had every posture colliding, so
    ``mmstab.plan`` refused for arm contact what ``mmstab plan`` accepts.

    Args:
        path: the robot's YAML file (docs/robot.md).

    Raises:
        ConfigError: the file is not a valid robot description, or its stowed arm touches
            the robot or reaches below the ground.
    """
    from mmstab.model.touching import load_checked_robot

    return load_checked_robot(path)[0]


def _objects(
    first: Robot | Problem, terrain: Terrain | None, path: BasePath | None
) -> tuple[Robot, Terrain, BasePath, Settings | None]:
    """Robot, terrain, path and (for a problem) its settings, from either call form."""
    if isinstance(first, Problem):
        if terrain is not None or path is not None:
            raise TypeError("plan(problem) takes no terrain or path: the problem has them")
        return first.robot, first.terrain, first.base_path, Settings.from_problem(first)
    if terrain is None or path is None:
        raise TypeError("plan(robot, terrain, path): give the terrain and the path")
    if not isinstance(path, (CirclePath, RoutePath)):
        raise TypeError(f"path must be a CirclePath or a RoutePath, not {type(path).__name__}")
    if isinstance(terrain, HeightmapTerrain) and terrain.robot is None:
        terrain = terrain.with_robot(first)  # its contacts are the robot's
    return first, terrain, path, None


def plan(
    robot: Robot | Problem,
    terrain: Terrain | None = None,
    path: BasePath | None = None,
    settings: Settings | None = None,
    *,
    ws: Workspace | None = None,
    progress: bool = False,
) -> PathPlan:
    """Plan the arm along a path and judge the plan (``mmstab plan``'s numbers and verdicts).

    Args:
        robot: the robot (:func:`mmstab.load_robot`), or a loaded problem
            (:func:`mmstab.load_problem`; then no ``terrain`` and ``path``).
        terrain: the ground (:class:`~mmstab.terrain.Ramp`,
            :class:`~mmstab.terrain.HeightmapTerrain`).
        path: the base's path (:class:`~mmstab.paths.circle.CirclePath`, or
            :class:`~mmstab.paths.route.RoutePath`, e.g. :func:`mmstab.route_path`).
        settings: every stage's settings; default the problem's, or
            :meth:`Settings.defaults` for these objects.
        ws: the robot's workspace V, if already loaded (default: the cache, else built).
        progress: show progress bars.

    Returns:
        The plan with its verdicts; ``accepted`` is what ``mmstab plan`` exits 0 on.

    Raises:
        MmstabError: an empty workspace, or ``planner.flipper_angles`` set.
        TypeError: the call mixes the two forms, or a path of another type.
    """
    robot_, terrain_, path_, loaded = _objects(robot, terrain, path)
    where = str(robot.path) if isinstance(robot, Problem) else "mmstab.plan"
    if settings is None:
        settings = loaded if loaded is not None else Settings.defaults(robot_, terrain_, path_)
    t0 = time.perf_counter()
    if ws is None:
        ws = robot_workspace(robot_, settings.workspace, progress=progress)
    region = region_of(ws, settings.workspace.method, where)
    stage = plan_base_path(robot_, terrain_, path_, ws, region, settings.planner, settings.spacing)
    if isinstance(stage, RoutePlan):
        stage = stage._replace(fixed_seconds=stage.fixed_seconds + time.perf_counter() - t0)
        assert isinstance(path_, RoutePath)
        return _route_plan(robot_, terrain_, path_, settings, stage)
    assert isinstance(path_, CirclePath)
    return _lap_plan(robot_, terrain_, path_, settings, stage)


def _route_plan(
    robot: Robot, terrain: Terrain, path: RoutePath, settings: Settings, stage: RoutePlan
) -> PathPlan:
    # the turns that would slide slowed (mmstab.runs.time_law): the plan's path is that route
    stage = with_time_law(robot, terrain, path, stage, settings.verdicts)
    path = stage.route if stage.route is not None else path
    arm_path = arm_path_check(robot, stage, path.lap_time, settings.controller.dt)
    v = route_verdicts(robot, terrain, path, stage, settings.verdicts, arm_path=arm_path)
    return PathPlan(
        robot, terrain, path, settings, stage.s, stage.fractions, stage.poses,
        stage.target_com, stage.postures, stage.realised_com_error, stage.collision_free,
        stage.mu_planned, np.asarray(v["mu_realised"], dtype=float), stage.mu_stowed,
        stage.mu_removed, v["stability"], v["slip"], v["climb"], v["high_centred"],
        v["verdicts"], stage,
    )  # fmt: skip


def _lap_plan(
    robot: Robot, terrain: Terrain, path: CirclePath, settings: Settings, stage: Plan
) -> PathPlan:
    postures = np.asarray(stage.postures, dtype=float)
    mu = stability_along(robot, terrain, stage.poses, robot.arm_com(postures))
    mu_realised = np.asarray(mu.reconfigured, dtype=float)
    if robot.tool_wrench is not None:  # payload.wrench: at the postures' tool points
        mu_realised = robot_mu(robot, terrain.gravity_body(stage.poses), postures)
    mu_planned = np.array([t.mu for t in stage.targets], dtype=float)
    poses = [
        {"pose": t.pose, "fraction": stage.fractions[k], "target_com": t.target_com,
         "mu_planned": t.mu, "mu_realised": mu_realised[k],
         "collision_free": bool(stage.collision_free[k])}
        for k, t in enumerate(stage.targets)
    ]  # fmt: skip
    lap_time = settings.controller.lap_time
    arm_path = arm_path_check(robot, stage, lap_time, settings.controller.dt)
    v = lap_verdicts(robot, terrain, path, stage, poses, settings.verdicts, lap_time, arm_path)
    s = path.length * np.asarray(stage.fractions, dtype=float)
    return PathPlan(
        robot, terrain, path, settings, s, np.asarray(stage.fractions, dtype=float),
        np.asarray(stage.poses, dtype=float), np.asarray(stage.target_com, dtype=float),
        postures, np.asarray(stage.realised_com_error, dtype=float),
        np.asarray(stage.collision_free), mu_planned, mu_realised,
        np.asarray(mu.stowed, dtype=float), np.asarray(mu.arm_removed, dtype=float),
        v["stability"], v["slip"], v["climb"], v["high_centred"], v["verdicts"], stage,
    )  # fmt: skip


class Tracked(NamedTuple):
    """A tracking run of a plan (:func:`track`), judged as ``mmstab track`` judges it.

    Attributes:
        plan: the plan driven.
        run: the recorded run (``run.tipped``: where it would tip over, else None).
        settings: the controller's settings as run (a route's ``lap_time`` and
            ``duration`` are its own; the ``plugin`` asked for).
        verdicts: per limit (``tip``, ``slide``, ``arm_contact``): ``verdict`` (``holds``,
            ``tips``, ``slides``, ``collides``), ``unsafe``, and the record ``mmstab track``
            writes for it (``tipped``, ``slip``, ``arm_self_collision``), checked at the
            run's saved samples (:func:`mmstab.runs.tracking.checks.run_verdicts`).
    """

    plan: PathPlan
    run: TrackingRun
    settings: ControllerSettings
    verdicts: dict[str, dict[str, Any]]

    @property
    def exit_status(self) -> int:
        """``mmstab track``'s exit status: 3 tips, 4 slides, 5 the arm touches, else 0."""
        return exit_status(self.verdicts)

    @property
    def accepted(self) -> bool:
        """The run neither tips, slides nor touches the robot with its arm (exit status 0)."""
        return self.exit_status == 0


def track_plan(
    plan: PathPlan,
    *,
    plugin: str | None = None,
    backend: str = "interpreted",
    duration: float | None = None,
    initial_arm: InitialArm = "stowed",
    progress: bool = False,
) -> Tracked:
    """Drive a plan with the QP controller along its path (the closed-loop simulation).

    Args:
        plan: a plan of :func:`plan`.
        plugin: QP plugin (default the settings' ``controller.plugin``, or ``codegen.plugin``
            for the generated backend).
        backend: ``interpreted`` (CasADi ``conic``) or ``generated`` (compiled C).
        duration: simulated time [s] (default the circle's ``controller.duration``, a
            route's driving time).
        initial_arm: ``stowed`` or ``planned`` (the plan's first posture).
        progress: show a progress bar.

    Raises:
        MmstabError: an unknown backend or plugin, a failed build, or the robot tips over
            at the start.
    """
    from mmstab.runs.tracking import StepBackend
    from mmstab.runs.tracking.checks import run_verdicts
    from mmstab.runs.tracking.simulation import settings_for_path, simulate

    if backend not in ("interpreted", "generated"):
        raise MmstabError(f"backend must be 'interpreted' or 'generated', got {backend!r}")
    controller = settings_for_path(plan.settings.controller, plan.path)
    step: StepBackend | None = None
    if backend == "generated":
        from mmstab.codegen.build import generate
        from mmstab.codegen.functions import STEP_NAME

        plugin = plugin if plugin is not None else plan.settings.codegen.plugin
        controller = dataclasses.replace(controller, plugin=plugin)
        source = (plan.robot, controller, plan.settings.codegen)
        step = StepBackend(generate(source, plugin=plugin).load(STEP_NAME), "generated")
    elif plugin is not None:
        controller = dataclasses.replace(controller, plugin=plugin)
    run = simulate(
        plan.scene,
        plan,
        plugin=plugin,
        step=step,
        duration=duration,
        progress=progress,
        initial_arm=initial_arm,
        settings=controller,
    )
    verdicts = run_verdicts(plan.robot, plan.terrain, plan.settings.verdicts, run)
    return Tracked(plan, run, controller, verdicts)


def track(
    plan: PathPlan | Problem,
    arm_plan: Any = None,
    *,
    plugin: str | None = None,
    backend: str = "interpreted",
    duration: float | None = None,
    initial_arm: InitialArm = "stowed",
    progress: bool = False,
    allow_unstable: bool = True,
) -> Any:
    """Drive a plan with the QP controller: :func:`track_plan` on a :class:`PathPlan`.

    ``track(plan, ...)`` returns a :class:`Tracked` (plan, run, settings, verdicts,
    ``exit_status``, ``accepted``). The older form
    ``track(problem, arm_plan=None, ...)`` (:func:`mmstab.app.track`) still returns
    ``(problem, plan, run)``.

    Args:
        plan: a plan of :func:`plan` (or a loaded problem: the older form).
        arm_plan: the older form's plan (None: planned there).
        plugin: QP plugin (default the settings' ``controller.plugin``).
        backend: ``interpreted`` or ``generated``.
        duration: simulated time [s] (default the circle's ``controller.duration``, a
            route's driving time).
        initial_arm: ``stowed`` or ``planned``.
        progress: show progress bars.
        allow_unstable: go on with a plan some pose of which is at or below the margin;
            else raise :class:`~mmstab.core.files.UnstableError` before driving it.

    Raises:
        UnstableError: the plan is unstable and ``allow_unstable`` is False.
    """
    if isinstance(plan, Problem):
        from mmstab.app import Backend
        from mmstab.app import track as track_problem

        kind: Backend = "generated" if backend == "generated" else "interpreted"
        if backend not in ("interpreted", "generated"):
            raise MmstabError(f"backend must be 'interpreted' or 'generated', got {backend!r}")
        return track_problem(plan, arm_plan, plugin=plugin, backend=kind, duration=duration,
                             initial_arm=initial_arm, progress=progress,
                             allow_unstable=allow_unstable)  # fmt: skip
    if arm_plan is not None:
        raise TypeError("track(plan, ...) takes no arm_plan: the plan is driven")
    if not allow_unstable:
        from mmstab.runs.verdict import check_plan

        check_plan(plan.stability, len(plan.s), allow_unstable)
    return track_plan(plan, plugin=plugin, backend=backend, duration=duration,
                      initial_arm=initial_arm, progress=progress)  # fmt: skip
