"""``mmstab record`` and ``mmstab follow``: robot recordings in, online answers out."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from mmstab.cli.status import EXIT_ARM_COLLISION, EXIT_SLIDES, EXIT_UNSTABLE
from mmstab.cli.verdicts import in_ground_line, report


def _problem(args: argparse.Namespace) -> Any:
    from mmstab.core.problem import load_problem

    return load_problem(args.problem)


def _number(value: float | None, spec: str, unit: str) -> str:
    """``value`` formatted with its unit, or ``n/a`` (no map covered the robot: no mu)."""
    return "n/a" if value is None else format(value, spec) + unit


def _record(args: argparse.Namespace) -> int | None:
    from mmstab.core.files import MmstabError, check_output_dir
    from mmstab.outputs.recording import record_route

    problem = _problem(args)
    out = Path(args.out or f"results/online/{Path(args.problem).stem}.mcap")
    check_output_dir(out.parent, f"output file {out}: folder")
    if args.duration is not None and not args.duration > 0:
        raise MmstabError(f"--duration: must be positive, got {args.duration}")
    rec = record_route(problem, out, args.duration)
    print(
        f"record: {rec.maps} maps and {rec.odometry} odometry messages over {rec.duration:.1f} s "
        f"-> {rec.path} ({rec.bytes / 1e6:.1f} MB)"
    )
    return None


def _follow(args: argparse.Namespace) -> int | None:
    from mmstab.core.files import ConfigError, MmstabError, check_output_dir
    from mmstab.outputs.online import run_follow
    from mmstab.terrain.recording import is_recording

    problem = _problem(args)
    if not is_recording(args.bag):
        raise ConfigError(args.bag, "", "not a recording (.mcap, .bag or a ROS 2 bag directory)")
    out = Path(args.out or "results/online")
    check_output_dir(out)
    if args.limit is not None and args.limit < 1:
        raise MmstabError(f"--limit: must be at least 1, got {args.limit}")
    s = run_follow(problem, args.bag, out, args.limit)  # refuses a recording without updates
    lat = s["latency_ms"]
    print(
        f"follow: {s['updates']} maps ({s['skipped_maps']} before odometry) over "
        f"{s['progress_m'][1] - s['progress_m'][0]:.2f} m of the route; map to answer p50 "
        f"{lat['p50']:.2f} ms, p99 {lat['p99']:.2f} ms, max {lat['max']:.1f} ms (to the "
        f"command p99 {s['command_latency_ms']['p99']:.2f} ms)"
    )
    print(
        f"follow: {s['replanned_poses']} pose plans on {s['updates_with_replan']} maps; robot "
        f"not on its map at {s['robot_not_covered_updates']} maps; route ahead covered "
        f"{s['covered_ahead_m']['median']:.2f} m (median), {s['covered_ahead_m']['min']:.2f} m "
        f"(least); mu min {_number(s['mu_min'], '.1f', ' N rad')}; QP failures {s['qp_failures']}"
    )
    off = s.get("offline")
    if off is not None and off["agreeing_poses"]:
        rel = off["relative_difference"]
        print(
            f"follow: against the offline plan at {off['agreeing_poses']} of {off['poses']} poses "
            f"where the map agrees: mu differs by {100 * rel['median']:.2f} % (median), "
            f"{100 * rel['max']:.2f} % (most); offline {1e3 * off['seconds_per_pose']:.1f} ms/pose"
        )
    return follow_status(s, args)


def follow_status(s: dict[str, Any], args: argparse.Namespace) -> int | None:
    """``mmstab follow``'s verdicts on stderr and its exit status (None: 0).

    As ``plan``'s: 3 tips, else 4 slides, else 5 the arm in the map's ground; each accepted by
    its ``--allow-...`` option (then a warning).
    """
    status = None
    if s["tipped"] is not None:
        t = s["tipped"]
        line = f"the robot tips over on its map at {t['time_s']:.2f} s (s = {t['s_m']:.2f} m)"
        status = report("unstable", line, "--allow-unstable", args.allow_unstable, EXIT_UNSTABLE)
    if s["slides"] is not None:
        v = s["slides"]
        line = (
            f"the tracks would slide on {v['maps']} maps, first at {v['time_s']:.2f} s (s = "
            f"{v['s_m']:.2f} m): tilt {math.degrees(v['tilt_rad']):.2f} deg beyond "
            f"{math.degrees(v['critical_tilt_rad']):.2f} deg = atan(friction {s['friction']:g})"
        )
        found = report("slides", line, "--allow-sliding", args.allow_sliding, EXIT_SLIDES)
        status = status or found
    ground = s.get("arm_in_ground")
    if ground is not None and ground["contact"]:
        line = in_ground_line(ground, "the arm is in its map's ground")
        found = report("arm collision", line, "--allow-collision", args.allow_collision,
                       EXIT_ARM_COLLISION)  # fmt: skip
        status = status or found
    return status


def add_online_commands(sub: Any) -> None:
    """``record`` (a generated recording) and ``follow`` (the online loop on a recording)."""
    h = "write the recording a robot driving the problem's route would make (maps, odometry)"
    p = sub.add_parser("record", help=h, description=h)
    p.add_argument("problem", help="route problem YAML file (e.g. problems/rough.yaml)")
    p.add_argument(
        "-o",
        "--out",
        default=None,
        help=".mcap, .bag or ROS 2 bag folder (default results/online/NAME.mcap)",
    )
    p.add_argument("--duration", type=float, default=None, help="record the first S seconds [s]")
    p.set_defaults(handler=_record)
    h = "follow a recording map by map: rest, re-plan the horizon, controller step (online)"
    p = sub.add_parser("follow", help=h, description=h)
    p.add_argument("problem", help="route problem YAML file (its online: section: topics, horizon)")
    p.add_argument(
        "--bag", required=True, help="the recording: .mcap, ROS 1 .bag or ROS 2 bag folder"
    )
    p.add_argument("-o", "--out", default=None, help="output folder (default results/online)")
    p.add_argument("--limit", type=int, default=None, help="follow only the first N maps")
    p.add_argument("--allow-unstable", action="store_true", help="exit 0 even if the robot tips")
    p.add_argument("--allow-sliding", action="store_true", help="exit 0 even if the tracks slide")
    p.add_argument(
        "--allow-collision", action="store_true", help="exit 0 even if the arm is in the ground"
    )
    p.set_defaults(handler=_follow)
