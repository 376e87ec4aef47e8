"""Defaults of the problem sections a command may not need: a problem needs what it uses.

A problem file needs ``robot``, ``terrain`` and ``path``; every other section, and every key
in it, falls back to the value below: the default problem's (``problems/ramp.yaml``, the
paper's settings), except where :data:`SECTION_DEFAULTS` documents
another default for a key (e.g. ``planner.method``). The merged problem is then checked
against the closed schema, so a misspelt key is still refused.
"""

from __future__ import annotations

import copy
import math
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
        "arm_com_frame": "map",
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


#: Keys a problem file may omit, by section, and the value they then take: each is the
#: behaviour of files written before the key existed (``problem_from_dict`` fills them in).
SECTION_DEFAULTS: dict[str, dict[str, Any]] = {
    "planner": {
        "method": "cmaes",
        "seeding": "starts",
        "coarse_samples": 4096,
        "coarse_basins": 4,
        "coarse_neighbours": 256,
        "coarse_seeds": 1,
        "sigma0_unit": "m",
        "restarts": 0,
        "turret_window": None,
        "sequence_candidates": 256,
        "motion_cost": "joints",
        "ground_clearance": 0.02,
        "attitude_margin": None,
        "turn_slide": None,
        "climb": True,
    },
    # body, not the paper's map: on a route a base lagging its reference dragged the map-frame
    # arm CoM onto the ground (docs/physics.md, "seeded random pairs"); files written before
    # this default tracked in map (ramp.yaml and the other shipped problems name it)
    "controller": {"arm_com_frame": "body", "dynamic_fraction": 0.5},
    "workspace": {"method": "hull_difference"},
    "physics": {
        "control_dt": 0.004,
        "duration": None,
        "disagreement_angle": 0.35,
        "tip_hold": 0.8,
        "slip_distance": 0.05,
        "slip_window": 1.0,
        # share of slip_distance a route's turn may slide within slip_window: the plan slows
        # the corners that would slide more (mmstab.runs.time_law; e.g. 0.5: at most 0.63 by
        # `make skid-rates`). null: none slowed, the default: with 0.5 or 0.8 some accepted
        # validation routes still slide in MuJoCo (docs/routes.md)
        "slide_budget": None,
        # the arm over crests measured along a route plan (a record, not a verdict; costs
        # about a second a route): mmstab.runs.arm_ground
        "arm_over_crests": False,
        "check_dt": 0.02,
        "backend": "interpreted",
        "wheel": "sphere",
        "timestep": 0.004,
        "arm": "planned",
        "turn_ratio": 1.0,
        # the belts' Wong-Chiang shear modulus K [m], fitted by `make skid-fit` on the skid
        # experiment's MuJoCo runs (results/skid_fit/summary.json: shear_modulus_m)
        "shear_modulus": 0.0041,
        # how far each MuJoCo road wheel may drop below its bump stop [m]: 0, stiff wheels;
        # terrain.compliance (0.02) is the support mmstab assumes (docs/validation.md)
        "suspension_travel": "auto",
        "governor": {"slow": 0.25, "stop": 0.5, "wait_limit": 10.0},
        # a route's pivots turn about the skid model's pivot centre for the plan's CoM there
        # (mmstab.control.pivot), or about a point this far ahead of B's origin [m] (0: the origin)
        "pivot_centre": "auto",
    },
    "online": {
        "map_topic": "/elevation_mapping/elevation_map",
        "odom_topic": "/odom",
        "horizon": 2.0,
        "replan_tol": 0.01,
        "planner": "roadmap",
        "joints_topic": None,
        "record": {
            "rate": 10.0,
            "window": 6.0,
            "range": 3.0,
            "noise": 0.01,
            "unknown": 0.005,
            "odom_rate": 50.0,
            "seed": 5,
        },
    },
}


#: ``planner.method`` of a route problem, or a circle over a heightmap, that names none: the
#: posture roadmap (the arm's moves collision-free and above the ground by construction, no
#: round limit; docs/routes.md). A circle on a plane keeps the first release's ``cmaes``
#: (:data:`SECTION_DEFAULTS`): over a heightmap ``cmaes`` knows the support plane only, and a
#: seeded 1.8 m lap it planned ran its arm into the ground in MuJoCo.
ROUTE_METHOD = "roadmap"

#: ``planner`` keys of a path (route or circle) over a heightmap (``terrain.generate`` or
#: ``terrain.file``) that names none: the arm 5 cm above the ground under it [m] through a
#: 12 deg tilt of the body [rad]. With 2 cm and no margin the arm touched the ground in MuJoCo
#: on 9 of the tests' first 12 seeded random routes (docs/physics.md, "seeded random pairs");
#: with 3 deg (``kerb.yaml``'s) on none of those, but on one accepted route of
#: ``make validate-routes`` the forearm touched a bump while the body rocked 0.21 rad off its
#: predicted rest; with 12 deg no accepted route fails there (docs/validation.md). A plane
#: keeps :data:`SECTION_DEFAULTS`'s.
HEIGHTMAP_ROUTE_PLANNER: dict[str, Any] = {"ground_clearance": 0.05, "attitude_margin": 0.21}


#: Per arm joint of the default problem: the sprockets' ``w_b`` (2), then the arm's per-joint
#: values, and the workspace grid's samples of each of the 4-DoF Cameleon's joints.
SPROCKET_W_B = [1e-06, 1e-06]
ARM_W_B, POSTURE_GAIN, POSTURE_WEIGHT = 1e-04, 5.0, 1e-03
GRID_4DOF = (24, 29, 25, 25)
#: Samples of each joint beyond the fourth, before scaling (``problems/ramp_6dof.yaml``'s) [-].
GRID_EXTRA_JOINT = 13
#: Postures of the default grid of any arm: the 4-DoF grid's [-].
GRID_POSTURES = 24 * 29 * 25 * 25


def joint_defaults(arm_joints: int) -> dict[str, dict[str, Any]]:
    """The per-joint settings of an arm of ``arm_joints`` joints, by section.

    ``controller.w_b`` (2 + n: the sprockets, then 1e-4 per joint), ``posture_gain`` (5 per
    joint), ``posture_weight`` (1e-3 per joint) and ``workspace.grid``: the 4-DoF Cameleon's
    24 x 29 x 25 x 25 for its first joints and 13 per joint beyond the fourth; beyond four
    joints every count is then scaled by one factor (rounded, at least 2; the largest
    lowered while the grid is larger) so that the whole grid has at most, and about, the
    4-DoF grid's 435000 postures (5 joints: 14 x 17 x 15 x 15 x 8 = 428400): a whole grid, as
    the posture roadmap needs, built in about the 4-DoF grid's time. For 4 joints these are
    :data:`DEFAULT_SECTIONS`' values.
    """
    n = int(arm_joints)
    counts = [*GRID_4DOF[:n], *[GRID_EXTRA_JOINT] * max(0, n - len(GRID_4DOF))]
    scale = min(1.0, (GRID_POSTURES / math.prod(counts)) ** (1.0 / n))
    grid = [max(2, round(c * scale)) for c in counts]
    while math.prod(grid) > GRID_POSTURES:  # rounding up overshot: the largest count down
        grid[grid.index(max(grid))] -= 1
    return {
        "controller": {
            "w_b": [*SPROCKET_W_B, *[ARM_W_B] * n],
            "posture_gain": [POSTURE_GAIN] * n,
            "posture_weight": [POSTURE_WEIGHT] * n,
        },
        "workspace": {"grid": grid},
    }


#: The per-joint keys of a problem (:func:`joint_defaults`), as (section, key).
PER_JOINT_KEYS = (
    ("controller", "w_b"),
    ("controller", "posture_gain"),
    ("controller", "posture_weight"),
    ("workspace", "grid"),
)


def with_defaults(data: dict[str, Any], arm_joints: int | None = None) -> dict[str, Any]:
    """A copy of a problem mapping with the omitted sections and keys filled in.

    Precedence: the file's keys, then :data:`SECTION_DEFAULTS` (:data:`ROUTE_METHOD` for the
    ``planner.method`` of a route or of a circle over a heightmap,
    :data:`HEIGHTMAP_ROUTE_PLANNER` on any path over a heightmap),
    then the default problem's values (:data:`DEFAULT_SECTIONS`) for a section or key left out.
    With ``arm_joints`` (the robot's joint count), a per-joint key left out
    (:data:`PER_JOINT_KEYS`) takes :func:`joint_defaults`' value for that many joints.
    """
    out = dict(data)
    path, planner, terrain = data.get("path"), data.get("planner"), data.get("terrain")
    route = isinstance(path, dict) and ("waypoints" in path or "file" in path)
    named = planner if isinstance(planner, dict) else {}
    heightmap = isinstance(terrain, dict) and ("generate" in terrain or "file" in terrain)
    route_method = (route or heightmap) and "method" not in named
    if heightmap and isinstance(planner, (dict, type(None))):
        out["planner"] = {**HEIGHTMAP_ROUTE_PLANNER, **named}
    for name in dict.fromkeys([*DEFAULT_SECTIONS, *SECTION_DEFAULTS]):  # an order (a set has none)
        given = out.get(name, {})
        if isinstance(given, dict):
            default = {**DEFAULT_SECTIONS.get(name, {}), **SECTION_DEFAULTS.get(name, {})}
            merged = {**default, **copy.deepcopy(given)}
            for key, value in default.items():  # a partly given sub-section (controller.osqp)
                if isinstance(value, dict) and isinstance(merged[key], dict):
                    merged[key] = {**value, **merged[key]}
            out[name] = merged
    if route_method and isinstance(out.get("planner"), dict):
        out["planner"]["method"] = ROUTE_METHOD
    if arm_joints is not None:
        for name, keys in joint_defaults(arm_joints).items():
            given = data.get(name)
            given = given if isinstance(given, dict) else {}
            if not isinstance(out.get(name), dict):
                continue
            for key, value in keys.items():
                if key not in given:
                    out[name][key] = value
    return out
