"""Plan the arm along a route over rough ground, in code: mu planned vs stowed, the verdicts.

Run from the repository's root: ``python examples/plan_route.py``.
"""

import dataclasses

import numpy as np

import mmstab
from mmstab.planner import route_risk
from mmstab.terrain import HeightmapTerrain
from mmstab.terrain.generators import generate
from mmstab.workspace import WorkspaceSettings

robot = mmstab.load_robot("problems/robots/cameleon.yaml")
ground = HeightmapTerrain(generate({  # 3 cm RMS on a 10 deg side slope, an 8 cm kerb
    "kind": "rough", "seed": 5, "size": [8.0, 5.0], "resolution": 0.05, "amplitude": 0.03,
    "correlation_length": 0.4, "hill_height": 0.0, "hill_radius": 1.0, "slope": 0.17,
    "azimuth": np.pi / 2,
    "features": {"kerb": {"height": 0.08, "distance": 1.5, "azimuth": 0.0}}}))  # fmt: skip
route = mmstab.route_path(robot, ground, [[-2.5, 0.0], [0.0, 0.4], [2.5, 0.4]], speed=0.25,
                          turn_radius=1.0)  # fmt: skip
settings = mmstab.Settings.defaults(robot, ground, route)  # what a file naming none gets
settings = dataclasses.replace(settings, workspace=WorkspaceSettings(grid=(12, 10, 10, 10)))
plan = mmstab.plan(robot, ground, route, settings)  # workspace (cached), the roadmap, verdicts
print(" s [m]   mu planned  stowed  removed [N rad]  arm posture [rad]")
for s, mp, ms, mr, q in zip(
    plan.s, plan.mu_planned, plan.mu_stowed, plan.mu_removed, plan.postures, strict=True
):
    print(f"{s:5.2f} {mp:12.1f} {ms:7.1f} {mr:8.1f}    {np.round(q, 2)}")
print("verdicts:", {k: v["verdict"] for k, v in plan.verdicts.items()}, "accepted:", plan.accepted)
risk = route_risk(plan, margin=450.0)  # where even the best posture keeps mu <= 450 N rad
for name, found in (("with the planned arm", risk.below_margin),
                    ("with the arm stowed only", risk.saved_by_planning)):  # fmt: skip
    print(f"below 450 N rad {name}:", ", ".join(f"{r.start_s:.2f}-{r.end_s:.2f} m" for r in found))
assert np.all(plan.mu_planned >= plan.mu_stowed - 1e-9)  # the planner never does worse
