"""Routes 36 and 19 of ``make validate-routes``: a low μ about a diagonal is a rock.

Seed 5136: a 6.4 cm kerb over 4 cm bumps on a level map; seed 5119: a 14.6 cm deep, 62 cm
wide ditch on a 4.6° map with a kerb. The plan used to refuse both as tips on one sample
every 5 cm (μ 2.4 N rad as the rear leaves the kerb, 7.4 N rad bridging the ditch, below the
17.6 N rad the route's accelerations need) about a diagonal between two track corners;
MuJoCo holds both. Pushed across the diagonal the base turns 4.5° and 0.8° onto a corner
that holds it: no tip there (the routes are refused for their turns' slides).
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import ROOT

import mmstab
from experiments.validate_routes import load_settings, route_problem
from mmstab import app
from mmstab.outputs.routes import route_summary
from mmstab.planner import route_risk

#: The 3 deg attitude margin these routes were planned and refereed with (the default before
#: 12 deg): the plans whose physics this module checks.
THREE_DEG = {"attitude_margin": 0.0524}


def summary_of(k: int, tmp_path) -> dict:
    data = route_problem(load_settings(ROOT / "problems" / "validate_routes.yaml"), k)
    data["planner"] = {**data.get("planner", {}), **THREE_DEG}
    path = tmp_path / f"route{k:02d}.yaml"
    path.write_text(yaml.safe_dump(data))
    problem = mmstab.load_problem(path)
    plan = app.plan(problem)
    return route_summary(problem.following(plan), plan, route_risk(plan, 0.0))


@pytest.mark.parametrize(
    ("k", "s", "worst", "turn_deg"), [(36, 5.12, 2.44, 4.5), (19, 1.10, 7.41, 0.8)]
)
def test_a_seeded_route_rocks_where_it_was_refused_as_a_tip(k, s, worst, turn_deg, tmp_path):
    summary = summary_of(k, tmp_path)
    assert summary["verdicts"]["tip"]["verdict"] == "holds"
    assert summary["along_path"]["tip"]["stretches"] == []
    (rock,) = summary["along_path"]["tip"]["rocks"]
    assert rock["start_s"] == pytest.approx(s, abs=0.01) and rock["end_s"] == rock["start_s"]
    threshold = summary["stability"]["along_threshold"]
    assert threshold == pytest.approx(17.55, abs=0.01)  # 58.5 kg at 0.3 m/s^2
    assert rock["worst"] == pytest.approx(worst, abs=0.01) and rock["worst"] < threshold
    assert np.degrees(rock["rock_rad"]) == pytest.approx(turn_deg, abs=0.15)
    assert rock["mu_rocked"] > 250 and rock["work_m"] < 0.001 < 0.015 < rock["barrier_m"]
