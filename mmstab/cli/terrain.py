"""Terrain commands of ``mmstab``: ``rest``, ``stability-map``, ``terrain export``."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from mmstab.cli.commands import _problem
from mmstab.core.files import refuse_degrees


# ------------------------------------------------- terrain: rest, maps, export
def _arm_posture(robot: Any, arm: list[str] | None) -> Any:
    """``--arm``: ``stowed`` (or absent) -> None; one angle [rad] per joint, within its limits."""
    import numpy as np

    from mmstab.core.files import MmstabError

    if arm is None or arm == ["stowed"]:
        return None
    n = robot.arm_joints
    try:
        q = np.array([float(a) for a in arm])
    except ValueError:
        raise MmstabError(f"--arm: expected 'stowed' or {n} angles [rad], got {arm}") from None
    if q.shape != (n,) or not np.isfinite(q).all():
        raise MmstabError(f"--arm: expected 'stowed' or {n} finite angles [rad], got {arm}")
    for i, qi in enumerate(q):
        refuse_degrees(f"--arm: joint {i}", float(qi))
    bad = np.flatnonzero((q < robot.joint_lower) | (q > robot.joint_upper))
    if bad.size:
        i = int(bad[0])
        raise MmstabError(
            f"--arm: joint {i} = {q[i]} rad is outside its limits "
            f"[{robot.joint_lower[i]}, {robot.joint_upper[i]}]"
        )
    return q


#: The sections ``mmstab rest`` and ``terrain export`` use: the others are not checked beyond
#: the schema (a route off the map, a workspace grid over the size bound do not stop them).
REST_SECTIONS = ("robot", "terrain", "payload")

#: ``mmstab rest --json``: the unit of each value of :meth:`Stance.to_json` and of the inputs
#: echoed (docs/cli.md).
REST_UNITS = {
    "roll": "rad",
    "pitch": "rad",
    "z": "m",
    "G_T_B": "m (translation column)",
    "contacts": "m",
    "support_polygon": "m",
    "mu": "N rad",
    "tilt": "rad",
    "friction": "-",
    "slip_margin": "rad",
    "pose": "x_m, y_m [m], yaw_rad [rad]",
    "arm_q_rad": "rad",
    "flipper_angle_rad": "rad",
}


def _finite(name: str, values: Sequence[float]) -> None:
    import math

    from mmstab.core.files import MmstabError

    if not all(math.isfinite(v) for v in values):
        raise MmstabError(f"{name}: must be finite, got {list(values)}")


def _rest(args: argparse.Namespace) -> None:
    import json

    import numpy as np

    from mmstab.core.files import MmstabError
    from mmstab.stability.stance import stance

    _finite("--pose", args.pose)
    refuse_degrees("--pose YAW", args.pose[2])
    if args.flipper is not None:
        _finite("--flipper", [args.flipper])
        refuse_degrees("--flipper", args.flipper)
    problem = _problem(args, REST_SECTIONS)
    flippers = problem.robot.base.flippers
    if args.flipper is not None and flippers is None:
        raise MmstabError(f"--flipper: robot {problem.robot.name} has no flippers (base.flippers)")
    limits = None if flippers is None else flippers.limits
    if args.flipper is not None and limits and not limits.lower <= args.flipper <= limits.upper:
        raise MmstabError(
            f"--flipper: {args.flipper} rad is outside base.flippers.limits "
            f"[{limits.lower}, {limits.upper}]"
        )
    q = _arm_posture(problem.robot, args.arm)
    st = stance(problem.terrain, problem.robot, args.pose, args.flipper, q)
    if args.json:
        robot = problem.robot
        echoed = {  # the inputs the stance is for, as used (stowed: the robot's angles)
            "pose": dict(zip(("x_m", "y_m", "yaw_rad"), map(float, args.pose), strict=True)),
            "arm": "stowed" if q is None else "given",
            "arm_q_rad": (robot.stowed if q is None else q).tolist(),
            # the file's angle; none for a base without flippers
            "flipper_angle_rad": args.flipper
            if args.flipper is not None
            else getattr(flippers, "angle", None),
        }
        print(json.dumps({**st.to_json(), **echoed, "units": REST_UNITS}, allow_nan=True))
        return
    np.set_printoptions(precision=4, suppress=True)
    print(
        f"rest: roll {st.roll:+.5f} rad ({np.degrees(st.roll):+.2f} deg), pitch {st.pitch:+.5f}"
        f" rad ({np.degrees(st.pitch):+.2f} deg), z {st.z:+.4f} m"
    )
    print(f"rest: mu {st.mu:.2f} N rad; flags: {', '.join(st.flags) or 'none'}")
    print(
        f"rest: tilt {np.degrees(st.tilt):.2f} deg, slides beyond "
        f"{np.degrees(st.tilt + st.slip_margin):.2f} deg (friction {st.friction:g}): slip "
        f"margin {np.degrees(st.slip_margin):+.2f} deg; limit crossed: {st.binding}"
    )
    print(
        f"rest: {len(st.contacts)} touching contact points; support polygon of "
        f"{len(st.support_polygon)} vertices (hull of the load-carrying contacts; G, m):"
    )
    print("  " + np.array2string(st.support_polygon, prefix="  "))
    print(f"rest: G_T_B =\n{st.G_T_B}")


def _stability_map(args: argparse.Namespace) -> None:
    from mmstab.core.files import MmstabError, check_output_dir
    from mmstab.outputs.stability_map import run_stability_map

    if not 0 < args.spacing < float("inf") or args.headings < 1:
        raise MmstabError("--spacing must be finite and > 0 [m] and --headings >= 1")
    problem = _problem(args)
    check_output_dir(args.out or f"results/terrain/{problem.name}")
    s = run_stability_map(problem, args.out, args.spacing, args.headings, args.force_size)
    print(
        f"stability-map: {s['poses']} poses ({s['rest_ms_per_pose']:.3f} ms/pose at rest), "
        f"stable share {s['share_stable']:.3f} (no tip {s['share_no_tip']:.3f}, "
        f"no slide {s['share_no_slide']:.3f}); cells stable at every heading "
        f"{s['cells_stable_at_every_heading']}, tipping at every heading "
        f"{s['cells_unstable_at_every_heading']}"
    )


def _terrain_export(args: argparse.Namespace) -> None:

    import numpy as np

    from mmstab.core.files import MmstabError, check_output_dir
    from mmstab.core.sizes import TERRAIN_BYTES_PER_CELL, Estimate, refusal
    from mmstab.terrain.factory import as_heightmap
    from mmstab.terrain.io import save_npz

    if Path(args.out).suffix.lower() != ".npz":
        raise MmstabError(f"-o {args.out}: the export is an .npz file")
    _finite("--size", args.size)
    _finite("--resolution", [args.resolution])
    if min(args.size) <= 0 or not args.resolution > 0:
        raise MmstabError("--size and --resolution must be positive [m]")
    cells = float(np.prod([s / args.resolution + 1.0 for s in args.size]))
    est = Estimate("--resolution", f"{cells:.3g} map cells", 0.0, cells * TERRAIN_BYTES_PER_CELL)
    why = refusal(est, force=True)  # a ramp sampled at 1e-6 m: "out of memory", naming nothing
    if why is not None:
        raise MmstabError(f"--size / --resolution: {why}")
    problem = _problem(args, REST_SECTIONS)
    check_output_dir(Path(args.out).parent, f"output file {args.out}: folder")
    hm = as_heightmap(problem.terrain, tuple(args.size), args.resolution)
    path = save_npz(args.out, hm)
    ny, nx = hm.shape
    print(f"terrain export: {nx} x {ny} cells at {hm.resolution} m -> {path}")


def _add_terrain_commands(sub: Any) -> None:
    """``rest``, ``stability-map`` and ``terrain export`` (mmstab.terrain)."""
    h = "the resting pose of the base at one pose: roll, pitch, z, contacts, polygon, mu, flags"
    p = sub.add_parser("rest", help=h, description=h)
    p.add_argument("problem", help="problem YAML file (e.g. problems/kerb.yaml)")
    p.add_argument(
        "--pose",
        nargs=3,
        type=float,
        required=True,
        metavar=("X", "Y", "YAW"),
        help="base pose [m, m, rad]: in G on a heightmap, (x, y, heading) in S on the ramp",
    )
    p.add_argument(
        "--flipper", type=float, default=None, help="flipper angle [rad], within its limits"
    )
    p.add_argument(
        "--arm", nargs="+", default=None, metavar="Q", help="'stowed' or one angle per joint [rad]"
    )
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(handler=_rest)

    h = "mu of the stowed arm over a grid of positions x headings: worst and best heading"
    p = sub.add_parser("stability-map", help=h, description=h)
    p.add_argument("problem", help="problem YAML file")
    p.add_argument("-o", "--out", default=None, help="output folder (default results/terrain/NAME)")
    p.add_argument("--spacing", type=float, default=0.25, help="grid spacing [m] (0.25)")
    p.add_argument("--headings", type=int, default=8, help="headings per cell (8)")
    p.add_argument(
        "--force-size",
        action="store_true",
        help="run a map whose time estimate exceeds the bound (not beyond the memory)",
    )
    p.set_defaults(handler=_stability_map)

    h = "terrain files"
    p = sub.add_parser("terrain", help=h, description=h)
    tsub = p.add_subparsers(dest="terrain_command", required=True, metavar="ACTION")
    h = "write the problem's terrain as .npz (elevation, resolution, origin)"
    e = tsub.add_parser("export", help=h, description=h)
    e.add_argument("problem", help="problem YAML file")
    e.add_argument("-o", "--out", required=True, help="output .npz file")
    e.add_argument(
        "--size",
        nargs=2,
        type=float,
        default=[6.0, 6.0],
        metavar=("X", "Y"),
        help="extent sampled for a ramp [m] (6 6)",
    )
    e.add_argument("--resolution", type=float, default=0.05, help="ramp cell size [m] (0.05)")
    e.set_defaults(handler=_terrain_export)
