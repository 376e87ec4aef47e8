"""The verdicts of the problem commands: a report on stderr and the exit status.

An unstable plan or run (exit 3), tracks that would slide (exit 4) and an arm that touched
the robot (exit 5) each print one line; the matching ``--allow-...`` option turns it into a
warning and exit 0 (``docs/cli.md``).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from mmstab.cli.status import EXIT_ARM_COLLISION, EXIT_SLIDES, EXIT_UNSTABLE


def report(word: str, line: str, option: str, allowed: bool, status: int) -> int | None:
    """One verdict on stderr: a warning and None when ``allowed``, else ``status``.

    Args:
        word: the verdict's word (``unstable``, ``slides``, ``arm collision``).
        line: what happened, one line.
        option: the option that accepts it (``--allow-sliding``).
        allowed: the option was given.
        status: the exit status otherwise.
    """
    if allowed:
        print(f"mmstab: warning: {line} ({option})", file=sys.stderr)
        return None
    print(f"mmstab: {word}: {line}; pass {option} to accept it", file=sys.stderr)
    return status


def tipped_status(summary: dict[str, Any]) -> int | None:
    """Report a run where the robot tipped over; exit status 3 (no option accepts it)."""
    from mmstab.runs.verdict import describe_tipping

    if summary.get("tipped") is None:
        return None
    print(f"mmstab: unstable: {describe_tipping(summary['tipped'])}", file=sys.stderr)
    return EXIT_UNSTABLE


def plan_status(s: dict[str, Any], args: argparse.Namespace) -> int | None:
    """Report an unstable plan on stderr; exit status 3 unless ``--allow-unstable``."""
    from mmstab.runs.verdict import describe_plan_verdict

    verdict = s["stability"]
    if verdict["stable"]:
        return None
    total = len(s["poses"]) if isinstance(s.get("poses"), list) else 1
    line = describe_plan_verdict(verdict, total)
    return report("unstable", line, "--allow-unstable", args.allow_unstable, EXIT_UNSTABLE)


def slides_status(s: dict[str, Any], args: argparse.Namespace) -> int | None:
    """Report poses where the tracks slide on stderr; exit status 4 unless ``--allow-sliding``."""
    from mmstab.runs.verdict import describe_sliding

    verdict = s.get("slip")
    if verdict is None or not verdict["slides"]:
        return None
    total = len(s["poses"]) if isinstance(s.get("poses"), list) else s.get("steps", 1)
    line = describe_sliding(verdict, total)
    return report("slides", line, "--allow-sliding", args.allow_sliding, EXIT_SLIDES)


def plan_contact_status(s: dict[str, Any], args: argparse.Namespace) -> int | None:
    """Report a plan whose arm touches the robot or the ground; exit status 5 unless allowed.

    The robot: at a planned posture, or on the arm's path between two (``arm_path``: a
    pose-by-pose search's posture reference, as ``mmstab track`` follows it). The ground:
    the arm on its posture reference at a dense sample's rest (``along_path.arm_in_ground``).
    ``--allow-collision`` allows both.
    """
    contact = s["verdicts"]["arm_contact"]
    if not contact["unsafe"]:
        return None
    in_ground = (s.get("along_path") or {}).get("arm_in_ground") or {}
    ground = [[x["start_s"], x["end_s"]] for x in in_ground.get("stretches", [])]
    # the spans apart from the ground's are the robot's (merged spans: one that meets the
    # ground's is told as the ground's)
    robot = [w for w in contact["where"] if not any(w[0] <= b and a <= w[1] for a, b in ground)]
    lines = []
    if ground:
        spans = ", ".join(f"{a:.2f}" if a == b else f"{a:.2f}-{b:.2f}" for a, b in ground[:4])
        deepest = max(x["by"] for x in in_ground["stretches"])
        lines.append(f"the arm on its posture reference is in the ground at rest at s = {spans} m "
                     f"(up to {100 * deepest:.1f} cm in)")  # fmt: skip
    path = s.get("arm_path") or {}
    if robot or path or not ground:
        lines.append(robot_contact_line(s, robot or contact["where"], path))
    return report("arm collision", "; ".join(lines), "--allow-collision", args.allow_collision,
                  EXIT_ARM_COLLISION)  # fmt: skip


def robot_contact_line(s: dict[str, Any], where: list[list[float]], path: dict[str, Any]) -> str:
    """Where the planned arm touches the robot (``where``: arc-length spans [m])."""
    spans = ", ".join(f"{a:.2f}" if a == b else f"{a:.2f}-{b:.2f}" for a, b in where[:4])
    pairs = ", ".join(list(path.get("reference", {}).get("pairs", {}))[:3])
    line = f"the planned arm touches the robot at s = {spans} m" + (f" ({pairs})" if pairs else "")
    if path:
        line += (
            f"; the path between the planned postures is not checked by planner.method "
            f"{s['settings']['method']} (sequence and roadmap check it)"
        )
    return line


def in_ground_line(record: dict[str, Any], what: str) -> str:
    """``what`` at its first four times in the ground, and how far in at most.

    From a run's ``arm_in_ground`` (:func:`mmstab.runs.arm_ground.in_ground_in_time`:
    ``track``'s and ``follow``'s).
    """
    spans_s = record["intervals_s"]
    spans = ", ".join(f"{x['start_s']:.2f}-{x['end_s']:.2f}" for x in spans_s[:4])
    deepest = max(x["by"] for x in spans_s)
    return f"{what} at t = {spans} s (up to {100 * deepest:.1f} cm in)"


def arm_collision_status(summary: dict[str, Any], args: argparse.Namespace) -> int | None:
    """Report a run whose arm touched the robot or the ground; exit 5 unless allowed.

    The robot: ``arm_self_collision``; the ground at the tracked rests (a heightmap's):
    ``arm_in_ground``. A summary without the records (a run stored without ``mmstab track``'s
    summary) has none. ``--allow-collision`` allows both.
    """
    from mmstab.runs.verdict import describe_arm_collision

    collision = summary.get("arm_self_collision")
    in_ground = summary.get("arm_in_ground") or {}
    lines = []
    if collision is not None and not collision["verdict"]["safe"]:
        lines.append(describe_arm_collision(collision))
    if in_ground.get("contact"):
        lines.append(
            in_ground_line(in_ground, "the tracked arm is in the ground at the tracked rest")
        )
    if not lines:
        return None
    line = "; ".join(lines)
    allowed = args.allow_collision
    return report("arm collision", line, "--allow-collision", allowed, EXIT_ARM_COLLISION)


def high_centred_warning(verdict: dict[str, Any]) -> None:
    """Where the path high-centres the robot (:mod:`mmstab.runs.high_centred`), if anywhere."""
    if verdict["high_centred"]:
        where = ", ".join(f"{x['start_s']:.2f}-{x['end_s']:.2f} m" for x in verdict["stretches"])
        print(
            f"mmstab: warning: the chassis rests on the ground at s = {where} of the path "
            "(high-centred): the tracks carry little of the weight and may not drive it on",
            file=sys.stderr,
        )


def timing_line(command: str, timing: dict[str, Any] | None) -> None:
    """The arm's time law: μ_dyn along the reference before and after, the moves slowed."""
    if timing is None:
        return
    print(
        f"{command}: arm time law (dynamic_fraction {timing['dynamic_fraction']:g}): "
        f"mu_dynamic min along the reference {timing['mu_dynamic_min_before']:.1f} -> "
        f"{timing['mu_dynamic_min']:.1f} N rad (static {timing['mu_static_min']:.1f}); "
        f"{len(timing['slowed_moves'])} move(s) slowed, +{timing['lap_time_added_s']:.2f} s"
    )


def limits_line(command: str, verdicts: dict[str, Any], spacing: float) -> None:
    """One verdict per limit (tip, slide, step, high-centred, arm contact), one line.

    Args:
        command: the command's name (``plan``).
        verdicts: :func:`mmstab.runs.along.limit_verdicts`.
        spacing: the path's checked samples' spacing [m].
    """

    def where(v: dict[str, Any]) -> str:
        spans = [f"{a:.2f}" if a == b else f"{a:.2f}-{b:.2f}" for a, b in v["where"][:4]]
        more = f" +{len(v['where']) - 4}" if len(v["where"]) > 4 else ""
        return f" at s = {', '.join(spans)}{more} m" if spans else ""

    names = {"tip": "tip", "slide": "slide", "step": "step", "high_centred": "high-centred",
             "arm_contact": "arm contact"}  # fmt: skip
    parts = [f"{names[k]}: {v['verdict'].replace('_', '-')}{where(v)}" for k, v in verdicts.items()]
    print(f"{command}: verdicts along the path (every {100 * spacing:.0f} cm): " + "; ".join(parts))


def turn_slide_line(command: str, turn_slide: dict[str, Any] | None) -> None:
    """``planner.turn_slide``: the turns priced over the limit with the first search's postures.

    Each turn's span, its heading change, the model's price [cm] and the poses that chose
    again (none: no plan keeps it within the limit, the first choice stands).
    """
    if not turn_slide or turn_slide.get("limit_m") is None:
        return
    parts = [
        f"s = {t['start_s']:.2f}-{t['end_s']:.2f} m ({t['turn_rad']:.2f} rad) priced "
        f"{100 * t['slide_m']:.1f} cm, "
        + (f"poses {', '.join(map(str, t['poses']))} chose again" if t["poses"]
           else "no plan within the limit: the first choice kept")
        for t in turn_slide["turns"]
    ]  # fmt: skip
    said = "; ".join(parts) if parts else "every turn of the planned poses within it"
    print(f"{command}: turn slide limit {100 * turn_slide['limit_m']:g} cm: {said}")


def verify_status(verify: dict[str, Any] | None, status: int | None) -> int | None:
    """``plan --verify``: MuJoCo's outcome beside the plan's verdict, one line.

    An accepted plan that tips (exit 3), slides or leaves the map (exit 4) or touches the
    ground with the arm (exit 5, as ``mmstab simulate``) in MuJoCo is not accepted: physics
    is the referee where the model is unsure. A refused plan keeps its
    status; a stall is a warning.
    """
    if verify is None:
        return status
    v = verify
    events = {k: e for k, e in v["events"].items() if e is not None}
    when = (
        ", ".join(
            f"{k}{', ' + e['cause'] if 'cause' in e else ''} at "
            f"{e.get('time_s', e.get('first_time_s')):.2f} s"
            + (f" (s = {e['s_m']:.2f} m)" if "s_m" in e else "")
            for k, e in events.items()
        )
        or "no event"
    )
    mu = v["mu_relative_difference_median"]
    print(
        f"plan: verify in MuJoCo ({v['simulated_s']:.1f} s): {v['mujoco']} ({when}); mmstab "
        f"{v['plan']}: {'agree' if v['agree'] else 'DISAGREE'}; mu predicted vs simulated "
        f"{'n/a' if mu is None else f'{100 * mu:.1f} %'} (median); base error max "
        f"{100 * v['base_error_max_m']:.1f} cm "
        f"(body origin {100 * v['base_origin_error_max_m']:.1f} cm)"
    )
    place_line(v)
    if status is not None or v["plan"] != "accepted" or v["mujoco"] in ("holds", "stalls"):
        if v["mujoco"] == "stalls":
            cause = v["events"]["stalled"].get("cause", "stuck")
            print(f"mmstab: warning: the route stalls in MuJoCo ({cause}, not unsafe)",
                  file=sys.stderr)  # fmt: skip
        return status
    line = f"mmstab accepted the route but in MuJoCo it {v['mujoco']} ({when}); see {v['run']}"
    print(f"mmstab: physics disagrees: {line}", file=sys.stderr)
    if v["mujoco"] == "touches the ground":  # an arm link on the ground: simulate's exit 5
        return EXIT_ARM_COLLISION
    return EXIT_UNSTABLE if v["mujoco"] == "tips" else EXIT_SLIDES


def place_line(v: dict[str, Any]) -> None:
    """``plan --verify``: where MuJoCo's event came against where the plan flags its limit."""
    p = v.get("place")
    if not p:
        return
    where = ", ".join(f"{a:.2f}-{b:.2f}" for a, b in p["flagged"])
    if p["same_place"]:
        said = f"where the plan flags it (s = {where} m)"
    elif p["distance_m"] is None:
        kinds = " or ".join(k.replace("_", "-") for k in p["limits"])
        said = f"the plan flags no {kinds} anywhere"
    else:
        said = f"{p['distance_m']:.2f} m from where the plan flags it (s = {where} m)"
    print(f"plan: MuJoCo {v['mujoco']} at s = {p['s_m']:.2f} m, {said}")
