"""A stability map: mu of the stowed arm at rest over (x, y) x headings on a heightmap.

Run from the repository's root: ``python examples/stability_map.py [OUT.png]``.
"""

import sys

import numpy as np

import mmstab
from mmstab.stability.stance import stability_map

kerb = mmstab.load_problem("problems/kerb.yaml")
terrain = kerb.terrain.with_robot(kerb.robot, None, kerb.robot.stowed)  # robot, flippers, arm
sm = stability_map(terrain, spacing=0.25, n_headings=8)  # every 0.25 m, 8 yaws
print(f"{sm.mu.size} resting poses in {sm.seconds_rest * 1e3:.1f} ms")
iy, ix = np.unravel_index(np.nanargmin(sm.worst), sm.worst.shape)
print(
    f"worst mu {sm.worst[iy, ix]:.1f} N rad at x {sm.x[ix]:.2f} m, y {sm.y[iy]:.2f} m, "
    f"heading {np.degrees(sm.worst_heading[iy, ix]):.0f} deg"
)
print(f"median mu {np.nanmedian(sm.mu):.1f} N rad; high-centred poses: {np.sum(sm.flags & 1)}")
if len(sys.argv) > 1:
    import matplotlib.pyplot as plt

    ext = [sm.x[0], sm.x[-1], sm.y[0], sm.y[-1]]
    plt.imshow(sm.worst, origin="lower", extent=ext, cmap="RdYlGn")
    plt.colorbar(label="worst mu over headings [N rad]")
    plt.xlabel("x [m]"), plt.ylabel("y [m]")
    plt.savefig(sys.argv[1], dpi=100)
assert np.nanmin(sm.worst) < np.nanmedian(sm.mu)  # the kerb's edge is the weak spot
