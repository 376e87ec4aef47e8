"""mmstab: stability-aware planning and control of tracked mobile manipulators on slopes.

The package is laid out as the pipeline (``docs/architecture.md``): ``core`` (configuration,
schema, the problem) -> ``model`` (robot, kinematics) and ``terrain`` / ``paths`` (the ground
and the base's path) -> ``stability`` (force-angle) -> ``workspace`` (the arm-CoM workspace V)
-> ``planner`` (Eq. 6 per pose) -> ``control`` (the QP controller) -> ``codegen`` -> ``runs``,
``physics``, ``viz`` -> ``app`` -> ``outputs`` -> ``cli`` (the paper's figures and the
studies: the repository's ``experiments/``, outside the package).

The names below are the public API, re-exported from their stages::

    import mmstab

    robot = mmstab.load_robot("problems/robots/cameleon.yaml")
    ramp = mmstab.Ramp(0.2)
    route = mmstab.route_path(robot, ramp, [[0, 0], [2, 0]], speed=0.3, turn_radius=0.5)
    plan = mmstab.plan(robot, ramp, route)   # the workspace V (cached), Eq. 6, the verdicts
    run = mmstab.track(plan).run             # the QP controller drives it
    problem_plan = mmstab.plan(mmstab.load_problem("problems/ramp.yaml"))  # from a file

They load on first use, so ``import mmstab`` stays light (no CasADi until a stage is asked for).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: Public name -> the module that defines it.
_EXPORTS: dict[str, str] = {
    # inputs
    "load_problem": "mmstab.core.problem",
    "Problem": "mmstab.core.problem",
    "ConfigError": "mmstab.core.files",
    "MmstabError": "mmstab.core.files",
    # model
    "load_robot": "mmstab.app.api",
    "Robot": "mmstab.model.robot",
    "Payload": "mmstab.model.payload",
    "attach_payload": "mmstab.model.payload",
    "with_flipper_angle": "mmstab.model.robot",
    "flipper_ground_angle": "mmstab.model.robot",
    # ground and paths
    "Terrain": "mmstab.terrain",
    "Ramp": "mmstab.terrain",
    "Heightmap": "mmstab.terrain",
    "HeightmapTerrain": "mmstab.terrain",
    "load_heightmap": "mmstab.terrain.io",
    "roll_pitch": "mmstab.terrain",
    "global_com_functions": "mmstab.terrain",
    "CirclePath": "mmstab.paths.circle",
    "RoutePath": "mmstab.paths.route",
    # stability
    "force_angle": "mmstab.stability.static",
    "robot_force_angle": "mmstab.stability.static",
    "robot_mu": "mmstab.stability.dynamic",
    "stance": "mmstab.stability.stance",
    "Stance": "mmstab.stability.stance",
    "route_path": "mmstab.paths.route",
    # the pipeline (the layer the CLI and the experiments share)
    "plan": "mmstab.app.api",
    "track": "mmstab.app.api",
    "PathPlan": "mmstab.app.api",
    "Controller": "mmstab.control.loop",
    "Tracked": "mmstab.app.api",
    "Settings": "mmstab.app.settings",
    "stability_along": "mmstab.app",
}

__all__ = [
    "CirclePath",
    "ConfigError",
    "Controller",
    "Heightmap",
    "HeightmapTerrain",
    "MmstabError",
    "PathPlan",
    "Payload",
    "Problem",
    "Ramp",
    "Robot",
    "RoutePath",
    "Settings",
    "Stance",
    "Terrain",
    "Tracked",
    "attach_payload",
    "flipper_ground_angle",
    "force_angle",
    "global_com_functions",
    "load_heightmap",
    "load_problem",
    "load_robot",
    "plan",
    "robot_force_angle",
    "robot_mu",
    "roll_pitch",
    "route_path",
    "stability_along",
    "stance",
    "track",
    "with_flipper_angle",
]  # the keys of _EXPORTS (a test holds them equal)

if TYPE_CHECKING:  # the same names, for type checkers and editors
    from mmstab.app import stability_along
    from mmstab.app.api import PathPlan, Tracked, load_robot, plan, track
    from mmstab.app.settings import Settings
    from mmstab.control.loop import Controller
    from mmstab.core.files import ConfigError, MmstabError
    from mmstab.core.problem import Problem, load_problem
    from mmstab.model.payload import Payload, attach_payload
    from mmstab.model.robot import Robot, flipper_ground_angle, with_flipper_angle
    from mmstab.paths.circle import CirclePath
    from mmstab.paths.route import RoutePath, route_path
    from mmstab.stability.dynamic import robot_mu
    from mmstab.stability.stance import Stance, stance
    from mmstab.stability.static import force_angle, robot_force_angle
    from mmstab.terrain import (
        Heightmap,
        HeightmapTerrain,
        Ramp,
        Terrain,
        global_com_functions,
        roll_pitch,
    )
    from mmstab.terrain.io import load_heightmap


def __getattr__(name: str) -> Any:
    """Load a public name from its stage on first use (PEP 562)."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'mmstab' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])
