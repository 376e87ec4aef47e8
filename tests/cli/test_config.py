"""Bad input: one line naming the file and the field, exit status 2, nothing written."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from conftest import ROOT, write_problem

from experiments.__main__ import build_parser as experiments_parser
from mmstab.cli import main
from mmstab.core.files import ConfigError
from mmstab.core.problem import load_problem


def _swap_limits(p, r):
    lim = r["arm"]["links"][2]["limits"]
    lim["lower"], lim["upper"] = lim["upper"], lim["lower"]


CASES = [
    (
        "wrong type",
        lambda p, r: r["base"].__setitem__("mass", "heavy"),
        "cameleon.yaml",
        "base.mass",
    ),
    ("missing key", lambda p, r: p["terrain"].pop("slope"), "problem.yaml", "terrain.slope"),
    (
        "unknown key",
        lambda p, r: p["sweep"].__setitem__("sampels", 3),
        "problem.yaml",
        "sweep.sampels",
    ),
    ("unknown section", lambda p, r: p.__setitem__("extra", {}), "problem.yaml", "extra"),
    (
        "nan",
        lambda p, r: r["arm"]["links"][1].__setitem__("mass", float("nan")),
        "cameleon.yaml",
        "arm.links[1].mass",
    ),
    (
        "negative mass",
        lambda p, r: r["base"].__setitem__("mass", -48.0),
        "cameleon.yaml",
        "base.mass",
    ),
    ("inverted limit", _swap_limits, "cameleon.yaml", "arm.links[2].limits"),
    (
        "short vector",
        lambda p, r: r["base"].__setitem__("com", [0.0, 0.1]),
        "cameleon.yaml",
        "base.com",
    ),
    (
        "stowed out of limits",
        lambda p, r: r["arm"]["stowed"].__setitem__(1, 5.0),
        "cameleon.yaml",
        "arm.stowed[1]",
    ),
    (
        "flipper in the ground",
        lambda p, r: r["base"]["flippers"].__setitem__("angle", -1.2),
        "cameleon.yaml",
        "base.flippers.angle",
    ),
    (
        "unknown arm-CoM frame",
        lambda p, r: p["controller"].__setitem__("arm_com_frame", "world"),
        "problem.yaml",
        "controller.arm_com_frame",
    ),
    (
        "dynamic fraction above 1",
        lambda p, r: p["controller"].__setitem__("dynamic_fraction", 1.5),
        "problem.yaml",
        "controller.dynamic_fraction",
    ),
    (
        "dynamic fraction not a number",
        lambda p, r: p["controller"].__setitem__("dynamic_fraction", "half"),
        "problem.yaml",
        "controller.dynamic_fraction",
    ),
    (
        "missing robot",
        lambda p, r: p.__setitem__("robot", "robots/none.yaml"),
        "problem.yaml",
        "robot",
    ),
]


@pytest.mark.parametrize("case,edit,filename,field", CASES, ids=[c[0] for c in CASES])
def test_bad_input_names_file_and_field(tmp_path, capsys, case, edit, filename, field):
    path = write_problem(tmp_path, edit)
    with pytest.raises(ConfigError) as info:
        load_problem(path)
    assert info.value.path.endswith(filename)
    assert info.value.field == field
    out = tmp_path / "out"
    assert main(["fig5", str(path), "-o", str(out)], parser=experiments_parser) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert filename in err and field in err and "Traceback" not in err
    assert not out.exists()


def test_cli_subprocess_bad_file_exit_status(tmp_path):
    path = write_problem(tmp_path, lambda p, r: r["base"].__setitem__("mass", -1.0))
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [sys.executable, "-m", "experiments", "fig6", str(path), "-o", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "base.mass" in proc.stderr
    assert not (tmp_path / "o").exists()
    missing = subprocess.run(
        [sys.executable, "-m", "experiments", "fig5", str(tmp_path / "no.yaml")],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
    )
    assert missing.returncode == 2 and "no.yaml" in missing.stderr


def _laughs(levels: int, width: int = 9) -> str:
    """A "billion laughs" YAML: each level aliases the one below ``width`` times."""
    lines = ["a0: &a0 [" + ", ".join(['"lol"'] * width) + "]"]
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * width) + "]")
    return "\n".join([*lines, f"robot: *a{levels - 1}"]) + "\n"


def test_yaml_alias_expansion_is_counted_and_bounded(tmp_path):
    import yaml

    from mmstab.core.files import MAX_YAML_NODES, ConfigError, _expanded_size, read_yaml

    # by hand: a list of 3 scalars is 4 nodes; a list aliasing it twice is 1 + 2 * 4 = 9; the
    # top mapping holds 3 keys + the two lists + the alias again: 1 + 3 + 4 + 9 + 4 = 21
    small = "a: &a [1, 2, 3]\nb: [*a, *a]\nc: *a\n"
    assert _expanded_size(yaml.compose(small), {}) == 21
    ok = tmp_path / "ok.yaml"
    ok.write_text(small)
    assert read_yaml(ok)["b"] == [[1, 2, 3], [1, 2, 3]]
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(_laughs(10))  # 9**10 scalars: refused while still a node graph
    with pytest.raises(ConfigError, match="aliases") as err:
        read_yaml(bomb)
    assert str(bomb) in str(err.value)
    assert _expanded_size(yaml.compose(_laughs(5)), {}) < MAX_YAML_NODES  # 9**5: allowed


def test_cli_refuses_a_yaml_alias_bomb_in_one_line(tmp_path):
    import subprocess
    import sys

    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(_laughs(10))
    proc = subprocess.run(
        [sys.executable, "-m", "mmstab", "plan", str(bomb)], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "YAML nodes" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_planner_that_gives_up_exits_6_not_2(tmp_path, monkeypatch, capsys):
    """A search that gives up is no bad input: its own status, one line naming the search."""
    import mmstab.planner.searches.sequence as sequence

    def edit(p, r):
        p["workspace"]["grid"] = [8, 6, 6, 6]
        p["planner"].update(method="sequence", poses=4)

    path = write_problem(tmp_path, edit)
    monkeypatch.chdir(tmp_path)  # the command writes in its working folder
    monkeypatch.setattr(sequence, "MAX_ROUNDS", 0)  # gives up before its first round
    status = main(["plan", str(path), "-o", str(tmp_path / "out")])
    last = capsys.readouterr().err.splitlines()[-1]  # after the workspace's progress bar
    assert status == 6
    assert last == "mmstab: no plan: planner: sequence search did not settle in 0 rounds"


def test_sections_a_command_does_not_read_are_optional(tmp_path):
    """robot + terrain + path + planner margin is a whole route problem; typos still refused."""
    import yaml

    from mmstab.core.defaults import DEFAULT_SECTIONS

    ramp = yaml.safe_load((ROOT / "problems" / "ramp.yaml").read_text())
    assert {k: ramp[k] for k in DEFAULT_SECTIONS} == DEFAULT_SECTIONS  # the documented defaults
    rough = yaml.safe_load((ROOT / "problems" / "rough.yaml").read_text())
    minimal = {
        "robot": str(ROOT / "problems" / "robots" / "cameleon.yaml"),
        "terrain": rough["terrain"],
        "path": {
            "waypoints": [[-4.0, -0.5], [0.0, 0.5], [4.0, 0.0]],
            "speed": 0.3,
            "turn_radius": 1.0,
        },
        "planner": {"margin": 50.0},
    }
    path = tmp_path / "minimal.yaml"
    path.write_text(yaml.safe_dump(minimal))
    problem = load_problem(path)
    assert problem.route is not None and problem.section("planner")["margin"] == 50.0
    assert problem.section("controller")["dt"] == ramp["controller"]["dt"]
    assert problem.section("planner")["method"] == "roadmap"  # a route's default (ROUTE_METHOD)
    circle = {
        **minimal,
        "path": yaml.safe_load((ROOT / "problems" / "ramp.yaml").read_text())["path"],
    }
    path.write_text(yaml.safe_dump(circle))  # over rough.yaml's map: as a route there
    assert load_problem(path).section("planner")["method"] == "roadmap"
    path.write_text(yaml.safe_dump({**circle, "terrain": {"slope": 0.2}}))
    assert load_problem(path).section("planner")["method"] == "cmaes"  # the first release's
    minimal["planner"]["margn"] = 1.0
    path.write_text(yaml.safe_dump(minimal))
    with pytest.raises(ConfigError, match="margn"):
        load_problem(path)
