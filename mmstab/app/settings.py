"""Every stage's settings in one frozen object, built by one loader from a problem file.

:class:`Settings` holds the per-stage settings (``PlannerSettings``, ``WorkspaceSettings``,
``ControllerSettings``, ``CodegenSettings``, ``VerdictSettings``); the stages take these
objects, not the problem's sections. ``Settings()`` is the default
problem's (``problems/ramp.yaml``'s values, the keys a file may omit at their defaults) for
the 4-DoF robot; :meth:`Settings.defaults` fits them to another robot, terrain and path as
a problem file that names none would; :meth:`Settings.from_problem` reads a loaded problem.
Change one value with :func:`dataclasses.replace` (``Settings``, the per-stage dataclasses)
or ``_replace`` (``PlannerSettings``, a NamedTuple)::

    settings = Settings.defaults(robot, terrain, path)
    settings = dataclasses.replace(settings, planner=settings.planner._replace(poses=12))
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from mmstab.codegen.settings import CodegenSettings
from mmstab.control.controller.settings import ControllerSettings
from mmstab.core.defaults import with_defaults
from mmstab.paths.route import DEFAULT_SPACING, RoutePath
from mmstab.planner.settings import PlannerSettings
from mmstab.runs.verdict_settings import VerdictSettings
from mmstab.terrain import HeightmapTerrain
from mmstab.workspace.settings import WorkspaceSettings

if TYPE_CHECKING:
    from mmstab.core.problem import Problem
    from mmstab.model.robot import Robot
    from mmstab.paths.base import BasePath
    from mmstab.terrain import Terrain


def _default_sections() -> dict[str, Any]:
    """The sections of a circle problem on a plane that names none (4 arm joints)."""
    return with_defaults({}, 4)


def _default(name: str) -> Any:
    return getattr(Settings.from_sections(_default_sections()), name)


@dataclass(frozen=True)
class Settings:
    """The settings of every stage (the problem file's sections, read once).

    Attributes:
        planner: the ``planner:`` section (Eq. 6, the search).
        spacing: a route's planned poses' spacing (``planner.spacing``) [m].
        workspace: the ``workspace:`` section (V's grid, the planning region).
        controller: the ``controller:`` section (the QP controller, the tracking run).
        codegen: the ``codegen:`` section (the generated C step).
        verdicts: the limits a plan is judged by (``planner.margin``, ``physics:``'s slide).
    """

    planner: PlannerSettings = field(default_factory=lambda: _default("planner"))
    spacing: float = DEFAULT_SPACING
    workspace: WorkspaceSettings = field(default_factory=lambda: _default("workspace"))
    controller: ControllerSettings = field(default_factory=lambda: _default("controller"))
    codegen: CodegenSettings = field(default_factory=lambda: _default("codegen"))
    verdicts: VerdictSettings = field(default_factory=VerdictSettings)

    @classmethod
    def from_sections(cls, data: Mapping[str, Any]) -> Settings:
        """Build from a validated problem mapping (every section filled in)."""
        planner = data["planner"]
        return cls(
            planner=PlannerSettings.from_section(dict(planner), data.get("physics")),
            spacing=float(planner.get("spacing", DEFAULT_SPACING)),
            workspace=WorkspaceSettings.from_section(data["workspace"]),
            controller=ControllerSettings.from_section(data["controller"]),
            codegen=CodegenSettings.from_section(data["codegen"]),
            verdicts=VerdictSettings.from_sections(planner, data.get("physics", {})),
        )

    @classmethod
    def from_problem(cls, problem: Problem) -> Settings:
        """The settings of a loaded problem (:func:`mmstab.load_problem`)."""
        return cls.from_sections(problem.data)

    @classmethod
    def defaults(
        cls,
        robot: Robot | None = None,
        terrain: Terrain | None = None,
        path: BasePath | None = None,
    ) -> Settings:
        """The settings a problem file naming none would get for these inputs.

        The robot's joint count sets the per-joint keys (``controller.w_b``,
        ``posture_gain``, ``posture_weight``, ``workspace.grid``); a route plans with
        ``method: roadmap``, as does a circle over a heightmap; a path over a heightmap keeps
        the arm 5 cm above the ground
        (:func:`mmstab.core.defaults.with_defaults`). None: the default robot, a plane, a
        circle (``Settings()``).
        """
        skeleton: dict[str, Any] = {}
        if isinstance(path, RoutePath):
            skeleton["path"] = {"waypoints": []}
        if isinstance(terrain, HeightmapTerrain):
            skeleton["terrain"] = {"file": ""}
        joints = robot.arm_joints if robot is not None else 4
        return cls.from_sections(with_defaults(skeleton, joints))

    def replace(self, **changes: Any) -> Settings:
        """A copy with whole stages replaced (:func:`dataclasses.replace`)."""
        return dataclasses.replace(self, **changes)
