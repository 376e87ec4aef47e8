"""One registry of settings checks, run for every command at load time; size bounds."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import RAMP_YAML, ROOT, write_problem

from experiments.__main__ import build_parser as experiments_parser
from mmstab.cli import build_parser, main
from mmstab.core import sizes
from mmstab.core.files import ConfigError, MmstabError
from mmstab.core.problem import load_problem
from mmstab.core.setting_checks import SECTION_CHECKS, check_duration

GB = 1e9


@pytest.fixture
def memory_16gb(monkeypatch):
    """Size checks against a fixed 16 GB of available memory (machine independent)."""
    monkeypatch.setattr(sizes, "available_memory", lambda: 16 * GB)


# ------------------------------------------------------------------------------ the registry
def test_problem_imports_nothing_above_the_inputs():
    code = (
        "import sys, mmstab.core.problem; "
        "print(' '.join(sorted(m for m in sys.modules if m.startswith('mmstab'))))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    loaded = set(out.stdout.split())
    for above in ("controller", "codegen", "planner", "tasks", "workspace", "tracking"):
        assert f"mmstab.{above}" not in loaded
    assert {"mmstab.core.setting_checks", "mmstab.core.sizes", "mmstab.core.schema"} <= loaded


def test_importing_a_stage_registers_nothing():
    before = dict(SECTION_CHECKS)
    import mmstab.codegen  # noqa: F401
    import mmstab.control.controller  # noqa: F401
    import mmstab.planner  # noqa: F401

    assert dict(SECTION_CHECKS) == before
    assert set(SECTION_CHECKS) == {"planner", "controller", "codegen", "physics", "workspace"}
    with pytest.raises(TypeError):
        SECTION_CHECKS["extra"] = lambda p, s: None  # type: ignore[index]


def _weights_1_8(p, r):
    p["planner"]["w_stability"], p["planner"]["w_motion"] = 0.9, 0.9


@pytest.mark.parametrize("command", ["fig5", "workspace", "codegen", "track"])
def test_every_command_checks_the_planner_weights(tmp_path, capsys, command, monkeypatch):
    """fig5 once accepted weights summing to 1.8 and saved them: they are refused."""
    path = write_problem(tmp_path, _weights_1_8)
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    parser = experiments_parser if command == "fig5" else build_parser
    assert main([command, str(path), "-o", str(out)], parser=parser) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "planner.w_motion" in err and str(path) in err
    assert not out.exists() and not (tmp_path / "results").exists()


def test_controller_and_codegen_checks_moved_with_their_logic(tmp_path):
    cases = [
        (lambda p, r: p["controller"].__setitem__("kp", [1000.0] * 6), "controller.kp"),
        (lambda p, r: p["controller"].__setitem__("duration", 1e-4), "controller.duration"),
        (lambda p, r: p["codegen"].__setitem__("plugin", "qpoases"), "codegen.plugin"),
    ]
    for edit, field in cases:
        with pytest.raises(ConfigError) as info:
            load_problem(write_problem(tmp_path, edit))
        assert info.value.field == field


def test_planner_margin_is_an_optional_number(tmp_path):
    assert "margin" not in load_problem(RAMP_YAML).section("planner")
    path = write_problem(tmp_path, lambda p, r: p["planner"].__setitem__("margin", 25.0))
    assert load_problem(path).section("planner")["margin"] == 25.0
    path = write_problem(tmp_path, lambda p, r: p["planner"].__setitem__("margin", "big"))
    with pytest.raises(ConfigError) as info:
        load_problem(path)
    assert info.value.field == "planner.margin"


# ------------------------------------------------------------------------ command-line options
@pytest.mark.parametrize("value", ["nan", "inf", "-1", "0"])
def test_track_duration_is_checked_before_any_work(tmp_path, capsys, monkeypatch, value):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    assert main(["track", str(RAMP_YAML), "--duration", value, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("mmstab: error: --duration") and "\n" not in err
    assert not out.exists() and not (tmp_path / "results").exists()  # no workspace built


def test_track_duration_beyond_memory_is_refused_even_forced(memory_16gb):
    with pytest.raises(MmstabError, match="--duration: .* memory") as info:
        check_duration(1e9, 0.001, force_size=True)
    assert "16 GB" in str(info.value)
    check_duration(30.0, 0.001)  # the default lap


def test_track_plugin_option_is_checked_before_any_work(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["track", str(RAMP_YAML), "--plugin", "gurobi"]) == 2
    assert "--plugin" in capsys.readouterr().err
    assert main(["track", str(RAMP_YAML), "--backend", "generated", "--plugin", "qpoases"]) == 2
    assert "qpOASES" in capsys.readouterr().err
    assert not (tmp_path / "results").exists()


# ------------------------------------------------------------------------------------- sizes
def test_default_problem_is_within_the_bounds(memory_16gb):
    found = sizes.check_sizes(RAMP_YAML, load_problem(RAMP_YAML).data)
    assert found["workspace"].work.startswith(f"{24 * 29 * 25 * 25} postures")
    assert found["controller"].work.startswith("30000 control periods")
    assert found["animation"].work.startswith("90 frames")
    assert found["sweep"].work.startswith(f"{11 * 100} sweep samples")
    for est in found.values():
        assert est.seconds < sizes.MAX_SECONDS and est.bytes < 0.8 * 16 * GB


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda p: p["workspace"].__setitem__("grid", [1000000] * 4), "workspace.grid"),
        (lambda p: p["controller"].__setitem__("duration", 1e7), "controller.duration"),
        (lambda p: p["planner"].__setitem__("popsize", 10**9), "planner.popsize"),
        (lambda p: p["sweep"].__setitem__("samples", 10**9), "sweep.samples"),
        (lambda p: p["sweep"].__setitem__("poses", 10**9), "sweep.poses"),
        (
            lambda p: p["workspace"].__setitem__("precision_samples", 10**9),
            "workspace.precision_samples",
        ),
    ],
)
def test_beyond_memory_is_refused_naming_the_field(tmp_path, memory_16gb, capsys, edit, field):
    path = write_problem(tmp_path, lambda p, r: edit(p))
    with pytest.raises(ConfigError) as info:
        load_problem(path, force_size=True)  # memory bounds are not overridable
    assert info.value.field == field
    assert "memory" in info.value.message and "16 GB available" in info.value.message
    argv = ["fig5", str(path), "--force-size", "-o", str(tmp_path / "o")]
    assert main(argv, parser=experiments_parser) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and field in err


def test_grid_memory_estimate_counts_the_postures(memory_16gb):
    est = sizes.workspace_estimate([1000000] * 4)
    assert est.bytes == pytest.approx(1e24 * sizes.WS_BYTES_PER_POSTURE, rel=1e-12)
    assert "1000000000000000000000000 postures" in est.work


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (
            lambda p: p["planner"].update(popsize=200_000, max_iterations=1000),
            "planner.popsize",
        ),
        (lambda p: p["planner"].update(max_iterations=10**6), "planner.max_iterations"),
        (lambda p: p["planner"].update(poses=10**5), "planner.poses"),
        (lambda p: p["animation"].update(frames=20000, width=64, height=64), "animation.frames"),
    ],
)
def test_beyond_the_time_bound_needs_force_size(tmp_path, memory_16gb, edit, field):
    path = write_problem(tmp_path, lambda p, r: edit(p))
    with pytest.raises(ConfigError) as info:
        load_problem(path)
    assert info.value.field == field
    assert "on this machine" in info.value.message and "--force-size" in info.value.message
    problem = load_problem(path, force_size=True)
    assert problem.force_size


def test_animation_frames_are_capped_by_the_samples():
    section = {"frames": 10**9, "width": 100, "height": 100}
    est = sizes.animation_estimate(section, samples=301)
    assert est.work.startswith("301 frames")
    assert est.seconds == pytest.approx(301 * sizes.ANIM_SECONDS_PER_FRAME)


def test_planner_time_estimate_by_hand():
    section = {"poses": 10, "popsize": 16, "max_iterations": 20, "starts": [2.0, 5.0]}
    est = sizes.planner_estimate({**section, "max_resample": 3})
    per_generation = 16 * sizes.PLAN_SECONDS_PER_SAMPLE * 4 + sizes.PLAN_SECONDS_PER_GENERATION
    assert est.seconds == pytest.approx(10 * 2 * 20 * per_generation + 10 * 0.1)


def test_planner_estimate_counts_restarts_and_the_coarse_pass_by_hand():
    section = {"poses": 10, "popsize": 16, "max_iterations": 20, "starts": [2.0, 5.0]}
    sample = sizes.PLAN_SECONDS_PER_SAMPLE * 2
    gen = sizes.PLAN_SECONDS_PER_GENERATION
    est = sizes.planner_estimate(
        {
            **section,
            "max_resample": 1,
            "restarts": 2,
            "seeding": "coarse",
            "coarse_seeds": 3,
            "coarse_samples": 10**9,
        }
    )
    # 3 seeds x (20 generations of 16, 32 and 64 samples), plus the coarse pass, per pose
    per_start = 20 * (16 * sample + gen) + 20 * (32 * sample + gen) + 20 * (64 * sample + gen)
    coarse = 10**9 * sizes.PLAN_SECONDS_PER_SAMPLE
    assert est.seconds == pytest.approx(10 * (3 * per_start + coarse) + 10 * 0.1)
    assert est.field == "planner.coarse_samples" and "2 restarts" in est.work
    assert est.bytes == pytest.approx(10**9 * sizes.PLAN_BYTES_PER_SAMPLE)


def test_long_work_is_announced(capsys):
    sizes.announce(sizes.Estimate("workspace.grid", "9 postures", 12.0, 0.0))
    sizes.announce(sizes.Estimate("workspace.grid", "8 postures", 2.0, 0.0))
    err = capsys.readouterr().err
    assert err == "mmstab: workspace.grid: 9 postures, about 12 s on this machine\n"


def test_human_units():
    assert sizes.human_bytes(400) == "400 B"
    assert sizes.human_bytes(2.5e9) == "2.5 GB"
    assert sizes.human_seconds(30) == "30 s"
    assert sizes.human_seconds(600) == "10 min"
    assert sizes.human_seconds(7200) == "2 h"
    assert sizes.human_seconds(86400 * 10) == "10 days"


def test_available_memory_is_positive_and_finite():
    mem = sizes.available_memory()
    assert 0 < mem < math.inf


def test_workspace_memory_constant_bounds_the_measured_peak(robot):
    """The workspace memory estimate bounds what the build allocates (tracemalloc)."""
    import tracemalloc

    from mmstab.workspace import build_workspace

    grid = (16, 12, 12, 12)
    n = int(np.prod(grid))
    build_workspace(robot, (4, 3, 3, 3), progress=False)  # warm caches (checker, imports)
    tracemalloc.start()
    try:
        build_workspace(robot, grid, progress=False)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < sizes.workspace_estimate(grid).bytes
    assert peak < n * sizes.WS_BYTES_PER_POSTURE + sizes.WS_CHUNK_BYTES  # one process here
    assert peak > n * 56  # at least the postures (32 B) and CoMs (24 B) it returns


def test_generated_map_estimate_counts_the_generators_cells():
    """The bound counts exactly the cells the generator would allocate (seeded sizes)."""
    from mmstab.terrain.generators import Grid

    rng = np.random.default_rng(7)
    for _ in range(20):
        size = (float(rng.uniform(0.5, 40.0)), float(rng.uniform(0.5, 40.0)))
        res = float(rng.choice([0.01, 0.02, 0.05, 0.1, 0.25]))
        est = sizes.terrain_estimate({"generate": {"size": list(size), "resolution": res}})
        grid = Grid.of_size(size, res)
        assert est is not None and est.bytes == grid.nx * grid.ny * sizes.TERRAIN_BYTES_PER_CELL
    assert sizes.terrain_estimate({"slope": 0.1}) is None


def test_a_10_km_map_at_1_cm_is_refused_before_any_allocation(tmp_path):
    data = yaml.safe_load((ROOT / "problems" / "rough.yaml").read_text())
    data["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    data["terrain"]["generate"].update(size=[10000.0, 10000.0], resolution=0.01)
    path = tmp_path / "huge.yaml"
    path.write_text(yaml.safe_dump(data))
    proc = subprocess.run(
        [sys.executable, "-m", "mmstab", "plan", str(path)], capture_output=True, text=True
    )
    assert proc.returncode == 2
    line = proc.stderr.strip()
    assert "\n" not in line and "terrain.generate.size" in line and "1e+12 map cells" in line
