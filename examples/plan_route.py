"""Plan the arm along a route over rough ground: mu planned vs stowed, the risk stretches.

Run from the repository's root: ``python examples/plan_route.py``.
"""

import numpy as np

import mmstab
from mmstab.planner import route_risk

problem = mmstab.load_problem("examples/bumpy_route.yaml")
plan = mmstab.plan(problem)  # the arm-CoM workspace (cached), then the whole route at once
print(" s [m]   mu planned  stowed  removed [N rad]  arm posture [rad]")
for s, mp, ms, mr, q in zip(
    plan.s, plan.mu_planned, plan.mu_stowed, plan.mu_removed, plan.postures, strict=True
):
    print(f"{s:5.2f} {mp:12.1f} {ms:7.1f} {mr:8.1f}    {np.round(q, 2)}")
risk = route_risk(plan, margin=450.0)  # where even the best posture keeps mu <= 450 N rad
print(
    "below 450 N rad with the planned arm:",
    [(round(r.start_s, 2), round(r.end_s, 2)) for r in risk.below_margin],
)
print(
    "below it with the arm stowed only:",
    [(round(r.start_s, 2), round(r.end_s, 2)) for r in risk.saved_by_planning],
)
assert np.all(plan.mu_planned >= plan.mu_stowed - 1e-9)  # the planner never does worse
