"""The drop-test validation script, run as a subprocess with small settings."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import yaml
from conftest import ROBOT_YAML, ROOT

pytestmark = pytest.mark.mujoco
pytest.importorskip("mujoco")

SCRIPT = ROOT / "benchmarks" / "validate_terrain.py"


def settings(**over):
    s = {
        "robot": str(ROBOT_YAML),
        "predictor": "plane",
        "seed": 3,
        "poses_per_terrain": 4,
        "margin": 0.7,
        "terrains": [
            {
                "name": "a",
                "kind": "plane",
                "slope": 0.1,
                "azimuth": 0.5,
                "size": [2.4, 2.4],
                "resolution": 0.1,
            },
            {
                "name": "b",
                "kind": "plane",
                "slope": 0.3,
                "azimuth": -2.0,
                "size": [2.4, 2.4],
                "resolution": 0.1,
            },
        ],
    }
    s.update(over)
    return s


def run(tmp_path, data):
    cfg = tmp_path / "v.yaml"
    cfg.write_text(yaml.safe_dump(data))
    env = {**os.environ, "MPLBACKEND": "Agg"}
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), str(cfg), "-o", str(out)],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        timeout=300,
    )
    return proc, out


def test_validation_writes_distributions_and_figure(tmp_path):
    proc, out = run(tmp_path, settings())
    assert proc.returncode == 0, proc.stderr
    data = json.loads((out / "summary.json").read_text())
    assert data["predictor"] == "plane"
    assert set(data["terrains"]) == {"a", "b"}
    assert data["overall"]["drops"] == 8 and data["overall"]["settled"] == 8
    for key in ("roll_deg", "pitch_deg", "z_m"):
        stats = data["overall"][key]
        assert 0 <= stats["median"] <= stats["p95"] <= stats["max"]
    assert data["overall"]["roll_deg"]["max"] < 0.3 and data["overall"]["z_m"]["max"] < 2e-3
    assert data["terrains"]["a"]["outliers"] == []
    assert data["drop_settings"]["friction"] > 0 and "machine" in data
    assert (out / "validation.png").stat().st_size > 0
    assert yaml.safe_load((out / "validation_settings.yaml").read_text())["seed"] == 3


@pytest.mark.parametrize(
    "over, message",
    [({"predictor": "oracle"}, "predictor"), ({"drop": {"frcition": 1.0}}, "drop.frcition")],
)
def test_bad_settings_one_line_exit_2_nothing_written(tmp_path, over, message):
    proc, out = run(tmp_path, settings(**over))
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "v.yaml" in lines[0]
    assert not out.exists()
