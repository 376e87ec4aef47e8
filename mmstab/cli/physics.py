"""``mmstab simulate``: the tracking run in MuJoCo with the controller in the loop."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mmstab.cli.status import EXIT_ARM_COLLISION, EXIT_SLIDES, EXIT_UNSTABLE
from mmstab.cli.verdicts import high_centred_warning, report, timing_line


def _simulate(args: argparse.Namespace) -> int | None:
    from mmstab.core.files import MmstabError, check_output_dir
    from mmstab.core.problem import load_problem
    from mmstab.outputs.simulate import run_simulate

    problem = load_problem(args.problem)
    out = Path(args.out or "results/physics")
    check_output_dir(out)
    if args.duration is not None and not args.duration > 0:
        raise MmstabError(f"--duration: must be positive, got {args.duration}")
    _check_duration(args, problem)
    s = run_simulate(problem, out, args.duration, args.arm, gif=args.gif)
    print(
        f"simulate: {s['duration_s']:.2f} s in MuJoCo ({s['backend']} controller, "
        f"{s['arm']} arm, {s['model']['wheel']} wheels) at "
        f"{s['real_time_factor']:.1f}x real time ({s['real_time_factor_cpu']:.1f}x in CPU time); "
        f"base error max {s['base_error_max_m']:.3f} m "
        f"(body origin {s['base_origin_error_max_m']:.3f} m), "
        f"arm CoM {s['arm_com_error_max_m']:.3f} m; QP failures {s['qp_failures']}"
    )
    d = s["mu_difference"]
    print(
        f"simulate: mu min predicted {s['mu_predicted_min']:.1f}, simulated "
        f"{s['mu_simulated_min']:.1f} N rad (median difference {d['median_abs']:.1f} N rad); "
        f"tilt off rest max {_rad(s['tilt_off_rest_max_rad'])}; downhill drift max "
        f"{s['downhill_drift_max_m']:.3f} m per {s['slip_window_s']:g} s"
    )
    timing_line("simulate", s["arm_timing"])
    high_centred_warning(s["high_centred"])
    _governor_lines(s)
    _disagreement_warning(s)
    if s["tipped"] is not None:
        how = {"support lost": f"its contacts' mu <= 0 for {s['tip_hold_s']:g} s",
               "overturned": "past the point of no return"}[s["tipped"]["cause"]]  # fmt: skip
        line = f"the robot tips over in MuJoCo at {s['tipped']['time_s']:.2f} s ({how})"
        print(f"mmstab: unstable: {line}", file=sys.stderr)
        return EXIT_UNSTABLE
    if s["left_map"] is not None:  # past the map the model does not hold: not allowable
        line = f"the robot left its map in MuJoCo at {s['left_map']['time_s']:.2f} s"
        if s["slid"] is not None:
            line += f" (it slid from {s['slid']['time_s']:.2f} s)"
        print(f"mmstab: slides: {line}", file=sys.stderr)
        return EXIT_SLIDES
    if s["slid"] is not None:
        line = (
            f"the robot slides in MuJoCo at {s['slid']['time_s']:.2f} s (more than "
            f"{s['slip_distance_m']:g} m downhill in {s['slip_window_s']:g} s)"
        )
        status = report("slides", line, "--allow-sliding", args.allow_sliding, EXIT_SLIDES)
        if status is not None:
            return status
    return _arm_ground_status(s, args)


def _rad(value: float | None) -> str:
    """An angle [rad] for the summary line; ``none`` where no check had one."""
    return "none" if value is None else f"{value:.3f} rad"


def _disagreement_warning(s: dict[str, Any]) -> None:
    """A warning where the simulated attitude left mmstab's predicted rest (not a tip)."""
    d = s["disagreement"]
    if d is not None:
        print(f"mmstab: warning: disagreement: the chassis tilts more than "
              f"{s['disagreement_angle_rad']:g} rad off mmstab's predicted resting attitude "
              f"from {d['time_s']:.2f} s (at most {d['tilt_off_rest_max_rad']:.3f} rad)"
              + ("; MuJoCo's contacts still carry it" if s["tipped"] is None else ""),
              file=sys.stderr)  # fmt: skip


def _governor_lines(s: dict[str, Any]) -> None:
    """How long the reference waited for the base; a warning if the run ended stalled."""
    if s["reference_wait_s"] > 0:
        print(f"simulate: the reference waited {s['reference_wait_s']:.2f} s for the base "
              "(physics.governor)")  # fmt: skip
    stall = s["stalled"]
    if stall is not None:
        print(f"mmstab: warning: stalled{_stall_cause(stall)}: the base did not catch up with its "
              f"reference, and the run ends at {stall['time_s']:.2f} s with the path unfinished",
              file=sys.stderr)  # fmt: skip


def _stall_cause(stall: dict[str, Any]) -> str:
    """`` (high-centred: the chassis on the ground ...)`` from a stall's record, or ``""``."""
    if "cause" not in stall:
        return ""
    where = f" at s = {stall['s_m']:.2f} m" if stall.get("s_m") is not None else ""
    parts = ", ".join(f"{k} {100 * v:.0f} %" for k, v in stall["touching"].items() if v > 0)
    high = stall["cause"] == "high-centred"
    held = "the chassis rests on the ground" if high else "on its tracks"
    return f", {stall['cause']}{where} ({held}; touching in its last second: {parts or 'none'})"


def _arm_ground_status(s: dict[str, Any], args: argparse.Namespace) -> int | None:
    """An arm link that touched the ground in MuJoCo: exit 5 unless ``--allow-collision``."""
    a = s["arm_ground_contact"]
    if a is None:
        return None
    where = f" at s = {a['s_m']:.2f} m" if a.get("s_m") is not None else ""
    tilt = a.get("tilt_off_rest_rad")
    attitude = "" if tilt is None else f", the body {tilt * 57.29578:.1f} deg off its rest"
    line = (
        f"the arm touches the ground in MuJoCo from {a['first_time_s']:.2f} s{where} "
        f"({100 * a['fraction_of_checks']:.1f} % of the checks{attitude})"
    )
    return report("arm collision", line, "--allow-collision", args.allow_collision,
                  EXIT_ARM_COLLISION)  # fmt: skip


def _check_duration(args: argparse.Namespace, problem: Any) -> None:
    """The simulated time (``--duration``, else ``physics.duration``) within the size bounds.

    (A route's own driving time was bounded when the problem loaded.) Estimated as a
    tracking run at ``physics.control_dt``: 1e300 s crashed NumPy, 1e6 s ran for days.

    Raises:
        MmstabError: naming ``--duration``; ConfigError naming ``physics.duration``.
    """
    from mmstab.core.files import ConfigError
    from mmstab.core.sizes import check_steps, refusal, steps_estimate

    phys = problem.section("physics")
    dt = float(phys["control_dt"])
    if args.duration is not None:
        check_steps("--duration", float(args.duration), dt, force=args.force_size)
    elif phys["duration"] is not None:
        est = steps_estimate("physics.duration", float(phys["duration"]), dt)
        why = refusal(est, args.force_size)
        if why is not None:
            raise ConfigError(problem.path, "physics.duration", why)


def add_physics_commands(sub: Any) -> None:
    """``simulate`` (docs/physics.md)."""
    h = "track the problem's path on the whole robot in MuJoCo, the controller in the loop"
    p = sub.add_parser("simulate", help=h, description=h)
    p.add_argument(
        "problem", help="problem YAML file (its physics: section; e.g. problems/ramp.yaml)"
    )
    p.add_argument("-o", "--out", default=None, help="output folder (default results/physics)")
    p.add_argument("--duration", type=float, default=None, help="simulated time [s]")
    p.add_argument(
        "--force-size",
        action="store_true",
        help="run a simulated time whose time estimate exceeds the bound (not beyond the memory)",
    )
    p.add_argument(
        "--arm",
        choices=["planned", "stowed"],
        default=None,
        help="the plan's arm postures or the arm held stowed (default: physics.arm)",
    )
    p.add_argument(
        "--gif", action="store_true", help="also write physics.gif, a replay in MuJoCo's attitudes"
    )
    p.add_argument("--allow-sliding", action="store_true", help="exit 0 even if the robot slides")
    p.add_argument(
        "--allow-collision",
        action="store_true",
        help="exit 0 (warning) even if an arm link touches the ground in MuJoCo",
    )
    p.set_defaults(handler=_simulate)
