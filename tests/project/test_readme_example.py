"""The README's Python example runs as written, and its numbers are mmstab's own."""

from __future__ import annotations

import re

import numpy as np
from conftest import ROOT


def readme_block() -> str:
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert len(blocks) == 1, "the README has one Python example"
    return blocks[0]


def test_readme_example_runs_and_its_mu_is_the_stance(monkeypatch, capsys, tmp_path):
    import yaml

    import mmstab

    monkeypatch.chdir(ROOT)  # the example's paths are the repository's
    namespace: dict = {}
    exec(compile(readme_block(), "README.md", "exec"), namespace)
    keys = ("robot", "ramp", "plan", "tracked", "rest")
    robot, ramp, plan, tracked, rest = (namespace[k] for k in keys)
    run = tracked.run
    printed = capsys.readouterr().out
    assert "accepted True" in printed and "run accepted True" in printed
    assert tracked.exit_status == 0 and not any(v["unsafe"] for v in tracked.verdicts.values())

    # at rest on the 0.2 rad ramp, heading along its contour: the roll is the slope (analytic)
    assert abs(rest.roll - 0.2) < 1e-9 and abs(rest.pitch) < 1e-9 and rest.mu > 0
    # every planned pose's mu is mmstab.stance's at that pose and posture, recomputed here
    again = [
        mmstab.stance(robot, ramp, pose, arm=q).mu
        for pose, q in zip(plan.poses, plan.postures, strict=True)
    ]
    np.testing.assert_allclose(again, plan.mu_planned, rtol=1e-12)
    stowed = [mmstab.stance(robot, ramp, p).mu for p in plan.poses]
    np.testing.assert_allclose(stowed, plan.mu_stowed, rtol=1e-12)
    assert np.all(plan.mu_planned > plan.mu_stowed)  # the planned arm is the more stable
    # the tracked run: no tip, no failed QP, mu positive along it
    assert run.tipped is None and not run.failures and run.mu.reconfigured.min() > 0
    assert run.t[-1] > 5.0  # the whole route (2.9 m at 0.2 m/s at most), not a stub
    # the same robot, ramp and route as a problem file that names nothing else: the same plan
    problem = yaml.safe_load((ROOT / "examples" / "slope_route.yaml").read_text())
    problem.pop("workspace")  # the file's coarse grid: the code's is the default
    problem["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(problem))
    from_file = mmstab.plan(mmstab.load_problem(tmp_path / "p.yaml"))
    np.testing.assert_allclose(from_file.postures, plan.postures, atol=1e-12)
    np.testing.assert_allclose(from_file.mu_planned, plan.mu_planned, atol=1e-12)
    assert from_file.verdicts == plan.verdicts
