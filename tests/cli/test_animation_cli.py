"""`mmstab animation`: the tracking run rendered as a GIF (short run, few frames)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from conftest import write_problem
from PIL import Image


def _short(p, r):
    p["workspace"]["grid"] = [10, 8, 8, 8]
    p["controller"]["duration"] = 0.3
    p["animation"].update(frames=4, fps=5, width=200, height=120)


@pytest.mark.slow
def test_animation_subprocess_writes_a_gif(tmp_path):
    path = write_problem(tmp_path, _short)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    out = tmp_path / "anim"

    def animate():
        return subprocess.run(
            [sys.executable, "-m", "mmstab", "animation", str(path), "-o", str(out)],
            check=True,
            env=env,
            cwd=tmp_path,
            capture_output=True,
            text=True,
        )

    first = animate()  # no stored run yet: it tracks (and stores the run) first
    assert "tracking first" in first.stderr
    with Image.open(out / "animation.gif") as gif:
        assert gif.n_frames == 4
        assert gif.size == (200, 120)
    info = json.loads((out / "animation.json").read_text())
    assert info["frames"] == 4 and info["simulated_s"] == pytest.approx(0.3, abs=1e-9)
    assert info["mu_min"] > 0
    # the stored run is the tracking run's, thinned to 10 ms: its minimum is no lower
    full_min = json.loads((out / "summary.json").read_text())["mu_min"]["reconfigured"]
    assert full_min - 1e-9 <= info["mu_min"] <= full_min * 1.01
    stored = (out / "run.npz").stat().st_mtime_ns
    second = animate()  # one run serves both: rendered from the store, not simulated again
    assert "tracking first" not in second.stderr
    assert (out / "run.npz").stat().st_mtime_ns == stored


def test_animation_settings_are_validated(tmp_path):
    from mmstab.core.files import ConfigError
    from mmstab.core.problem import load_problem

    path = write_problem(tmp_path, lambda p, r: p["animation"].__setitem__("fps", 0))
    with pytest.raises(ConfigError) as info:
        load_problem(path)
    assert info.value.field == "animation.fps"
