"""Validate a resting-pose predictor against MuJoCo heightfield drops.

Usage: ``python benchmarks/validate_terrain.py [SETTINGS.yaml] [-o DIR] [--predictor NAME]``
(default ``problems/validate_terrain.yaml`` -> ``results/terrain/summary.json`` and
``validation.png``). ``make validate-terrain`` runs it. Bad settings: one line on stderr,
exit status 2, nothing written.
"""

from __future__ import annotations

import argparse
import sys

from common import machine_info

from mmstab.core.files import MmstabError
from mmstab.physics.drop_validation import PREDICTORS, main_validation


def main(argv: list[str] | None = None) -> int:
    """Run the validation; return the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("settings", nargs="?", default="problems/validate_terrain.yaml")
    parser.add_argument("-o", "--out", default="results/terrain", help="output folder")
    parser.add_argument("--predictor", choices=sorted(PREDICTORS), help="override the file's")
    args = parser.parse_args(argv)
    import mujoco

    try:
        machine = machine_info(mujoco=mujoco.__version__)
        data = main_validation(args.settings, args.out, args.predictor, {"machine": machine})
    except MmstabError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    o = data["overall"]
    print(
        f"overall ({o['settled']}/{o['drops']} settled): median/p95/max |droll| "
        f"{o['roll_deg']['median']:.3g}/{o['roll_deg']['p95']:.3g}/{o['roll_deg']['max']:.3g} deg, "
        f"|dpitch| {o['pitch_deg']['median']:.3g}/{o['pitch_deg']['p95']:.3g}/"
        f"{o['pitch_deg']['max']:.3g} deg, |dz| {1000 * o['z_m']['median']:.3g}/"
        f"{1000 * o['z_m']['p95']:.3g}/{1000 * o['z_m']['max']:.3g} mm -> {args.out}/"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
