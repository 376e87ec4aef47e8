"""The robot at rest on a heightmap: roll, pitch, mu and flags over a kerb, and a stability map.

Run from the repository's root: ``python examples/rest_on_heightmap.py [OUT.png]``.
"""

import sys

import numpy as np

import mmstab
from mmstab.stability.stance import stability_map

kerb = mmstab.load_problem("problems/kerb.yaml")  # a generated 10 cm kerb at x = 0.5 m
robot, ground = kerb.robot, kerb.terrain
print("   x [m]  roll [deg]  pitch [deg]  mu [N rad]  limit  flags")
for x in np.arange(-0.4, 1.21, 0.2):
    st = mmstab.stance(robot, ground, [x, 0.0, 0.0])  # pose (x, y, yaw) in G, the arm stowed
    print(
        f"{x:8.2f} {np.degrees(st.roll):11.2f} {np.degrees(st.pitch):12.2f} "
        f"{st.mu:11.1f}  {st.binding:5}  {','.join(st.flags) or '-'}"
    )
flat, on_edge = (mmstab.stance(robot, ground, [x, 0.0, 0.0]) for x in (-0.4, 0.2))
assert abs(flat.pitch) < 0.01 and on_edge.pitch > 0.1  # level before it, nose up on it
sm = stability_map(ground.with_robot(robot), spacing=0.25, n_headings=8)  # 0.25 m, 8 yaws
iy, ix = np.unravel_index(np.nanargmin(sm.worst), sm.worst.shape)
print(f"{sm.mu.size} resting poses: worst mu {sm.worst[iy, ix]:.1f} N rad at x {sm.x[ix]:.2f} m")
if len(sys.argv) > 1:
    import matplotlib.pyplot as plt

    plt.imshow(sm.worst, origin="lower", extent=[sm.x[0], sm.x[-1], sm.y[0], sm.y[-1]])
    plt.colorbar(label="worst mu over headings [N rad]")
    plt.savefig(sys.argv[1], dpi=100)
assert np.nanmin(sm.worst) < np.nanmedian(sm.mu)  # the kerb's edge is the weak spot
