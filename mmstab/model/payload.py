"""A payload held at the wrist, folded into the arm's last link.

What the gripper holds moves with the wrist, so for the arm's CoM (Eq. 1), its mass, the
overall CoM (Eq. 5) and everything built on them (workspace, planner, controller) a payload
is part of the last link: the link's mass becomes ``m + m_p`` and its CoM the mass-weighted
mean of the two, in the wrist frame. :func:`attach_payload` returns that robot; the
description's hash changes with the payload, so cached workspaces are not reused.

The problem's optional ``payload:`` section (``mass`` [kg], ``com`` [m] in the wrist frame,
optional ``wrench``: ``[fx, fy, fz [N], nx, ny, nz [N m]]`` in the body frame B at the tool
point, the wrist frame's origin) is read by :func:`payload_from_section`; the wrench rides
on the robot (``Robot.tool_wrench``) into the planner's measure and the verdicts.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import ConfigError
from mmstab.model.robot import FloatArray, Robot


class Payload(NamedTuple):
    """A point mass held at the wrist.

    Attributes:
        mass: payload mass [kg] (>= 0).
        com_wrist: its CoM in the wrist (last link's DH) frame (3,) [m].
        wrench_body: external wrench at the tool, body frame, ``[f [N], n [N m]]`` (6,),
            or None.
    """

    mass: float
    com_wrist: FloatArray
    wrench_body: FloatArray | None = None


def check_payload(
    path: str | os.PathLike[str], field: str, mass: float, com_wrist: ArrayLike
) -> Payload:
    """Validate a payload read from ``path`` (``field`` names its section).

    Raises:
        ConfigError: a negative or non-finite mass, a CoM that is not 3 finite numbers.
    """
    if not isinstance(mass, int | float) or not math.isfinite(mass) or mass < 0:
        raise ConfigError(path, f"{field}.mass", f"must be a finite mass >= 0 [kg], got {mass}")
    com = np.asarray(com_wrist, dtype=float) if np.ndim(com_wrist) == 1 else None
    if com is None or com.shape != (3,) or not np.all(np.isfinite(com)):
        raise ConfigError(path, f"{field}.com", f"must be 3 finite numbers [m], got {com_wrist!r}")
    return Payload(mass=float(mass), com_wrist=com)


def payload_from_section(path: str | os.PathLike[str], section: dict[str, Any]) -> Payload:
    """The problem's ``payload:`` section (schema-checked) as a :class:`Payload`.

    Raises:
        ConfigError: a negative or non-finite mass, a bad CoM, a wrench that is not 6
            finite numbers (one line naming the file and field).
    """
    p = check_payload(path, "payload", section["mass"], section["com"])
    if "wrench" not in section:
        return p
    w = section["wrench"]
    wrench = np.asarray(w, dtype=float) if isinstance(w, list) else None
    if wrench is None or wrench.shape != (6,) or not np.all(np.isfinite(wrench)):
        raise ConfigError(path, "payload.wrench", f"must be 6 finite numbers [N, N m], got {w!r}")
    return p._replace(wrench_body=wrench)


def attach_payload(robot: Robot, payload: Payload) -> Robot:
    """The robot with ``payload`` folded into its last arm link (a new Robot).

    The payload's wrench, if any, becomes ``Robot.tool_wrench``.
    """
    if payload.wrench_body is not None:
        robot = dataclasses.replace(robot, tool_wrench=np.asarray(payload.wrench_body, float))
    if payload.mass == 0:
        return robot
    last = robot.links[-1]
    mass = last.mass + payload.mass
    com = (last.mass * last.com + payload.mass * payload.com_wrist) / mass
    links = (*robot.links[:-1], dataclasses.replace(last, mass=mass, com=com))
    tag = f"{robot.source_hash}|payload {payload.mass!r} {payload.com_wrist.tolist()!r}"
    return dataclasses.replace(
        robot, links=links, source_hash=hashlib.sha256(tag.encode()).hexdigest()
    )
