"""Collision pairs that touch at every posture, found as MoveIt's setup assistant finds them.

A spherical-wrist style zero-length link (``a = d = 0``) between two capsules makes the
capsules on either side meet at its joint whatever the angles: checked, such a pair made
every posture "collide". :func:`with_touching_allowed` adds the pairs in contact at every
one of :data:`TOUCHING_SAMPLES` sampled postures to the robot's ``collision_allow``, so no
checker built from it checks them (``mmstab.core.problem`` does it for a problem's robot and
notes the pairs on stderr). :func:`load_checked_robot` is that loader: it also refuses a
stowed posture that puts the arm into the robot or below the tracks' ground plane.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from mmstab.core.files import ConfigError
from mmstab.model.collision import CollisionChecker
from mmstab.model.parts import FLIPPER_CONTACT_TOL
from mmstab.model.plane_clearance import arm_ground_clearance
from mmstab.model.robot import Robot, load_robot

#: Postures :func:`touching_pairs` draws, uniformly within the joint limits (the stowed one is
#: added) [-]; MoveIt's setup assistant samples 10000 by default.
TOUCHING_SAMPLES = 2000
#: Seed of that draw.
TOUCHING_SEED = 0


def touching_pairs(robot: Robot) -> tuple[tuple[str, str], ...]:
    """The checked pairs in contact at the stowed posture and :data:`TOUCHING_SAMPLES` others.

    The others are drawn uniformly within the joint limits (``TOUCHING_SEED``); a pair already
    allowed (``robot.collision_allow``) is not checked. A few ms: bounding spheres first, and a
    pair stops at its first free posture.

    Returns:
        The pairs' body names (``("forearm", "wrist")``), in the checker's order.
    """
    checker = CollisionChecker(robot)
    rng = np.random.default_rng(TOUCHING_SEED)
    lo, hi = robot.joint_lower, robot.joint_upper
    q = np.vstack([robot.stowed, rng.uniform(lo, hi, (TOUCHING_SAMPLES, robot.arm_joints))])
    R, p = checker.shape_poses(q)
    rows = np.arange(len(q))
    names = [link.name for link in robot.links]
    found = []
    for pair in checker.pairs:
        if not checker._may_touch(pair, p, rows).all():
            continue
        if all(checker._fcl(pair, R, p, rows[k : k + 1])[0] for k in rows):
            other = pair.other if isinstance(pair.other, str) else names[pair.other]
            found.append((names[pair.link], other))
    return tuple(found)


def with_touching_allowed(robot: Robot) -> tuple[Robot, tuple[tuple[str, str], ...]]:
    """The robot with its always-touching pairs (:func:`touching_pairs`) allowed, and the pairs.

    ``source_hash`` is kept: the pairs follow from the description it hashes.
    """
    found = touching_pairs(robot)
    if not found:
        return robot, found
    allow = robot.collision_allow | {frozenset(pr) for pr in found}
    return dataclasses.replace(robot, collision_allow=frozenset(allow)), found


def load_checked_robot(
    path: str | os.PathLike[str],
) -> tuple[Robot, tuple[tuple[str, str], ...]]:
    """A robot file as a problem loads it: always-touching pairs allowed, the stowed arm clear.

    The stowed posture starts every plan and ends every approach: an arm stowed into the
    base, or below the plane the tracks rest on (z_B = 0, the ground on any plane, as for
    the flippers), made the roadmap refuse its start posture without saying why.

    Args:
        path: the robot's YAML file (docs/robot.md).

    Returns:
        The robot (:func:`with_touching_allowed`) and the pairs that function allowed.

    Raises:
        ConfigError: the file is invalid, or ``arm.stowed`` touches a checked pair or
            reaches below the ground.
    """
    robot, found = with_touching_allowed(load_robot(path))
    why = stowed_refusal(robot)
    if why is not None:
        raise ConfigError(Path(path), "arm.stowed", why)
    return robot, found


def stowed_refusal(robot: Robot) -> str | None:
    """Why ``robot.stowed`` cannot be a robot file's stowed posture, or None.

    The arm touches a checked pair (``collision_allow`` as given: pass the robot of
    :func:`with_touching_allowed`), or reaches below the tracks' plane z_B = 0 by more than
    the flippers' tolerance.
    """
    hits = CollisionChecker(robot).colliding_pairs(robot.stowed)
    if hits:
        return (
            f"the stowed arm touches the robot ({', '.join(hits)}); stow it clear, or allow "
            "the pair under collision.allow"
        )
    low = float(arm_ground_clearance(robot, robot.stowed)[0])
    if low < -FLIPPER_CONTACT_TOL:
        return (
            f"the stowed arm reaches {-low:.3f} m below the ground (the tracks' plane "
            "z_B = 0); raise it"
        )
    return None
