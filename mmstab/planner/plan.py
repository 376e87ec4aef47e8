"""The planner for a problem: its region, settings and poses along its path, then the IK.

A closed path (the circle) is planned at ``planner.poses`` poses evenly spread over the
lap (:func:`plan_path`); an open one (a route) at poses ``planner.spacing`` apart, each
warm-started from the one before (:func:`plan_route`, :mod:`mmstab.planner.along_route`).
The region searched is ``workspace.method``'s (:func:`mmstab.planner.regions.planning_region`).
"""

from __future__ import annotations

import gc
import time

from mmstab.core.files import MmstabError
from mmstab.core.heap import keep_freed_memory
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray, Robot
from mmstab.paths.base import BasePath
from mmstab.paths.circle import CirclePath
from mmstab.paths.route import DEFAULT_SPACING, RoutePath, route_samples
from mmstab.planner.along_path import Plan, solve_path
from mmstab.planner.along_route import RoutePlan, solve_route
from mmstab.planner.regions import PlanningRegion, planning_region
from mmstab.planner.settings import PlannerSettings
from mmstab.terrain import Terrain
from mmstab.workspace import Workspace, WorkspaceSettings


def problem_region(
    problem: Problem, workspace: Workspace | None, progress: bool
) -> tuple[Workspace, PlanningRegion]:
    """The problem's workspace V (given, or loaded/built) and its planning region.

    Raises:
        MmstabError: the workspace V is empty.
    """
    from mmstab.workspace import robot_workspace

    settings = WorkspaceSettings.from_section(problem.section("workspace"))
    ws = workspace if workspace is not None else robot_workspace(problem.robot, settings,
                                                                  progress=progress)  # fmt: skip
    return ws, region_of(ws, settings.method, str(problem.path))


def region_of(ws: Workspace, method: str, where: str = "mmstab") -> PlanningRegion:
    """The planning region of ``ws`` for ``workspace.method`` (``where``: names the source).

    Raises:
        MmstabError: the workspace V is empty.
    """
    if len(ws.valid_com_in_V) == 0:
        raise MmstabError(f"{where}: the workspace V is empty; no arm CoM can be planned")
    return planning_region(ws, method)


def plan_path(problem: Problem, workspace: Workspace | None = None, progress: bool = False) -> Plan:
    """Plan the problem's circle: workspace (cached), the planner per pose, IK per target.

    Args:
        problem: a loaded problem (sections ``planner``, ``workspace``, ``path``).
        workspace: a prebuilt :class:`mmstab.workspace.Workspace`; default: load or build.
        progress: show progress bars.
    """
    ws, region = problem_region(problem, workspace, progress)
    settings = PlannerSettings.from_section(problem.section("planner"), problem.section("physics"))
    return plan_circle(problem.robot, problem.terrain, problem.circle, ws, region, settings,
                       str(problem.path))  # fmt: skip


def plan_circle(
    robot: Robot,
    terrain: Terrain,
    circle: CirclePath,
    ws: Workspace,
    region: PlanningRegion,
    settings: PlannerSettings,
    where: str = "mmstab",
) -> Plan:
    """Plan a circle: ``settings.poses`` poses over the lap, the planner per pose, IK per target.

    Args:
        robot: the robot.
        terrain: the ground.
        circle: the base's circle in the map frame.
        ws: the robot's workspace V.
        region: the region searched (:func:`region_of`).
        settings: the planner's settings.
        where: names the source in messages (the problem file).

    Raises:
        MmstabError: ``settings.flipper_angles`` set (the flippers are planned elsewhere).
    """
    from mmstab.workspace.ik import PostureSolver

    if settings.flipper_angles:
        raise MmstabError(
            f"{where}: planner.flipper_angles plans the flippers, which the tracking "
            "controller does not move; they are planned by make levers "
            "(mmstab.planner.levers.solve_path_flippers)"
        )
    solver = PostureSolver(robot, ws)
    poses = circle.poses(settings.poses)
    return solve_path(robot, terrain, region, poses, settings, solver.realise, closed=True)


def plan_route(
    problem: Problem, workspace: Workspace | None = None, progress: bool = False
) -> RoutePlan:
    """Plan the problem's route: workspace (cached), poses ``planner.spacing`` apart, IK.

    Raises:
        MmstabError: the problem's path is not a route, or the workspace V is empty.
    """
    route = problem.route
    if route is None:
        raise MmstabError(f"{problem.path}: path: not a route (waypoints or file)")
    t0 = time.perf_counter()
    ws, region = problem_region(problem, workspace, progress)
    section = problem.section("planner")
    settings = PlannerSettings.from_section(section, problem.section("physics"))
    spacing = float(section.get("spacing", DEFAULT_SPACING))
    return plan_route_path(problem.robot, problem.terrain, route, ws, region, settings, spacing,
                           t0)  # fmt: skip


def plan_route_path(
    robot: Robot,
    terrain: Terrain,
    route: RoutePath,
    ws: Workspace,
    region: PlanningRegion,
    settings: PlannerSettings,
    spacing: float = DEFAULT_SPACING,
    t0: float | None = None,
) -> RoutePlan:
    """Plan a route: poses ``spacing`` apart, each warm-started from the one before, IK.

    Poses at 0, ``spacing``, ... and the route's end; their fractions are the route's time
    fractions (the end is reached before the period ends, ``mmstab.paths.route``). Every
    pose after the first is warm-started from the one before
    (:func:`mmstab.planner.along_route.solve_route`).

    Args:
        robot: the robot.
        terrain: the ground.
        route: the base's route.
        ws: the robot's workspace V.
        region: the region searched (:func:`region_of`).
        settings: the planner's settings.
        spacing: distance between planned poses along the route (``planner.spacing``) [m].
        t0: ``time.perf_counter()`` when the fixed costs began (default: now).
    """
    from mmstab.workspace.ik import PostureSolver

    t0 = time.perf_counter() if t0 is None else t0
    s = route_samples(route.length, spacing)
    poses = route.route.sample(s).pose
    solver = PostureSolver(robot, ws)
    prepare_search(robot, ws, settings, terrain, poses[:1])
    fixed = time.perf_counter() - t0
    plan = solve_route(
        robot, terrain, region, s, poses, settings, solver.realise, route.fraction_of_s(s)
    )
    return plan._replace(fixed_seconds=fixed)


def plan_base_path(
    robot: Robot,
    terrain: Terrain,
    base_path: BasePath,
    ws: Workspace,
    region: PlanningRegion,
    settings: PlannerSettings,
    spacing: float = DEFAULT_SPACING,
) -> Plan | RoutePlan:
    """:func:`plan_circle` on a closed path, :func:`plan_route_path` on a route."""
    if isinstance(base_path, CirclePath):
        return plan_circle(robot, terrain, base_path, ws, region, settings)
    if isinstance(base_path, RoutePath):
        return plan_route_path(robot, terrain, base_path, ws, region, settings, spacing)
    raise MmstabError(f"a path must be a CirclePath or a RoutePath, not {type(base_path).__name__}")


def prepare_search(
    robot: Robot,
    ws: Workspace,
    settings: PlannerSettings,
    terrain: Terrain | None = None,
    poses: FloatArray | None = None,
) -> None:
    """Load (or build) what the search keeps between the plans of a process, once.

    With a ``terrain`` and ``poses`` (the route's first, (1, 3) [m, m, rad]) a heightmap's
    rest solver is warmed on them (its contact candidates' coarse subset, 9 ms once a
    process, and the compiled kernel), whatever the method.

    ``method: roadmap``: the roadmap (its cache file), the start node's component on the
    nodes ``ground_clearance`` up (its graph, clusters) and its shortest-path tree, A*'s
    arrays of that graph, with a terrain the nodes' least arm height over the tilts of
    ``attitude_margin`` (:func:`mmstab.planner.grounded.node_lowest`), the compiled
    kernels loaded (the moves' clearance bounds, A*, the ground under the arm), the
    robot's turn floors
    (:meth:`mmstab.model.collision.CollisionChecker.turn_floors`), the objects alive then
    frozen (:func:`freeze_long_lived`) and the C heap's freed blocks kept for reuse
    (:func:`mmstab.core.heap.keep_freed_memory`); a route's poses then cost only their own
    search, and a one-off plan reports these fixed costs apart
    (``RoutePlan.fixed_seconds``). Other methods: nothing more.
    """
    if terrain is not None and poses is not None and len(poses):
        terrain.gravity_body(poses)
    if settings.method != "roadmap" or robot.tool_wrench is not None:
        return
    from mmstab.model import collision_distance
    from mmstab.model.collision import CollisionChecker
    from mmstab.planner.ground.kernel import load_kernels
    from mmstab.planner.searches.roadmap import component_view
    from mmstab.planner.searches.roadmap.moves import prepare_astar, start_tree
    from mmstab.workspace.roadmap import load_or_build_roadmap

    roadmap = load_or_build_roadmap(robot, ws)
    start = roadmap.connect(robot.stowed, robot)
    component_view(robot, roadmap, start, settings.ground_clearance)
    start_tree(roadmap, start, settings.ground_clearance)
    prepare_astar(roadmap, settings.ground_clearance)
    ground = settings.ground_clearance is not None
    if ground and terrain is not None and poses is not None and len(poses):  # under the arm
        from mmstab.planner.ground.under_arm import GroundUnderArm
        from mmstab.planner.grounded import node_lowest

        margin = settings.attitude_margin or 0.0
        node_lowest(roadmap, GroundUnderArm(robot, terrain, poses[:1], margin=margin))
    CollisionChecker(robot).turn_floors()
    collision_distance.available()
    load_kernels()
    freeze_long_lived()
    keep_freed_memory()


#: Whether :func:`freeze_long_lived` has run in this process.
_FROZEN = {"done": False}


def freeze_long_lived() -> None:
    """Leave the objects alive now out of the cycle collector's full passes, once a process.

    The modules and the caches just loaded live as long as the process; a full pass of
    the cycle collector over them cost 60 ms of CPU (about 4 ms per pose of a 16-pose
    one-off plan) and came in the middle of some one-off plans' search. Frozen
    (:func:`gc.freeze`) they are not looked at again; objects made later are collected as
    before. Once per process: garbage alive at that moment is never collected.
    """
    if not _FROZEN["done"]:
        gc.freeze()
        _FROZEN["done"] = True


def unfreeze_long_lived() -> None:
    """Give every frozen object back to the cycle collector; the next plan freezes again.

    A loop that freezes its own set-up (:func:`gc.freeze` moves all live objects, the
    planner's too) and ends with :func:`gc.unfreeze` calls this instead, so that the
    planner's once-a-process freeze is not taken as done when nothing is frozen.
    """
    gc.unfreeze()
    _FROZEN["done"] = False


def plan_problem(
    problem: Problem, workspace: Workspace | None = None, progress: bool = False
) -> Plan | RoutePlan:
    """The plan along the problem's path: :func:`plan_path` or :func:`plan_route`.

    The path's own kind decides: a closed path (the circle) is a lap, an open one (a
    route) is driven once.
    """
    if problem.base_path.closed:
        return plan_path(problem, workspace, progress)
    return plan_route(problem, workspace, progress)
