"""JSON schemas of the robot description and of a problem file.

Every key is required (except the few marked optional, whose default is documented) and
no other key is allowed, so that a typo is an error and a saved problem says everything a
run depended on. Units: metres, radians, kg, seconds.
Semantic checks the schema cannot express (inverted limits, a flipper under the
ground) live beside the loaders.
"""

from __future__ import annotations

from typing import Any

#: ``planner.method``: the names of the planner's searches (``mmstab.planner.searches.SEARCHES``
#: registers one search per name; a test keeps both equal).
PLANNER_METHODS = ("cmaes", "exhaustive", "sequence", "roadmap")

NUM: dict[str, Any] = {"type": "number"}
POS: dict[str, Any] = {"type": "number", "exclusiveMinimum": 0}
NONNEG: dict[str, Any] = {"type": "number", "minimum": 0}
INT_POS: dict[str, Any] = {"type": "integer", "minimum": 1}
SEED: dict[str, Any] = {"type": "integer", "minimum": 0}
VEC2: dict[str, Any] = {"type": "array", "items": NUM, "minItems": 2, "maxItems": 2}
VEC3: dict[str, Any] = {"type": "array", "items": NUM, "minItems": 3, "maxItems": 3}
VEC3_POS: dict[str, Any] = {"type": "array", "items": POS, "minItems": 3, "maxItems": 3}
VEC4: dict[str, Any] = {"type": "array", "items": NUM, "minItems": 4, "maxItems": 4}
WEIGHT01: dict[str, Any] = {"type": "number", "minimum": 0, "maximum": 1}
#: An angle [rad]: ``unit`` (ignored by jsonschema) makes :func:`mmstab.core.files.validate`
#: refuse ``|value| > 2 pi`` as degrees, naming the unit, and add ``[rad]`` to a bound's message.
RAD: dict[str, Any] = {"type": "number", "unit": "rad"}
VEC3_RAD: dict[str, Any] = {"type": "array", "items": RAD, "minItems": 3, "maxItems": 3}


def angle(**bounds: float) -> dict[str, Any]:
    """An angle [rad] with JSON-schema bounds (``minimum=0, maximum=1.2``)."""
    return {**RAD, **bounds}


def obj(**props: Any) -> dict[str, Any]:
    """A closed object schema: all ``props`` required, nothing else allowed."""
    return {
        "type": "object",
        "properties": props,
        "required": list(props),
        "additionalProperties": False,
    }


#: The most arm joints a robot file may list (the QP has 2 + n variables).
MAX_ARM_JOINTS = 12


def with_optional(schema: dict[str, Any], **props: Any) -> dict[str, Any]:
    """A closed object schema with extra keys that may be left out (their default applies)."""
    return {**schema, "properties": {**schema["properties"], **props}}


def vec(n: int, item: dict[str, Any] = NUM) -> dict[str, Any]:
    """Array of exactly ``n`` items."""
    return {"type": "array", "items": item, "minItems": n, "maxItems": n}


def vec_min(n: int, item: dict[str, Any] = NUM) -> dict[str, Any]:
    """Array of at least ``n`` items."""
    return {"type": "array", "items": item, "minItems": n}


#: Largest length or coordinate [m] and mass [kg] of a robot file. Generous for a tracked
#: mobile manipulator (the Cameleon: 0.7 m, 58 kg); beyond them a mistyped value (a body
#: centre at 1e300 m) broke the route's footprint sampling with a NumPy error.
MAX_ROBOT_SIZE, MAX_ROBOT_MASS = 100.0, 1e6
M: dict[str, Any] = {"type": "number", "minimum": -MAX_ROBOT_SIZE, "maximum": MAX_ROBOT_SIZE}
M_POS: dict[str, Any] = {**POS, "maximum": MAX_ROBOT_SIZE}
KG: dict[str, Any] = {**POS, "maximum": MAX_ROBOT_MASS}
VEC3_M, VEC3_M_POS = vec(3, M), vec(3, M_POS)

BOX = obj(type={"const": "box"}, size=VEC3_M_POS, center=VEC3_M, rpy=VEC3_RAD)
CAPSULE = obj(type={"const": "capsule"}, radius=M_POS, p0=VEC3_M, p1=VEC3_M)

LINK = obj(
    name={"type": "string", "minLength": 1},
    dh=obj(a=M, alpha=RAD, d=M, theta_offset=RAD),
    mass=KG,
    com=VEC3_M,
    geometry={"oneOf": [BOX, CAPSULE]},
    limits=obj(lower=RAD, upper=RAD, velocity=POS),
)

ROBOT = obj(
    name={"type": "string", "minLength": 1},
    note={"type": "string"},
    base=with_optional(
        obj(
            mass=KG,
            com=VEC3_M,
            body=obj(size=VEC3_M_POS, center=VEC3_M),
            tracks=obj(
                length=M_POS,
                width=M_POS,
                height=M_POS,
                separation=M_POS,
                sprocket_radius=M_POS,
                velocity_limit=POS,
            ),
        ),
        # optional: a base without flippers (a plain tracked base) leaves the section out
        flippers=with_optional(
            obj(length=M_POS, width=M_POS, thickness=M_POS, pivot=VEC3_M, angle=RAD),
            # optional: the range [rad] and rate [rad/s] the planner may move them in
            # (planner.flipper_angles); not part of the description's hash (no cache uses it)
            limits=obj(lower=RAD, upper=RAD, rate=POS),
        ),
        # optional: a rear pair, hinged at pivot (the left one), angle 0 pointing backward;
        # it stays at its angle (the planner and --flipper move the front pair)
        rear_flippers=obj(length=M_POS, width=M_POS, thickness=M_POS, pivot=VEC3_M, angle=RAD),
    ),
    arm=obj(
        mount=obj(xyz=VEC3_M, rpy=VEC3_RAD),
        # any number of joints (the 4-DoF Cameleon, a 6-DoF variant: robots/cameleon_6dof.yaml)
        links={"type": "array", "items": LINK, "minItems": 1, "maxItems": MAX_ARM_JOINTS},
        stowed=vec_min(1, RAD),  # one angle per link
    ),
)
#: Optional ``collision:`` of a robot file: pairs of bodies (arm link names, or the base parts
#: ``body``, ``track_left``, ``track_right``, ``flipper_left``, ``flipper_right``) never checked
#: against each other, as MoveIt's SRDF ``disable_collisions`` (docs/urdf.md).
COLLISION: dict[str, Any] = {
    "type": "object",
    "properties": {"allow": {"type": "array", "items": vec(2, {"type": "string", "minLength": 1})}},
    "additionalProperties": False,
}
ROBOT = with_optional(ROBOT, collision=COLLISION)

# One entry per pipeline stage; a problem file has every section.
PROBLEM_SECTIONS: dict[str, dict[str, Any]] = {
    "robot": {"type": "string", "minLength": 1},
    "terrain": {"type": "object"},  # one of three forms: mmstab.terrain.factory
    "path": {"type": "object"},  # a circle or a route: PATH_CIRCLE | PATH_ROUTE (problem.py)
    "sweep": obj(
        samples={"type": "integer", "minimum": 8},
        poses={"type": "integer", "minimum": 1},
        roll_pose=VEC3,
    ),
    "planner": with_optional(  # CMA-ES or exhaustive arm-CoM planner, Eq. 6 (docs/planner.md)
        obj(
            w_stability=WEIGHT01,
            w_motion=WEIGHT01,
            poses=INT_POS,
            starts={"type": "array", "items": NUM, "minItems": 1},
            sigma0=POS,
            popsize={"type": "integer", "minimum": 2},
            max_iterations=INT_POS,
            tol_fitness=POS,
            tol_x=POS,
            max_resample=INT_POS,
            seed=SEED,
            method={"enum": list(PLANNER_METHODS)},
            seeding={"enum": ["starts", "coarse"]},
            coarse_samples={"type": "integer", "minimum": 16},
            coarse_basins=INT_POS,
            coarse_neighbours={"type": "integer", "minimum": 0},
            coarse_seeds=INT_POS,
            sigma0_unit={"enum": ["m", "diameter"]},
            restarts={"type": "integer", "minimum": 0, "maximum": 8},
            turret_window={
                "oneOf": [{"type": "null"}, angle(exclusiveMinimum=0)]
            },  # [rad]; null: unbounded
            sequence_candidates={"type": "integer", "minimum": 1, "maximum": 4096},
            motion_cost={"enum": ["com", "joints"]},  # method roadmap's motion term
            # method roadmap: least height [m] of the arm above the plane the tracks rest on
            # (z_B = 0); null: not checked (docs/roadmap.md, "Ground clearance")
            ground_clearance={"oneOf": [{"type": "null"}, NONNEG]},
            # method roadmap on terrain: the arm clears the ground through the body's tilts
            # up to this [rad] about its origin; null: off (docs/roadmap.md)
            attitude_margin={"oneOf": [{"type": "null"}, angle(minimum=0, maximum=0.5)]},
            # method roadmap on a route: the slide [m] a turn may cost with the chosen
            # postures; null: off (docs/roadmap.md)
            turn_slide={"oneOf": [{"type": "null"}, NONNEG]},
            climb={"type": "boolean"},  # the climb limit at a route's steps (roadmap)
        ),
        margin=NUM,  # optional: a plan is stable when every pose's mu > margin [N rad]; 0
        # optional: flipper angles searched per pose between the robot's flipper limits,
        # rate-limited along the path (docs/levers.md); 0 = flippers fixed (the default)
        flipper_angles={"type": "integer", "minimum": 0, "maximum": 64},
        # optional, routes: planned poses this far apart [m]; 0.5; at least 1 mm (a 10 km
        # route then plans 1e7 poses, refused by the size bounds without --force-size)
        spacing={"type": "number", "minimum": 1e-3},
    ),
    "controller": obj(  # tracking controller, paper Eq. 7-8 (mmstab/control/controller.py)
        dt=POS,
        lap_time=POS,
        duration=POS,
        kp=vec(6, POS),
        w_a=vec(6, NONNEG),
        w_b=vec_min(3, POS),  # per joint: 2 sprockets + the arm's n (checked at load)
        posture_gain=vec_min(1, NONNEG),  # per arm joint (n, checked at load)
        posture_weight=vec_min(1, NONNEG),
        plugin={"enum": ["qpoases", "osqp", "qrqp", "daqp", "box"]},
        feedforward={"type": "boolean"},
        base_offset=NONNEG,
        approach_time=NONNEG,
        kkt_tol=POS,
        osqp=obj(eps_abs=POS, eps_rel=NONNEG, max_iter=INT_POS, polish={"type": "boolean"}),
        # the arm-CoM task's frame: map (paper Eq. 7) or body (docs/controller.md)
        arm_com_frame={"enum": ["map", "body"]},
        # the arm's time law: along the reference the dynamic mu keeps this share of the
        # static mu (mmstab/control/timing.py); null: off
        dynamic_fraction={"oneOf": [{"type": "null"}, {**NONNEG, "maximum": 1}]},
    ),
    "workspace": with_optional(
        obj(
            grid=vec_min(1, {"type": "integer", "minimum": 2}),  # per arm joint (checked at load)
            precision_samples=INT_POS,
            seed=SEED,
            method={"enum": ["hull_difference", "valid_samples"]},  # the planner's region
        ),
        # optional: grid postures drawn (seeded by seed) when the full grid is over the size
        # bound (mmstab.core.sizes.workspace_postures); left out: the whole grid
        samples=INT_POS,
    ),
    "codegen": obj(  # the controller step as generated C (mmstab/codegen.py)
        plugin={"enum": ["qpoases", "osqp", "qrqp", "daqp", "box"]},  # qpoases: refused, clearly
        directory={"type": "string", "minLength": 1},
    ),
    "animation": obj(  # make animation: the tracking run as a GIF
        frames={"type": "integer", "minimum": 2},
        fps={"type": "integer", "minimum": 1, "maximum": 50},
        width={"type": "integer", "minimum": 64, "maximum": 1920},
        height={"type": "integer", "minimum": 64, "maximum": 1080},
    ),
}


# The ``path:`` section: a circle on the ground, or a route (``mmstab.paths.route``), told
# apart by ``waypoints`` / ``file``.
PATH_CIRCLE = obj(center=VEC2, radius=POS, start_angle=RAD, direction={"enum": ["ccw", "cw"]})
_ROUTE_BASE = with_optional(
    obj(
        speed={**POS, "description": "the reference speed on straight lines [m/s]"},
        turn_radius={**NONNEG, "description": "the corners' arc radius [m]; 0 pivots on the spot"},
    ),
    acceleration=POS,  # optional [m/s^2], default 0.3
    lateral_acceleration=POS,  # optional [m/s^2], default 0.3
)
#: waypoints in the map frame [m] (at least two: checked by the route builder, by name)
PATH_ROUTE_WAYPOINTS = with_optional(
    {**_ROUTE_BASE, "required": [*_ROUTE_BASE["required"], "waypoints"]},
    waypoints={
        "type": "array",
        "items": VEC2,
        "description": "the route's corners [[x, y], ...] in the map frame [m]",
    },
)
#: a CSV file of ``x,y[,yaw]`` lines, relative to the problem file
PATH_ROUTE_FILE = with_optional(
    {**_ROUTE_BASE, "required": [*_ROUTE_BASE["required"], "file"]},
    file={"type": "string", "minLength": 1},
)


# The tip-over envelope atlas (python -m experiments atlas; docs/atlas.md). An axis is a list
# of values or an evenly spaced range (a full-turn heading range omits its end); every axis
# is optional.
_RANGE = obj(start=NUM, stop=NUM, num={"type": "integer", "minimum": 1, "maximum": 10000})
_AXIS = {"oneOf": [{"type": "array", "items": NUM, "minItems": 1, "maxItems": 10000}, _RANGE]}
_FLIPPER = {"oneOf": [NUM, {"enum": ["robot", "ground"]}]}
ATLAS: dict[str, Any] = {
    "type": "object",
    "properties": {
        "axes": {
            "type": "object",
            "properties": {
                "slope": _AXIS,  # [rad], increasing, within terrain.slope's bounds
                "heading": _AXIS,  # [rad] about the slope normal; 0 = across, pi/2 = uphill
                "flipper_angle": {"type": "array", "items": _FLIPPER, "minItems": 1},
                "robots": {  # robot files, relative to the problem file
                    "type": "array",
                    "items": {"type": "string", "minLength": 1},
                    "minItems": 1,
                },
                "payload": _AXIS,  # [kg] at the wrist, increasing, >= 0
                "terrain_seeds": {"type": "array", "items": SEED, "minItems": 1},  # generator
            },
            "additionalProperties": False,
        },
        # the payload's CoM in the wrist frame [m] (default its origin)
        "payload_com": {"type": "array", "items": NUM, "minItems": 3, "maxItems": 3},
        "chunks": obj(slope=INT_POS, heading=INT_POS),  # cells per stored chunk, per axis
        "margin": NUM,  # [N rad]: the operator's envelope keeps mu >= margin
    },
    "required": ["axes", "chunks", "margin"],
    "additionalProperties": False,
}

# A payload held at the wrist and an optional wrench at the tool (docs/levers.md); left out:
# no payload. ``com`` is in the wrist (last DH) frame; ``wrench`` is [fx, fy, fz [N],
# nx, ny, nz [N m]] in the body frame B, acting at the tool point (the wrist frame's origin).
PAYLOAD: dict[str, Any] = with_optional(obj(mass=NUM, com=VEC3), wrench=vec(6))

# make levers (docs/levers.md): the experiments' own settings.
LEVERS: dict[str, Any] = with_optional(
    obj(
        margin=NUM,  # [N rad]: "safe" / "holds" means mu >= margin
        speeds=vec_min(1, POS),  # lap-speed factors of the dynamic-mu comparison (1 = lap_time)
        samples=INT_POS,  # samples along one lap for the dynamic measure
        side_slope=angle(minimum=0, maximum=1.2),  # [rad]: payload, flippers
        max_payload=POS,  # [kg]: the payload bisection's upper bracket
        payload_com=VEC3,  # [m]: the payload's CoM in the wrist frame
        payload_reach=NONNEG,  # [m]: "held at the front/side": the tool this far beyond the tracks
        bisection_steps=INT_POS,  # steps of every bisection
        max_slope=angle(exclusiveMinimum=0, maximum=1.2),  # [rad] bracket
        robots={"type": "array", "items": {"type": "string", "minLength": 1}, "minItems": 1},
        variant_grid=vec(4, {"type": "integer", "minimum": 2}),  # workspace grid of the variants
        flipper_angles={"type": "integer", "minimum": 1, "maximum": 64},  # per pose (planner key)
    ),
    # optional: a problem file (relative to this one) whose terrain and circle give the
    # variants' rough-ground lap; left out: no rough column
    rough_problem={"type": "string", "minLength": 1},
)

# Online mode (mmstab follow, mmstab record; docs/online.md): topics, the receding horizon
# [m] ahead of the robot, the gravity change [rad] that re-plans a horizon pose, how a pose
# is planned (roadmap: nodes of the posture roadmap; warm: CMA-ES in V), the arm's measured
# JointState topic (null: the loop integrates its commands), and the generated recording:
# map rate [Hz], window side [m], sensor range [m], height noise (RMS) [m], fraction of
# cells dropped as unknown, odometry rate [Hz], seed.
ONLINE = obj(
    map_topic={"type": "string", "pattern": "^/"},
    odom_topic={"type": "string", "pattern": "^/"},
    horizon=POS,
    replan_tol=angle(exclusiveMinimum=0),
    planner={"enum": ["roadmap", "warm"]},
    joints_topic={"oneOf": [{"type": "null"}, {"type": "string", "pattern": "^/"}]},
    record=obj(
        rate={"type": "number", "exclusiveMinimum": 0, "maximum": 1000},
        window={"type": "number", "exclusiveMinimum": 0, "maximum": 100},
        range=POS,
        noise=NONNEG,
        unknown={"type": "number", "minimum": 0, "maximum": 0.9},
        odom_rate={"type": "number", "exclusiveMinimum": 0, "maximum": 1000},
        seed=SEED,
    ),
)

# The controller in the loop on the whole robot in MuJoCo (mmstab simulate; docs/physics.md):
# control period [s], simulated time [s] (null: the controller's / the route's), the chassis
# tilt off the predicted rest reported as a disagreement [rad], how long the contacts may lose
# the support before it is a tip [s], the downhill drift [m] over a window [s] that is a
# slide, the share of it a route's turn may use (the plan slows the turns that would use
# more; null: none slowed), the period of those checks [s], the controller step's backend,
# the road wheels' collision shape, MuJoCo's integration step [s] (docs/physics.md, "Model
# choices"), the arm: the plan's postures or held stowed, the drive layer's turn ratio (level-ground
# achieved / kinematic yaw rate, in (0, 1]; auto: the skid model's pivot), and the reference
# governor (the base error [m] from which the reference slows, at which it stops, and the
# wait [s] after which the run ends stalled; null: the reference runs on time), where a
# route's pivots turn (auto: the skid model's pivot centre for the plan's CoM; or a distance
# ahead of B's origin [m], 0: about the origin), and how far the road wheels may drop below
# their bump stops [m] (0: stiff wheels).
PHYSICS_KEYS = obj(
    control_dt={"type": "number", "exclusiveMinimum": 0, "maximum": 0.1},
    duration={"oneOf": [{"type": "null"}, POS]},
    disagreement_angle=angle(exclusiveMinimum=0, maximum=1.5),
    tip_hold={"type": "number", "minimum": 0, "maximum": 10},
    slip_distance=POS,
    slip_window=POS,
    slide_budget={"oneOf": [{"type": "null"}, {**POS, "maximum": 1}]},
    arm_over_crests={"type": "boolean"},
    check_dt=POS,
    backend={"enum": ["interpreted", "generated"]},
    wheel={"enum": ["sphere", "cylinder", "sphere_pair"]},
    timestep={"type": "number", "exclusiveMinimum": 0, "maximum": 0.01},
    arm={"enum": ["planned", "stowed"]},
    turn_ratio={"oneOf": [{"const": "auto"}, {**POS, "maximum": 1}]},
    shear_modulus={"type": "number", "minimum": 0, "maximum": 1},
    suspension_travel={
        "oneOf": [{"const": "auto"}, {"type": "number", "minimum": 0, "maximum": 0.2, "unit": "m"}]
    },
    governor={"oneOf": [{"type": "null"}, obj(slow=POS, stop=POS, wait_limit=NONNEG)]},
    pivot_centre={
        "oneOf": [{"const": "auto"}, {"type": "number", "minimum": -0.5, "maximum": 0.5}]
    },
)
# ``tip_angle``: the former name of ``disagreement_angle``, still read from older files
PHYSICS = with_optional(PHYSICS_KEYS, tip_angle=angle(exclusiveMinimum=0, maximum=1.5))

#: Sections a problem may leave out; the command that needs one says so when it is missing.
OPTIONAL_SECTIONS: dict[str, dict[str, Any]] = {
    "physics": PHYSICS,
    "online": ONLINE,
    "atlas": ATLAS,
    "payload": PAYLOAD,
    "levers": LEVERS,
}


def problem_schema() -> dict[str, Any]:
    """The closed schema of a whole problem file."""
    schema = obj(**PROBLEM_SECTIONS)
    schema["properties"].update(OPTIONAL_SECTIONS)
    return schema


def obj_optional(props: dict[str, Any]) -> dict[str, Any]:
    """A closed object schema whose keys are all optional."""
    return {"type": "object", "properties": props, "additionalProperties": False}
