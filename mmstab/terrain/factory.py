"""The one terrain factory: a problem's ``terrain:`` section -> a :class:`Terrain`."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from mmstab.config import ConfigError
from mmstab.robot import Robot
from mmstab.terrain.base import Terrain
from mmstab.terrain.ramp import Ramp


def _ramp(path: Path, section: Mapping[str, Any], robot: Robot | None) -> Terrain:
    return Ramp(float(section["slope"]))


#: Terrain kinds by the ``terrain.kind`` of a problem (default ``ramp``): (path, section,
#: robot) -> Terrain. New grounds register their builder here.
KINDS: dict[str, Any] = {"ramp": _ramp}


def from_section(
    path: str | Path, section: Mapping[str, Any], robot: Robot | None = None
) -> Terrain:
    """The terrain of a problem's validated ``terrain:`` section.

    Args:
        path: the problem file (for messages and relative paths).
        section: the ``terrain:`` section; ``kind`` (default ``ramp``) chooses the ground.
        robot: the robot standing on it (a ground whose resting pose depends on the robot
            binds it; the ramp does not need it).

    Raises:
        ConfigError: an unknown ``terrain.kind``.
    """
    kind = str(section.get("kind", "ramp"))
    if kind not in KINDS:
        raise ConfigError(
            Path(path), "terrain.kind", f"unknown kind {kind!r}; one of {list(KINDS)}"
        )
    return KINDS[kind](Path(path), section, robot)
