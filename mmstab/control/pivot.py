"""Where a skid-steered base pivots: the centres of a route's pivot turns.

A route's pivot (``turn_radius: 0``, or a corner whose arc does not fit) turns the heading
on the spot. A skid-steered base does not turn about B's origin: its belts slide sideways
about the point where the sideways friction balances, near the centre of mass. mmstab's skid
model (:func:`mmstab.stability.skid.skid_twist`) places that point: on level ground, the belts
at equal and opposite speeds, B's origin moves sideways at −ω · x_c, x_c the pivot centre's
distance ahead of it (6.2 cm for the Cameleon with the arm stowed, its CoM 4.9 cm ahead; 12 cm
with the CoM 10 cm ahead; −7.5 cm with the arm swung back, the CoM 6.1 cm behind). A pivot
*about the origin* is then a reference the base cannot follow: its origin swings on a circle
of radius x_c about the true centre, and a controller that holds a point ahead of the origin
on the swung reference turns the heading past it and drives off the corner to catch up.

:func:`route_pivot_centres` gives each pivot of a route the skid model's centre for the CoM
the plan has there (the arm's target at the pivot's start and end, averaged); the route then
turns about that point on the waypoint (:meth:`mmstab.paths.route.RoutePath.with_pivot_centres`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray, Robot
from mmstab.paths.route import RoutePath
from mmstab.stability.skid import skid_twist, track_patch

#: Belt speed of the model's pivot [m/s] (the model is homogeneous in the belt speeds).
PIVOT_BELT_SPEED = 0.1


def pivot_centre(robot: Robot, com_body: ArrayLike) -> FloatArray:
    """The skid model's level pivot centre: its distance ahead of B's origin on x_B [m].

    Args:
        robot: the robot (its belts' contact patch).
        com_body: the overall CoM in B (3,) or (N, 3) [m].

    Returns:
        x_c (N,) [m]: B's origin moves sideways at −ω x_c while the base pivots at ω (the
        friction coefficient scales every force alike, so it does not enter).
    """
    com = np.atleast_2d(np.asarray(com_body, dtype=float))
    belts = np.tile([-PIVOT_BELT_SPEED, PIVOT_BELT_SPEED], (len(com), 1))
    level = np.tile([0.0, 0.0, -9.81], (len(com), 1))
    twist = skid_twist(track_patch(robot), level, com, belts, friction=1.0)
    return np.asarray(-twist.velocity_body[:, 1] / twist.yaw_rate, dtype=float)


def route_pivot_centres(robot: Robot, path: RoutePath, plan: Any) -> FloatArray:
    """Each pivot's centre [m] ahead of B's origin, for the plan's CoM there (P,).

    Args:
        robot: the robot.
        path: the route (its pivots, and the time fractions they take).
        plan: the arm plan (``fractions`` (K,) in [0, 1), ``target_com`` (K, 3) in B [m]).
    """
    spans = path.route.pivot_spans
    if not len(spans):
        return np.zeros(0)
    f = np.asarray(plan.fractions, dtype=float)
    target = np.asarray(plan.target_com, dtype=float)
    u = path.fraction_of_s(spans.ravel())  # each pivot's start and end
    arm = np.column_stack([np.interp(u, f, target[:, i]) for i in range(3)])
    com = robot.overall_com(arm).reshape(len(spans), 2, 3).mean(axis=1)
    return pivot_centre(robot, com)


def pivoting(problem: Problem, plan: Any, centre: float | str) -> Problem:
    """The problem with its route's pivots about their centres (``physics.pivot_centre``).

    ``auto``: each pivot about the skid model's centre for the plan's CoM there
    (:func:`route_pivot_centres`); a number: every pivot about the point
    that far ahead of B's origin [m]; 0, or a path without pivots: the problem as it is.
    """
    path = problem.base_path
    if not isinstance(path, RoutePath) or path.limits is None or not len(path.route.pivot_spans):
        return problem
    spans = len(path.route.pivot_spans)
    if centre == "auto":
        centres = route_pivot_centres(problem.robot, path, plan)
    else:
        centres = np.full(spans, float(centre))
    if not np.any(centres):
        return problem
    return dataclasses.replace(problem, base_path=path.with_pivot_centres(centres))
