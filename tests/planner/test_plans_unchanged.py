"""A one-off ``method: roadmap`` plan gives the same plans as the planner before its speed-ups.

Seeded random maps and routes (``tests/runs/test_random_routes.py``'s generator, the
problems' default grid, every default check on), with a ditch, a kerb or bumps laid onto
each map in turn, and the random routes ``benchmarks/plan_random.py`` times, were planned
by the planner as it was before the one-off plan's per-pose costs were cut; their plans
are kept in ``tests/planner/plans_reference.json``. The planner of today must give the
same plans: the same verdict (a plan, or no plan at the same pose), postures, target CoMs,
μ (planned, stowed, arm removed, on the search's basis), collision verdicts and moves, to
1e-9 (floats are stored by their ``repr``, which round-trips exactly; the rests are solved
in batches, and a row's μ can differ in its last bits, 1e-13 N rad, with the rows it is
batched with, so the search's order of rests is free to change).

Write the file again (only when the plans are meant to change, and say why in
CHANGELOG.md): ``PYTHONPATH=. python tests/planner/test_plans_unchanged.py --write``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = Path(__file__).with_name("plans_reference.json")
#: Seeds of the maps (distinct from the random routes' 2400 + k) and their features.
SEEDS = tuple(range(5100, 5112))
#: The random routes of ``benchmarks/plan_random.py`` (pairs 0 .. 9), as they are.
PAIRS = tuple(range(10))
#: How far [the field's unit: m, rad, N rad] a plan may be from its reference.
TOL = 1e-9
CASES = [("map", k) for k in range(len(SEEDS))] + [("pair", k) for k in PAIRS]
FIELDS = (
    "poses", "target_com", "postures", "mu_planned", "mu_stowed", "mu_removed", "mu_search",
    "collision_free",
)  # fmt: skip


def feature(k: int, rng: np.random.Generator) -> dict[str, Any]:
    """Map k's feature: a ditch, a kerb or bumps in turn, drawn from ``rng``."""
    if k % 3 == 0:
        return {
            "ditch": {
                "depth": float(rng.uniform(0.03, 0.10)),
                "width": float(rng.uniform(0.2, 0.5)),
                "distance": float(rng.uniform(-1.0, 1.0)),
                "azimuth": float(rng.uniform(-np.pi, np.pi)),
            }
        }
    if k % 3 == 1:
        return {
            "kerb": {
                "height": float(rng.uniform(0.03, 0.08)),
                "distance": float(rng.uniform(-1.0, 1.0)),
                "azimuth": float(rng.uniform(-np.pi, np.pi)),
            }
        }
    return {
        "bumps": {
            "amplitude": float(rng.uniform(0.01, 0.04)),
            "wavelength": float(rng.uniform(0.5, 1.5)),
        }
    }


def problem_file(case: tuple[str, int], directory: Path) -> Path:
    """A case's problem file in ``directory``: a map with its feature, or a random pair."""
    sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tests" / "runs")]
    from test_random_routes import pair_problem, random_pair

    kind, k = case
    if kind == "pair":
        return pair_problem(k, directory)
    rng = np.random.default_rng(SEEDS[k])
    data = random_pair(rng, pivot_everywhere=k % 2 == 0)
    data["terrain"]["generate"]["features"] = feature(k, rng)
    path = directory / f"map{k}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def plan_record(path: Path) -> dict[str, Any]:
    """The plan of the problem at ``path`` as lists (its verdict, fields and moves)."""
    from mmstab.core.problem import load_problem
    from mmstab.planner import plan_problem
    from mmstab.planner.searches.roadmap import NoPlanError

    try:
        plan = plan_problem(load_problem(path))
    except NoPlanError as exc:
        return {"planned": False, "pose_index": exc.pose_index, "error": str(exc)}
    out: dict[str, Any] = {"planned": True}
    for name in FIELDS:
        out[name] = np.asarray(getattr(plan, name)).tolist()
    out["moves"] = [np.asarray(m).tolist() for m in plan.moves]
    return out


def write(directory: Path) -> None:
    """Plan every map and write :data:`REFERENCE`."""
    plans = [plan_record(problem_file(case, directory)) for case in CASES]
    cases = [list(c) for c in CASES]
    REFERENCE.write_text(json.dumps({"seeds": list(SEEDS), "cases": cases, "plans": plans}) + "\n")


@pytest.mark.slow
@pytest.mark.parametrize("i", range(len(CASES)), ids=[f"{c[0]}{c[1]}" for c in CASES])
def test_a_one_off_plan_is_the_plan_of_before_the_speed_ups(i, tmp_path):
    reference = json.loads(REFERENCE.read_text())
    assert reference["seeds"] == list(SEEDS) and reference["cases"] == [list(c) for c in CASES]
    want = reference["plans"][i]
    got = json.loads(json.dumps(plan_record(problem_file(CASES[i], tmp_path))))  # same rounding
    assert got["planned"] == want["planned"]
    if not want["planned"]:
        assert got["pose_index"] == want["pose_index"]
        return
    for name in FIELDS:
        a, b = np.array(got[name]), np.array(want[name])
        assert a.shape == b.shape, name
        np.testing.assert_allclose(a, b, rtol=0, atol=TOL, err_msg=name)
    assert len(got["moves"]) == len(want["moves"])
    for a, b in zip(got["moves"], want["moves"], strict=True):
        np.testing.assert_allclose(np.array(a), np.array(b), rtol=0, atol=TOL)


def test_the_reference_holds_plans_and_every_feature():
    reference = json.loads(REFERENCE.read_text())
    plans = reference["plans"]
    assert len(plans) == len(CASES)
    assert sum(p["planned"] for p in plans) >= len(plans) // 2  # mostly plans, not verdicts
    assert all(len(p["postures"]) >= 5 for p in plans if p["planned"])
    kinds = {next(iter(feature(k, np.random.default_rng(0)))) for k in range(len(SEEDS))}
    assert kinds == {"ditch", "kerb", "bumps"}


if __name__ == "__main__":
    import tempfile

    if "--write" not in sys.argv:
        sys.exit("usage: PYTHONPATH=. python tests/planner/test_plans_unchanged.py --write")
    with tempfile.TemporaryDirectory() as tmp:
        write(Path(tmp))
    print(f"-> {REFERENCE}")
