"""Track a planned route with the QP controller: errors, mu along the run, the tip verdict.

Run from the repository's root: ``python examples/track_route.py``.
"""

import mmstab

robot = mmstab.load_robot("problems/robots/cameleon.yaml")
ramp = mmstab.Ramp(0.2)  # a 0.2 rad (11.5 deg) slope rising toward +y
route = mmstab.route_path(robot, ramp, [[0, 0], [1.5, 0], [2.5, 1]], speed=0.2, turn_radius=1.0)
plan = mmstab.plan(robot, ramp, route)
run = mmstab.track(plan).run  # the whole route, the controller's settings as planned
after = run.t >= 1.0  # after the arm's 1 s start-up move
print(f"{run.t[-1]:.1f} s simulated, {run.steps} steps of {run.dt * 1e3:.0f} ms")
print(f"QP failures: {len(run.failures)}, tipped at: {run.tipped}")
print(f"base point error max {run.base_error[after].max() * 1e3:.2f} mm")
print(f"arm-CoM error max    {run.arm_com_error[after].max() * 1e3:.2f} mm")
for name, mu in run.mu._asdict().items():  # reconfigured (planned), arm_removed, stowed
    print(f"mu {name:12} min {mu.min():6.1f}  mean {mu.mean():6.1f} N rad")
assert run.tipped is None and not run.failures and run.mu.reconfigured.min() > 0
