"""A problem file: robot, ramp, path and the settings of every stage, validated at load.

The robot is given by a path relative to the problem file. ``load_problem`` is the one
place where a problem's inputs are checked; stages read their section from
``Problem.section(name)`` and trust it.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mmstab import schema
from mmstab.codegen import check_settings as _check_codegen
from mmstab.config import ConfigError, read_yaml, validate
from mmstab.controller import check_settings as _check_controller
from mmstab.robot import Robot, load_robot
from mmstab.terrain import CirclePath, Terrain, from_section

#: Semantic checks of a section beyond the schema: (problem path, section) -> None or raise.
SECTION_CHECKS: dict[str, Callable[[Path, dict[str, Any]], None]] = {}
SECTION_CHECKS["controller"] = _check_controller
SECTION_CHECKS["codegen"] = _check_codegen


@dataclass(frozen=True)
class Problem:
    """A validated problem.

    Attributes:
        path: the problem file.
        data: its validated content (sections by name).
        robot: the robot it names.
        terrain: the ground (:func:`mmstab.terrain.from_section` of the ``terrain:`` section).
        circle: the base reference path, in the terrain's map frame.
    """

    path: Path
    data: dict[str, Any]
    robot: Robot
    terrain: Terrain
    circle: CirclePath

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


def problem_from_dict(data: dict[str, Any], path: str | os.PathLike[str]) -> Problem:
    """Validate a problem mapping read from ``path`` (robot path relative to it)."""
    p = Path(path)
    data = schema.with_defaults(data)
    validate(p, data, schema.problem_schema())
    robot_path = (p.parent / data["robot"]).resolve()
    if not robot_path.is_file():
        raise ConfigError(p, "robot", f"no robot description at {robot_path}")
    for name, check in SECTION_CHECKS.items():
        check(p, data[name])
    c = data["path"]
    robot = load_robot(robot_path)
    return Problem(
        path=p,
        data=data,
        robot=robot,
        terrain=from_section(p, data["terrain"], robot),
        circle=CirclePath(
            center=tuple(c["center"]),
            radius=float(c["radius"]),
            start_angle=float(c["start_angle"]),
            direction=c["direction"],
        ),
    )


def load_problem(path: str | os.PathLike[str]) -> Problem:
    """Load and validate a problem YAML file.

    Raises:
        ConfigError: naming the file (problem or robot) and the field at fault.
    """
    return problem_from_dict(read_yaml(path), path)
