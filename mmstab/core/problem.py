"""A problem file: robot, ramp, path and the settings of every stage, validated at load.

The robot is given by a path relative to the problem file. ``load_problem`` is the one
place where a problem's inputs are checked; stages read their section from
``Problem.section(name)`` and trust it.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

from mmstab.core import schema
from mmstab.core.defaults import with_defaults
from mmstab.core.files import ConfigError, MmstabError, check_known_keys, read_yaml, validate
from mmstab.core.notes import note
from mmstab.core.setting_checks import check_arm_joints, check_problem
from mmstab.core.sizes import Estimate, estimates, refusal
from mmstab.model.payload import attach_payload, payload_from_section
from mmstab.model.robot import Robot, link_extent_warnings
from mmstab.model.touching import TOUCHING_SAMPLES, load_checked_robot
from mmstab.paths.base import BasePath
from mmstab.paths.circle import CirclePath
from mmstab.paths.route import RoutePath, is_route, route_path_from_section
from mmstab.terrain import Terrain, from_section
from mmstab.terrain.factory import check_section

#: Every key of a ``path:`` section, circle or route.
PATH_KEYS = tuple(
    dict.fromkeys(
        k
        for form in (schema.PATH_CIRCLE, schema.PATH_ROUTE_WAYPOINTS, schema.PATH_ROUTE_FILE)
        for k in form["properties"]
    )
)


@dataclass(frozen=True)
class Problem:
    """A validated problem.

    Attributes:
        path: the problem file.
        data: its validated content (sections by name).
        robot: the robot it names.
        terrain: the ground (:func:`mmstab.terrain.from_section` of the ``terrain:`` section).
        base_path: the base reference path in the terrain's map frame
            (:class:`mmstab.paths.base.BasePath`): a circle, or a route
            (:class:`mmstab.paths.route.RoutePath`) when ``path:`` has waypoints or a file.
            Stages that work on any path use it; :attr:`circle` and :attr:`route` are for
            the few that only know one kind (the circle's figures, a route's risk map).
        force_size: sizes beyond the time bounds were accepted (``--force-size``).
    """

    path: Path
    data: dict[str, Any]
    robot: Robot
    terrain: Terrain
    base_path: BasePath
    force_size: bool = False

    @property
    def circle(self) -> CirclePath:
        """The circle of a circle problem.

        Raises:
            MmstabError: the problem's path is a route (a stage that only knows circles).
        """
        if not isinstance(self.base_path, CirclePath):
            raise MmstabError(
                f"{self.path}: path: this command works on a circle; the problem's path is a "
                "route (use mmstab plan / track / route figures)"
            )
        return self.base_path

    @property
    def route(self) -> RoutePath | None:
        """The route of a route problem, else None."""
        return self.base_path if isinstance(self.base_path, RoutePath) else None

    def following(self, plan: Any) -> Problem:
        """The problem on the time law a plan's fractions follow (its ``route`` or ``path``).

        A route plan slows the turns that would slide (:mod:`mmstab.runs.time_law`); the
        tracking run, MuJoCo's reference and the plan's verdicts then drive that route.
        """
        route = getattr(plan, "route", None)  # a RoutePlan's; mmstab.plan's PathPlan: its path
        route = getattr(plan, "path", None) if route is None else route
        if not isinstance(route, RoutePath) or route is self.base_path:
            return self
        return dataclasses.replace(self, base_path=route)

    def size_estimates(self, duration: float | None = None) -> dict[str, Estimate]:
        """The size estimates of the stages (:func:`mmstab.core.sizes.estimates`), by section.

        The tracking run's is for the time it simulates (:func:`mmstab.runs.tracking.simulate`):
        ``duration`` [s] if given (``--duration``), else a route's driving time (a route sets
        its own length), else ``controller.duration``. On a route the planner's is for the
        poses it places, every ``planner.spacing`` (not ``planner.poses``).
        """
        poses = None
        if self.route is not None:  # a route plans every planner.spacing, not planner.poses
            poses = self.route.planned_poses(self.section("planner").get("spacing"))
        if duration is not None:
            return estimates(self.data, duration, "--duration", poses)
        if self.route is not None:
            return estimates(self.data, self.route.duration, "path", poses)
        return estimates(self.data)

    @property
    def ramp(self) -> Terrain:
        """Transitional alias of :attr:`terrain` (code written before the terrain interface)."""
        return self.terrain

    @property
    def name(self) -> str:
        """The problem's file stem (``ramp`` for ``problems/ramp.yaml``)."""
        return self.path.stem

    def section(self, name: str) -> dict[str, Any]:
        """One section's settings, as validated."""
        return self.data[name]

    def robot_path(self) -> Path:
        """The robot description's path."""
        return (self.path.parent / self.data["robot"]).resolve()

    def to_dict(self) -> dict[str, Any]:
        """Everything a run depended on: the problem and the robot description."""
        return {**self.data, "robot": read_yaml(self.robot_path())}


class Scene(NamedTuple):
    """A robot on the ground with its base's path: a problem's objects without its file.

    What the code-first API (:func:`mmstab.plan`, :func:`mmstab.track`) hands the stages
    that read only these three of a :class:`Problem`.

    Attributes:
        robot: the robot.
        terrain: the ground.
        base_path: the base's path in the terrain's map frame (a circle or a route).
    """

    robot: Robot
    terrain: Terrain
    base_path: BasePath

    @property
    def route(self) -> RoutePath | None:
        """The route, when the path is one, else None."""
        return self.base_path if isinstance(self.base_path, RoutePath) else None


_NOTED: set[tuple[Path, str]] = set()


def _note_robot(path: Path, robot: Robot, touching: tuple[tuple[str, str], ...]) -> None:
    """Notes on a robot file, on stderr, once per robot and process (not refusals).

    The collision pairs skipped as touching at every posture, and the links whose shape or
    CoM lies off their DH segment.
    """
    if (path, robot.source_hash) in _NOTED:
        return
    _NOTED.add((path, robot.source_hash))
    if touching:
        pairs = ", ".join("-".join(pr) for pr in touching)
        note(
            f"mmstab: note: {path}: {pairs} touch at every one of "
            f"{TOUCHING_SAMPLES + 1} sampled postures: not checked "
            "(collision.allow lists pairs not to check)"
        )
    for line in link_extent_warnings(robot):
        note(f"mmstab: warning: {path}: {line}")


def problem_from_dict(
    data: dict[str, Any],
    path: str | os.PathLike[str],
    *,
    force_size: bool = False,
    sections: Collection[str] | None = None,
) -> Problem:
    """Validate a problem mapping read from ``path`` (robot path relative to it).

    Every check runs here: the schema, the registry of :mod:`mmstab.core.setting_checks` and the
    size bounds of :mod:`mmstab.core.sizes` (``force_size`` accepts sizes beyond the time
    bounds, not beyond the memory). ``sections``: the sections the command uses (None: every
    one); the semantic checks and size bounds of the others are skipped, and without
    ``path`` a route is not checked against the ground (``mmstab rest``); the whole file is
    still checked against the schema.
    """
    p = Path(path)
    given = data
    data = with_defaults(given)
    validate(p, data, schema.problem_schema())
    robot_path = (p.parent / data["robot"]).resolve()
    if not robot_path.is_file():
        raise ConfigError(p, "robot", f"no robot description at {robot_path}")
    check_section(p, data["terrain"])  # before the size bounds read terrain.generate
    robot, touching = load_checked_robot(robot_path)
    described = robot  # the file's (a payload moves the last link's CoM)
    # the per-joint keys the file leaves out, for the robot's joint count (before the sizes)
    data = with_defaults(given, robot.arm_joints)
    check_arm_joints(p, data, robot.arm_joints, sections)
    check_problem(p, data, force_size=force_size, sections=sections)
    c = data["path"]
    planner = data.get("planner", {})
    if planner.get("turn_slide") is not None and (sections is None or "planner" in sections):
        if not is_route(c) or planner.get("method") != "roadmap":  # else it would do nothing
            raise ConfigError(p, "planner.turn_slide", "applies to a route planned with "
                              f"method: roadmap (method is {planner.get('method')})")  # fmt: skip
    # a misspelt ``waypoints`` would make a circle missing its ``center``: name the key
    check_known_keys(p, "path", c, PATH_KEYS)
    if is_route(c):
        form = schema.PATH_ROUTE_FILE if "file" in c else schema.PATH_ROUTE_WAYPOINTS
        validate(p, {"path": c}, schema.obj(path=form))
    else:
        validate(p, {"path": c}, schema.obj(path=schema.PATH_CIRCLE))
    if "payload" in data:  # optional: without it the robot is the file's, unchanged
        robot = attach_payload(robot, payload_from_section(p, data["payload"]))
    terrain = from_section(p, data["terrain"], robot)
    base_path: CirclePath | RoutePath
    if is_route(c):
        drives = sections is None or "path" in sections
        base_path = route_path_from_section(p, c, robot, terrain, on_ground=drives)
        # its run lasts the driving time, not controller.duration, and it plans every
        # planner.spacing, not planner.poses: bound those too
        n = base_path.planned_poses(data["planner"].get("spacing"))
        route_sizes = estimates(data, base_path.duration, "path", n)
        for name in ("controller", "animation", "planner"):
            est = route_sizes[name]
            why = refusal(est, force_size) if sections is None or name in sections else None
            if why is not None:
                raise ConfigError(p, est.field, why)
    else:
        base_path = CirclePath(
            center=tuple(c["center"]),
            radius=float(c["radius"]),
            start_angle=float(c["start_angle"]),
            direction=c["direction"],
        )
    _note_robot(robot_path, described, touching)  # once valid: a refusal stays one line
    return Problem(
        path=p,
        data=data,
        robot=robot,
        terrain=terrain,
        base_path=base_path,
        force_size=force_size,
    )


def load_problem(
    path: str | os.PathLike[str],
    *,
    force_size: bool = False,
    sections: Collection[str] | None = None,
) -> Problem:
    """Load and validate a problem YAML file (see :func:`problem_from_dict`).

    Raises:
        ConfigError: naming the file (problem or robot) and the field at fault.
    """
    return problem_from_dict(read_yaml(path), path, force_size=force_size, sections=sections)
