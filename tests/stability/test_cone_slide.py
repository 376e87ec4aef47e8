"""The friction cone's passes priced as a slide within the window (``cone_slide``).

Hand-computed against the braked robot's Coulomb slide: beyond the cone it accelerates
downhill at ``g (sin tilt - friction cos tilt)``, inside it friction stops the slide at the
same expression's magnitude.
"""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.stability.slip import cone_slide

G = 9.81  # mmstab.terrain.base.GRAVITY_G


def excess(tilt: float, friction: float = 0.7) -> float:
    return G * (np.sin(tilt) - friction * np.cos(tilt))


def test_excess_of_37_deg_against_friction_0_7():
    c = cone_slide([np.radians(37.0)], [0.0], 0.7, 1.0, rests=False)
    assert c.excess[0] == pytest.approx(0.4196, abs=1e-4)  # 9.81 (0.6018 - 0.5590)


def test_a_plane_just_beyond_the_cone_passed_quickly_holds():
    """0.4 s on a support 2 deg beyond the cone, 17.2 deg either side: 3.7 cm, under 5 cm."""
    beyond, holds = np.arctan(0.7) + np.radians(2.0), 0.3
    t = np.arange(0.0, 10.0, 0.2)
    tilt = np.full(t.size, holds)
    tilt[20:22] = beyond  # two samples: 0.4 s of the time law
    c = cone_slide(tilt, t, 0.7, 1.0)
    a, d = excess(beyond), -excess(holds)  # 0.418 m/s^2 pulling, 3.66 m/s^2 braking
    want = 0.5 * a * 0.4**2 + (a * 0.4) ** 2 / (2 * d)  # the pass, then its coast to a stop
    assert want == pytest.approx(0.0372, abs=1e-4)
    assert c.slide[20:22].max() == pytest.approx(want, rel=1e-9)
    assert c.dwell[20:22] == pytest.approx([0.2, 0.2])
    assert c.slide[:15].max() == 0.0  # before it nothing slides
    assert c.slide.max() < 0.05


def test_the_same_plane_stopped_on_slides():
    """A slow pivot there: 6.2 s on the same support. The window ending as the robot leaves
    holds a W (T - W / 2) = 2.4 m; at rest at the route's end the slide never stops."""
    beyond, holds = np.arctan(0.7) + np.radians(2.0), 0.3
    t = np.r_[np.arange(0.0, 3.9, 0.2), 4.0, 7.0, 10.0, 10.2 + np.arange(0.0, 3.9, 0.2)]
    tilt = np.where((t > 3.9) & (t < 10.1), beyond, holds)
    c = cone_slide(tilt, t, 0.7, 1.0)
    T = c.dwell[tilt > 0.5].sum()
    assert T == pytest.approx(1.6 + 3.0 + 1.6)  # half way to the neighbours' times
    a = excess(beyond)
    assert c.slide.max() >= a * 1.0 * (T - 0.5) > 2.3
    ends = cone_slide(np.r_[0.3, 0.3, beyond], [0.0, 0.2, 0.4], 0.7, 1.0)
    assert ends.slide[-1] == np.inf and ends.dwell[-1] == np.inf
    assert cone_slide(np.r_[0.3, 0.3, 0.3], [0.0, 0.2, 0.4], 0.7, 1.0).slide.max() == 0.0
