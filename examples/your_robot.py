"""Your own robot: a tracked base without flippers carrying an arm read from URDF, on a ditch.

Run from the repository's root: ``python examples/your_robot.py``. The arm is
``examples/arm.urdf``; ``mmstab arm-from-urdf examples/arm.urdf --base base_link --tip tool``
prints the same ``arm:`` section for a robot file.
"""

import tempfile
from pathlib import Path

import numpy as np
import yaml

import mmstab
from mmstab.model.urdf_arm import arm_section, build_arm
from mmstab.terrain.generators import generate

arm = build_arm("examples/arm.urdf", base="base_link", tip="tool")  # DH rows, masses, shapes
on_body = np.eye(4)
on_body[:3, 3] = [0.1, 0.0, 0.2]  # the arm's base link on the body frame B [m]
robot_file = {
    "name": "my_robot",
    "note": "a plain tracked base and a three-joint arm from examples/arm.urdf",
    "base": {  # no flippers key: a plain tracked base
        "mass": 40.0,
        "com": [0.0, 0.0, 0.1],
        "body": {"size": [0.6, 0.4, 0.15], "center": [0.0, 0.0, 0.12]},
        "tracks": {"length": 0.65, "width": 0.1, "height": 0.18, "separation": 0.5,
                   "sprocket_radius": 0.09, "velocity_limit": 8.0},
    },
    "arm": arm_section(arm, on_body),
}  # fmt: skip
with tempfile.TemporaryDirectory() as folder:
    path = Path(folder) / "my_robot.yaml"
    path.write_text(yaml.safe_dump(robot_file))
    robot = mmstab.load_robot(path)
print(f"{robot.name}: {robot.arm_joints} joints ({', '.join(ln.name for ln in robot.links)}), "
      f"{robot.total_mass:.1f} kg")  # fmt: skip
ground = mmstab.HeightmapTerrain(generate({
    "kind": "ditch", "seed": 0, "size": [6.0, 6.0], "resolution": 0.02,
    "depth": 0.15, "width": 0.5, "distance": 0.5, "azimuth": 0.0,  # across x = 0.25-0.75 m
}))  # fmt: skip
reach = np.array([0.0, -0.3, 0.3])  # the arm held forward [rad]
print("   x [m]  pitch [deg]  mu stowed  mu reaching [N rad]  flags")
xs, mu = np.arange(-0.5, 1.51, 0.25), []
for x in xs:
    stowed, reaching = (mmstab.stance(robot, ground, [x, 0.0, 0.0], arm=q)
                        for q in (robot.stowed, reach))  # fmt: skip
    mu.append(reaching.mu)
    print(f"{x:8.2f} {np.degrees(stowed.pitch):12.2f} {stowed.mu:10.1f} {reaching.mu:13.1f}"
          f"        {','.join(stowed.flags) or '-'}")  # fmt: skip
print(f"least mu reaching forward: {min(mu):.1f} N rad, at x = {xs[np.argmin(mu)]:.2f} m")
assert 0.25 <= xs[np.argmin(mu)] <= 1.0 and min(mu) < mu[0]  # least stable: climbing out
