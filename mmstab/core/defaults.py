"""Defaults of the problem sections a command may not need: a problem needs what it uses.

A problem file needs ``robot``, ``terrain`` and ``path``; every other section, and every key
in it, falls back to the value below: the default problem's (``problems/ramp.yaml``, the
paper's settings), except where :data:`mmstab.core.schema.SECTION_DEFAULTS` documents
another default for a key (e.g. ``planner.method``). The merged problem is then checked
against the closed schema, so a misspelt key is still refused.
"""

from __future__ import annotations

from typing import Any

#: Section -> its default keys (``problems/ramp.yaml``'s values; a test holds them equal).
DEFAULT_SECTIONS: dict[str, dict[str, Any]] = {
    "sweep": {"samples": 100, "poses": 11, "roll_pose": [0.0, 0.0, 0.0]},
    "planner": {
        "w_stability": 0.9,
        "w_motion": 0.1,
        "poses": 10,
        "method": "sequence",
        "turret_window": 0.8,
        "sequence_candidates": 256,
        "seeding": "coarse",
        "coarse_samples": 16384,
        "coarse_basins": 4,
        "coarse_neighbours": 512,
        "coarse_seeds": 1,
        "starts": [2.0, 5.0],
        "sigma0": 0.03,
        "sigma0_unit": "diameter",
        "popsize": 8,
        "max_iterations": 4,
        "restarts": 0,
        "tol_fitness": 1e-07,
        "tol_x": 0.0001,
        "max_resample": 3,
        "seed": 7,
    },
    "controller": {
        "dt": 0.001,
        "lap_time": 30.0,
        "duration": 30.0,
        "kp": [5.0, 5.0, 5.0, 5.0, 5.0, 5.0],
        "w_a": [1.0, 1.0, 0.01, 1.0, 1.0, 1.0],
        "w_b": [1e-06, 1e-06, 0.0001, 0.0001, 0.0001, 0.0001],
        "posture_gain": [5.0, 5.0, 5.0, 5.0],
        "posture_weight": [0.001, 0.001, 0.001, 0.001],
        "plugin": "qpoases",
        "feedforward": True,
        "base_offset": 0.2,
        "approach_time": 1.0,
        "kkt_tol": 1e-06,
        "osqp": {"eps_abs": 1e-11, "eps_rel": 1e-11, "max_iter": 100000, "polish": True},
    },
    "workspace": {
        "grid": [24, 29, 25, 25],
        "precision_samples": 20000,
        "seed": 3,
        "method": "hull_difference",
    },
    "codegen": {"plugin": "box", "directory": "results/codegen"},
    "animation": {"frames": 90, "fps": 9, "width": 560, "height": 320},
}
