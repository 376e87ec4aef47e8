"""Runs: closed-loop tracking simulations, rollouts, the online loop, their files and verdicts.

- ``tracking/``: the closed-loop tracking run (paper Fig. 9-12).
- ``online/``: the online loop on a robot's recorded maps (``mmstab follow``).
- ``rollout``: batched rollouts; ``store``: run files; ``recording``: runs as MCAP / ROS
  bags; ``verdict``: the safety verdicts.
"""
