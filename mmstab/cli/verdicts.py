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
    if args.allow_unstable:
        print(f"mmstab: warning: {line} (--allow-unstable)", file=sys.stderr)
        return None
    print(f"mmstab: unstable: {line}; pass --allow-unstable to accept it", file=sys.stderr)
    return EXIT_UNSTABLE


def slides_status(s: dict[str, Any], args: argparse.Namespace) -> int | None:
    """Report poses where the tracks slide on stderr; exit status 4 unless ``--allow-sliding``."""
    from mmstab.runs.verdict import describe_sliding

    verdict = s.get("slip")
    if verdict is None or not verdict["slides"]:
        return None
    total = len(s["poses"]) if isinstance(s.get("poses"), list) else s.get("steps", 1)
    line = describe_sliding(verdict, total)
    if args.allow_sliding:
        print(f"mmstab: warning: {line} (--allow-sliding)", file=sys.stderr)
        return None
    print(f"mmstab: slides: {line}; pass --allow-sliding to accept it", file=sys.stderr)
    return EXIT_SLIDES


def arm_collision_status(summary: dict[str, Any], args: argparse.Namespace) -> int | None:
    """Report a run whose arm touched the robot; exit status 5 unless ``--allow-collision``."""
    from mmstab.runs.verdict import describe_arm_collision

    report = summary["arm_self_collision"]
    if report["verdict"]["safe"]:
        return None
    line = describe_arm_collision(report)
    if args.allow_collision:
        print(f"mmstab: warning: {line} (--allow-collision)", file=sys.stderr)
        return None
    print(f"mmstab: arm collision: {line}; pass --allow-collision to accept it", file=sys.stderr)
    return EXIT_ARM_COLLISION
