"""The yaw-rate limit: on a slope the base turns no faster than its reference plus a margin.

A tracked base slides downhill as it turns (the skid-steer model,
:mod:`mmstab.stability.skid`: a slide per radian of turn that grows with the slope), and the
plan's time law prices the turns of its reference. The closed loop must not put more turn
into a second than that: where the heading lags (the tracks yaw at a fraction of their
command) the base point's rows ask for a fast catch-up turn and then an overshoot past the
path to pull the control point back. This limit bounds the commanded yaw rate
ω = r (θ̇_r − θ̇_l) / b to |ω| ≤ |γ̇_ref| + ``margin`` where the reference's local ground is
steeper than ``min_slope`` (no bound below it).

The QP has box bounds only, so the bound is a box on each sprocket about a common centre c:
|θ̇_l − c| ≤ h and |θ̇_r − c| ≤ h give |θ̇_r − θ̇_l| ≤ 2h, i.e. |ω| ≤ 2 h r / b for any c.
The centre is the forward speed the base point's rows ask for (ξ̇_des's point velocity
along the heading, over r; clipped to the sprockets' speed limit so the box always meets
the joint-speed limit), so the forward speed stays free within ± h r of it.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from mmstab.control.layout import SPROCKETS, ControllerParams, Layout
from mmstab.control.limits.base import Bounds, Limit, LimitContext

#: Commanded yaw rate allowed beyond the reference's [rad/s].
YAW_MARGIN = 0.25
#: Ground slope from which the limit applies [rad]: a level pivot slides nowhere, but on
#: 6-10° the unbounded catch-up slid (validation routes 11 and 30: 48° turned for the
#: path's 32°, and 2.1 rad/s of yaw for its 1.1; 12 and 17 cm in a second); below 6°, the
#: 5.7° ramp lap's, no bound.
YAW_MIN_SLOPE = np.radians(6.0)


class YawRateLimit(Limit):
    """|ω| ≤ |γ̇_ref| + margin on slopes ≥ ``min_slope``, as a box on the two sprockets."""

    name = "yaw_rate"
    reads = "xi_dot_ref[2:3] ground xi_dot_des[0:2] qdot_max[0:2]"

    def __init__(self, margin: float = YAW_MARGIN, min_slope: float = YAW_MIN_SLOPE):
        """``margin`` [rad/s] beyond the reference's turn rate, from ``min_slope`` [rad] up."""
        if margin < 0 or min_slope < 0:
            raise ValueError(f"yaw_rate: margin {margin} and min_slope {min_slope} must be >= 0")
        self.margin, self.min_slope = float(margin), float(min_slope)

    def rows(self, layout: Layout) -> tuple[int, int]:
        """The sprockets' rows."""
        return (0, SPROCKETS)

    def needs_context(self) -> bool:
        """It reads the reference's heading rate and ground and the base point's rate."""
        return True

    def bounds(
        self, state: ca.SX, params: ControllerParams, context: LimitContext | None = None
    ) -> Bounds:
        """(c − h, c + h) on both sprockets (2,) [rad/s]; ±inf below ``min_slope``."""
        assert context is not None  # needs_context: intersect refuses a call without one
        tracks = context.model.robot.base.tracks
        r, b = tracks.sprocket_radius, tracks.separation
        ref = context.reference
        roll, pitch = ref.ground[1], ref.ground[2]
        # the ground's normal tilted by roll and pitch: cos(slope) = cos(roll) cos(pitch)
        steep = ca.cos(roll) * ca.cos(pitch) <= np.cos(self.min_slope)
        yaw_max = ca.fabs(ref.xi_dot_ref[2]) + self.margin
        half = ca.if_else(steep, yaw_max * b / (2 * r), ca.inf)
        v_point = context.xi_dot_des[0:2]
        forward = v_point[0] * ca.cos(state[2]) + v_point[1] * ca.sin(state[2])
        qd = params.qdot_max[0:SPROCKETS]
        centre = ca.fmin(ca.fmax(forward / r, -qd), qd)
        return Bounds(centre - half, centre + half)
