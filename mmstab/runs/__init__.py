"""Runs: closed-loop tracking simulations, rollouts, their files and verdicts.

- ``tracking/``: the closed-loop tracking run (paper Fig. 9-12).
- ``rollout``: batched rollouts; ``store``: run files; ``verdict``: the safety verdicts.
"""
