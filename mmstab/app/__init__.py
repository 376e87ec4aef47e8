"""The application layer: the orchestration the CLI and the experiments share.

Each function here chains pipeline stages for a problem; the stages themselves never call
each other's top level. Layers (``docs/architecture.md``): inputs → model/terrain →
stability → workspace → planner → controller → codegen → application (this module, the
tracking simulation, the rollouts, the experiments) → CLI.

- :func:`workspace`: the problem's arm-CoM workspace V, loaded from the cache or built.
- :func:`plan`: the stability plan along the problem's path (workspace, CMA-ES, IK).
- :func:`with_plugin`, :func:`step_backend`: the controller step a run uses (interpreted,
  or the generated C library).
- :func:`track`: one closed-loop tracking run of a plan (planned first when none is given).
- :func:`stability_along`: μ along base poses, with the arm as given, stowed and removed.
"""

from __future__ import annotations

import copy
import os
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import casadi as ca
from numpy.typing import ArrayLike

from mmstab.app.settings import Settings
from mmstab.core.files import MmstabError
from mmstab.core.problem import Problem, problem_from_dict
from mmstab.stability.support import StabilityCases
from mmstab.stability.support import stability_along as _stability_along

if TYPE_CHECKING:
    from mmstab.planner import Plan, RoutePlan
    from mmstab.runs.tracking import InitialArm, StepBackend, TrackingPlan, TrackingRun
    from mmstab.workspace import Workspace

Backend = Literal["interpreted", "generated"]


class TrackResult(NamedTuple):
    """A tracking run with what it ran on.

    Attributes:
        problem: the problem as run (its ``controller.plugin`` replaced if one was asked).
        plan: the arm plan tracked.
        run: the recorded run.
    """

    problem: Problem
    plan: TrackingPlan
    run: TrackingRun


def workspace(
    problem: Problem,
    *,
    force: bool = False,
    progress: bool = True,
    cache_dir: str | os.PathLike[str] | None = None,
) -> Workspace:
    """The problem's workspace V (:func:`mmstab.workspace.load_or_build_workspace`).

    Args:
        problem: the problem.
        force: rebuild even when the cache matches.
        progress: show a progress bar while building.
        cache_dir: cache folder (default: the workspace module's).
    """
    from mmstab.workspace import load_or_build_workspace

    return load_or_build_workspace(problem, force=force, progress=progress, cache_dir=cache_dir)


def plan(
    problem: Problem, *, ws: Workspace | None = None, progress: bool = False
) -> Plan | RoutePlan:
    """The stability plan along the problem's path (paper Section II-D).

    A closed path (the circle): ``planner.poses`` poses around it; an open one (a route):
    poses ``planner.spacing`` apart, warm-started (:func:`mmstab.planner.plan_problem`).
    With ``physics.slide_budget`` set, a route's turns that would slide are slowed
    (:mod:`mmstab.runs.time_law`; the default, null, slows none): the plan's
    ``route`` is the route it is timed on (``problem.following(plan)`` drives it).

    Args:
        problem: the problem (``planner``, ``workspace`` and ``path`` sections).
        ws: the workspace V, if already loaded (default :func:`workspace`).
        progress: show progress bars.

    Raises:
        MmstabError: an empty workspace.
    """
    from mmstab.planner import RoutePlan, plan_problem
    from mmstab.runs.time_law import with_time_law

    ws = ws if ws is not None else workspace(problem, progress=progress)
    made = plan_problem(problem, ws)
    route = problem.route
    if isinstance(made, RoutePlan) and route is not None:
        settings = Settings.from_problem(problem).verdicts
        return with_time_law(problem.robot, problem.terrain, route, made, settings)
    return made


def stability_along(problem: Problem, poses: ArrayLike, arm_com_body: ArrayLike) -> StabilityCases:
    """μ along base poses of the problem's terrain: arm as given, stowed, removed.

    Args:
        problem: the problem (robot and terrain).
        poses: base poses (N, 3) in the map frame M [m, m, rad].
        arm_com_body: arm CoM in the body frame per pose (N, 3) or (3,) [m].
    """
    return _stability_along(problem.robot, problem.terrain, poses, arm_com_body)


def with_plugin(problem: Problem, plugin: str | None) -> Problem:
    """The problem with ``controller.plugin`` replaced (validated again); itself if None."""
    from mmstab.control.controller import PLUGINS

    if plugin is None or plugin == Settings.from_problem(problem).controller.plugin:
        return problem
    if plugin not in PLUGINS:
        raise MmstabError(f"unknown QP plugin {plugin!r}; choose one of {', '.join(PLUGINS)}")
    data = copy.deepcopy(problem.data)
    data["controller"]["plugin"] = plugin
    return problem_from_dict(data, problem.path, force_size=problem.force_size)


def generated_step(problem: Problem, plugin: str | None = None) -> StepBackend:
    """The code-generated controller step (:func:`mmstab.codegen.load_step`), built if needed.

    Args:
        problem: the problem (``controller`` and ``codegen`` sections).
        plugin: a code-generable QP plugin; default the problem's ``codegen.plugin``.

    Raises:
        MmstabError: the plugin cannot be generated (qpOASES), or the build fails.
    """
    from mmstab.codegen import load_step
    from mmstab.runs.tracking import StepBackend

    function = load_step(problem, plugin=plugin)
    if not isinstance(function, ca.Function):
        raise MmstabError(f"mmstab.codegen.load_step returned {type(function)}, not a Function")
    return StepBackend(function, "generated")


def track(
    problem: Problem,
    arm_plan: TrackingPlan | None = None,
    *,
    plugin: str | None = None,
    backend: Backend = "interpreted",
    duration: float | None = None,
    initial_arm: InitialArm = "stowed",
    progress: bool = True,
    allow_unstable: bool = True,
) -> TrackResult:
    """One tracking run: the step chosen, the plan made (unless given), the loop simulated.

    Args:
        problem: the problem.
        arm_plan: an arm plan; default :func:`plan` on the problem.
        plugin: QP plugin (default the problem's ``controller.plugin``, or ``codegen.plugin``
            for the generated backend).
        backend: ``interpreted`` (CasADi ``conic``) or ``generated`` (compiled C).
        duration: simulated time [s] (default the problem's ``controller.duration``).
        initial_arm: ``stowed`` or ``planned`` (see :mod:`mmstab.runs.tracking`).
        progress: show progress bars.
        allow_unstable: go on when the plan made here is unstable (some pose's μ at or
            below ``planner.margin``, :mod:`mmstab.runs.verdict`); else stop before tracking.

    Returns:
        The problem as run (its plugin replaced), the plan and the run (which stops where
        the robot would tip over, ``run.tipped``).

    Raises:
        MmstabError: an unknown backend or plugin, or a failed build (before planning).
        UnstableError: the plan made here is unstable and ``allow_unstable`` is False.
    """
    from mmstab.runs.tracking import simulate

    if backend not in ("interpreted", "generated"):
        raise MmstabError(f"backend must be 'interpreted' or 'generated', got {backend!r}")
    step: Any = None
    if backend == "generated":  # default plugin: the code-generable codegen.plugin
        plugin = plugin if plugin is not None else Settings.from_problem(problem).codegen.plugin
        problem = with_plugin(problem, plugin)
        step = generated_step(problem, plugin)  # build (or load) before planning: fail early
    else:
        problem = with_plugin(problem, plugin)
    if arm_plan is None:
        from mmstab.runs.verdict import check_plan, plan_stability

        made = plan(problem, progress=progress)
        check_plan(plan_stability(problem, made), len(made.poses), allow_unstable)
        arm_plan = made
    problem = problem.following(arm_plan)  # a route plan's slowed turns
    run = simulate(
        problem, arm_plan, step=step, duration=duration, progress=progress, initial_arm=initial_arm
    )
    return TrackResult(problem, arm_plan, run)
