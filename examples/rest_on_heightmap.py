"""The robot at rest on a heightmap: roll, pitch, mu and flags at poses over a kerb.

Run from the repository's root: ``python examples/rest_on_heightmap.py``.
"""

import numpy as np

import mmstab

kerb = mmstab.load_problem("problems/kerb.yaml")  # a generated 10 cm kerb at x = 0.5 m
print("   x [m]  roll [deg]  pitch [deg]  mu [N rad]  limit  flags")
for x in np.arange(-0.4, 1.21, 0.2):
    st = mmstab.stance(kerb.terrain, kerb.robot, [x, 0.0, 0.0])  # pose (x, y, yaw) in G
    print(
        f"{x:8.2f} {np.degrees(st.roll):11.2f} {np.degrees(st.pitch):12.2f} "
        f"{st.mu:11.1f}  {st.binding:5}  {','.join(st.flags) or '-'}"
    )
flat, on_edge = (mmstab.stance(kerb.terrain, kerb.robot, [x, 0.0, 0.0]) for x in (-0.4, 0.2))
assert abs(flat.pitch) < 0.01 and on_edge.pitch > 0.1  # level before it, nose up on it
