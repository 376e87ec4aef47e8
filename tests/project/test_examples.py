"""Each script in examples/ runs as a user would run it, and prints what it says it prints."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from conftest import ROOT

#: script -> text its output must contain
EXPECTED = {
    "rest_on_heightmap.py": "worst mu",
    "plan_route.py": "below 450 N rad with the arm stowed only",
    "track_route.py": "tipped at: None",
    "controller_loop.py": "arm CoM error 0.00 mm",
    "your_robot.py": "least mu reaching forward",
}


def test_every_example_is_listed():
    assert sorted(p.name for p in (ROOT / "examples").glob("*.py")) == sorted(EXPECTED)


@pytest.mark.parametrize("script", sorted(EXPECTED))
def test_example_runs(script, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    args = [sys.executable, str(ROOT / "examples" / script)]
    if script == "rest_on_heightmap.py":
        args.append(str(tmp_path / "map.png"))
    out = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr  # each script ends in an assert of its own
    assert EXPECTED[script] in out.stdout, out.stdout
    if script == "rest_on_heightmap.py":
        assert (tmp_path / "map.png").stat().st_size > 10_000
