"""The plant: how the tracked robot moves over one control period (simulation and C).

Kinematic, as the paper's: the commanded joint speeds are the actual ones (no slip, no
dynamics). Over dt at constant q̇ the sprockets drive the base along an exact arc in the map
frame's x-y plane (v = r(θ̇_l+θ̇_r)/2, ω = r(θ̇_r−θ̇_l)/b; a chord of length v dt sin(a)/a,
a = ω dt / 2, along the mid-heading; no sideways motion) and the joints move by q̇ dt.

One CasADi Function, :func:`build_plant`, is the plant everywhere: the Python simulation
(:mod:`mmstab.runs.tracking`), the closed-loop rollouts and, exported with the controller step as
``controller_plant``, the embedded C example (:mod:`mmstab.codegen`).
"""

from __future__ import annotations

import casadi as ca

from mmstab.control.layout import JOINTS, Layout
from mmstab.model.robot import Robot

PLANT_NAME = "controller_plant"  #: the plant's Function (and C symbol) name
#: |ω dt / 2| under which sin(a)/a uses its series 1 − a²/6 [rad].
SINC_SERIES_BELOW = 1e-4


def build_plant(robot: Robot) -> ca.Function:
    """The plant as a CasADi Function.

    Args:
        robot: the robot (sprocket radius r [m], track separation b [m]).

    Returns:
        ``controller_plant`` (state (5 + n), qdot (2 + n) [rad/s], dt [s]) -> state after dt
        (5 + n), for an arm of n joints (:class:`~mmstab.control.layout.Layout`).
    """
    tracks = robot.base.tracks
    r, b = tracks.sprocket_radius, tracks.separation
    lay = Layout.of(robot)
    s, qdot, dt = ca.SX.sym("state", lay.state), ca.SX.sym("qdot", lay.joints), ca.SX.sym("dt")
    x, y, heading = s[0], s[1], s[2]
    v, w = r * (qdot[0] + qdot[1]) / 2, r * (qdot[1] - qdot[0]) / b
    half = w * dt / 2
    small = ca.fabs(half) < SINC_SERIES_BELOW
    safe = ca.if_else(small, 1.0, half)
    sinc = ca.if_else(small, 1 - half**2 / 6, ca.sin(safe) / safe)
    chord, mid = v * dt * sinc, heading + half
    nxt = ca.vertcat(x + chord * ca.cos(mid), y + chord * ca.sin(mid), heading + w * dt)
    nxt = ca.vertcat(nxt, s[JOINTS] + qdot * dt)
    return ca.Function(PLANT_NAME, [s, qdot, dt], [nxt], ["state", "qdot", "dt"], ["state_next"])
