from __future__ import annotations

import copy
import functools
import os
import sys

# One OpenBLAS thread per test process, set before NumPy loads it (subprocesses inherit it):
# make test runs two workers on two cores, and OpenBLAS's threads on an oversubscribed
# machine made each small LAPACK call wait 0.1-0.25 s (a 200-triangulation test: 21 s -> 0.5 s).
# A pytest plugin that imports NumPy first defeats it (zarr's did: pyproject.toml's addopts
# leaves it out; the SVD of a 100 x 2 array took 6 ms of CPU instead of 13 us): say so.
if "numpy" in sys.modules and "OPENBLAS_NUM_THREADS" not in os.environ:
    import warnings

    warnings.warn(
        "NumPy was imported before tests/conftest.py (a pytest plugin?): OpenBLAS keeps its "
        "threads; set OPENBLAS_NUM_THREADS=1 or leave the plugin out (-p no:NAME)",
        stacklevel=1,
    )
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]

# With PYTHONDONTWRITEBYTECODE set (some sandboxes and CI images set it), every test worker
# and every command a test starts compiled mmstab from source again, and the test that
# imports each module alone compiled a module's chain once per module (18.7 s -> 8.4 s of
# CPU with the bytecode cached). The tests write their bytecode where Python does by default,
# __pycache__ beside the sources (git-ignored), for this process and the processes it starts.
# Not under a PYTHONPYCACHEPREFIX: Python then reads no bytecode from beside the sources, so
# the virtualenv's compiled libraries were compiled again (a fresh clone's collection took
# 14.1 s instead of 7.4 s, in each worker).
if sys.dont_write_bytecode or os.environ.get("PYTHONDONTWRITEBYTECODE"):
    sys.dont_write_bytecode = False
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
PROBLEMS = ROOT / "problems"
#: The tests' cache folder (workspaces, roadmaps, compiled C): the repository's own
#: results/workspace, built on first use in a fresh clone, never the user's cache folder;
#: a caller's $MMSTAB_CACHE wins.
os.environ.setdefault("MMSTAB_CACHE", str(ROOT / "results" / "workspace"))
ROBOT_YAML = PROBLEMS / "robots" / "cameleon.yaml"
RAMP_YAML = PROBLEMS / "ramp.yaml"

# The repository's experiments/ (not installed) imports from its root, in this process and
# in the subprocesses the tests start (``python -m experiments ...``) wherever they run.
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
os.environ["PYTHONPATH"] = os.pathsep.join(
    p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p
)

# Test modules import helpers from one another by name (``from test_under_arm import ...``)
# across the stage folders (docs/testing.md): every folder of tests/ is on the import path,
# whichever file is collected first (module names stay unique, as pytest needs anyway).
for _folder in sorted(p for p in Path(__file__).resolve().parent.iterdir() if p.is_dir()):
    if not _folder.name.startswith((".", "_")) and str(_folder) not in sys.path:
        sys.path.append(str(_folder))


#: A user's robot as docs/robot.md tells one to write it: a 32 kg "scout" with 0.6 m tracks,
#: flat 25 cm flippers and a 3-joint arm with 1-1.2 rad/s joints.
SCOUT: dict[str, Any] = {
    "name": "scout",
    "note": "a small tracked robot with a 3-joint arm, written from docs/robot.md",
    "base": {
        "mass": 32.0,
        "com": [0.0, 0.0, 0.08],
        "body": {"size": [0.55, 0.32, 0.14], "center": [0.0, 0.0, 0.1]},
        "tracks": {"length": 0.6, "width": 0.09, "height": 0.16, "separation": 0.42,
                   "sprocket_radius": 0.08, "velocity_limit": 10.0},
        "flippers": {"length": 0.25, "width": 0.06, "thickness": 0.05,
                     "pivot": [0.3, 0.255, 0.08], "angle": 0.0},
    },
    "arm": {
        "mount": {"xyz": [0.1, 0.0, 0.17], "rpy": [0, 0, 0]},
        "links": [
            {"name": "turret", "dh": {"a": 0.0, "alpha": 1.5708, "d": 0.12, "theta_offset": 0.0},
             "mass": 2.0, "com": [0.0, -0.06, 0.0],
             "geometry": {"type": "capsule", "radius": 0.05, "p0": [0, -0.12, 0], "p1": [0, 0, 0]},
             "limits": {"lower": -3.1, "upper": 3.1, "velocity": 1.0}},
            {"name": "upper", "dh": {"a": 0.35, "alpha": 0.0, "d": 0.0, "theta_offset": 0.0},
             "mass": 2.5, "com": [-0.17, 0, 0],
             "geometry": {"type": "capsule", "radius": 0.035, "p0": [-0.35, 0, 0], "p1": [0, 0, 0]},
             "limits": {"lower": -0.2, "upper": 2.6, "velocity": 1.0}},
            {"name": "fore", "dh": {"a": 0.3, "alpha": 0.0, "d": 0.0, "theta_offset": 0.0},
             "mass": 1.5, "com": [-0.15, 0, 0],
             "geometry": {"type": "capsule", "radius": 0.03, "p0": [-0.3, 0, 0], "p1": [0, 0, 0]},
             "limits": {"lower": -2.6, "upper": 2.6, "velocity": 1.2}},
        ],
        "stowed": [0.0, 0.2, -0.3],
    },
}  # fmt: skip


def ditch_ground(rng: np.random.Generator, slope_deg: float = 15.0, bump_m: float = 0.06) -> Any:
    """A user's 10 m map: a side slope (uphill +y), a 0.6 m wide, 20 cm deep ditch across
    x = 0, six seeded bumps of ``bump_m`` (a :class:`mmstab.terrain.heightmap.Heightmap`)."""
    from mmstab.terrain.heightmap import Heightmap

    res = 0.05
    x = np.arange(-5, 5 + 1e-9, res)
    X, Y = np.meshgrid(x, x)
    z = np.tan(np.radians(slope_deg)) * Y - 0.20 * (np.abs(X) < 0.3)
    for _ in range(6):
        cx, cy = rng.uniform(-4, 4, 2)
        z += bump_m * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * 0.3**2))
    return Heightmap.build(z, res, [x[0], x[0]], "ditch")


def random_robot(rng: np.random.Generator) -> dict[str, Any]:
    """A robot file's mapping drawn at random: a user's robot the tests did not write.

    SCOUT's layout scaled by 0.6-1.8, a base of 10-150 kg with its CoM anywhere over the
    tracks' middle, no flippers, a front pair or both pairs (0.1-0.8 rad up), and an arm of
    3-6 joints (a turret, then links of 0.05-0.45 m about parallel or crossed axes, 0.5-4 kg,
    0.8-2 rad/s) on top of the body; its stowed posture is the first drawn that the robot
    file's loader takes (clear of the base and above the tracks' plane), as a user would
    choose it.
    """
    import dataclasses

    from mmstab.model.robot import robot_from_dict
    from mmstab.model.touching import stowed_refusal, with_touching_allowed

    r = copy.deepcopy(SCOUT)
    r["name"] = "drawn"
    scale = rng.uniform(0.6, 1.8)
    length, separation = 0.6 * scale * rng.uniform(0.8, 1.2), 0.42 * scale * rng.uniform(0.7, 1.3)
    width, height = 0.09 * scale, 0.16 * scale * rng.uniform(0.8, 1.3)
    body_h = height * rng.uniform(0.6, 1.0)
    top = height * 0.35 + body_h
    r["base"] = {
        "mass": float(rng.uniform(10, 150)),
        "com": [float(rng.uniform(-0.05, 0.05) * scale), float(rng.uniform(-0.02, 0.02)),
                float(height * rng.uniform(0.4, 0.8))],
        "body": {"size": [float(length * rng.uniform(0.8, 1.05)), float(separation - width - 0.01),
                          float(body_h)], "center": [0.0, 0.0, float(top - body_h / 2)]},
        "tracks": {"length": float(length), "width": float(width), "height": float(height),
                   "separation": float(separation), "sprocket_radius": float(height / 2),
                   "velocity_limit": 10.0},
    }  # fmt: skip
    pair = {"length": float(0.25 * scale), "width": float(0.06 * scale),
            "thickness": float(0.05 * scale),
            "pivot": [float(length / 2), float((separation + width) / 2 + 0.035 * scale),
                      float(height / 2)]}  # fmt: skip
    pairs = int(rng.integers(0, 3))
    if pairs >= 1:
        r["base"]["flippers"] = {**pair, "angle": float(rng.uniform(0.1, 0.8))}
    if pairs == 2:
        rear = [-pair["pivot"][0], *pair["pivot"][1:]]
        r["base"]["rear_flippers"] = {**pair, "pivot": rear, "angle": float(rng.uniform(0.1, 0.8))}
    n = int(rng.integers(3, 7))
    links = []
    for i in range(n):
        a = 0.0 if i == 0 else float(rng.uniform(0.05, 0.45) * scale)
        alpha = 1.5708 if i == 0 else float(rng.choice([0.0, 1.5708, -1.5708]))
        d = float(rng.uniform(0.05, 0.15) * scale) if i == 0 else 0.0
        p0 = [-a, 0.0, 0.0] if a > 0 else [0.0, 0.0, -d]
        links.append({
            "name": f"link{i}", "dh": {"a": a, "alpha": alpha, "d": d, "theta_offset": 0.0},
            "mass": float(rng.uniform(0.5, 4.0)), "com": [p0[0] / 2, 0.0, p0[2] / 2],
            "geometry": {"type": "capsule", "radius": float(rng.uniform(0.02, 0.05)),
                         "p0": p0, "p1": [0.0, 0.0, 0.0]},
            "limits": {"lower": -3.0 if i == 0 else -2.5, "upper": 3.0 if i == 0 else 2.5,
                       "velocity": float(rng.uniform(0.8, 2.0))},
        })  # fmt: skip
    r["arm"] = {
        "mount": {"xyz": [float(rng.uniform(-0.2, 0.2) * scale), 0.0, float(top + 0.01)],
                  "rpy": [0.0, 0.0, float(rng.uniform(-0.3, 0.3))]},
        "links": links,
        "stowed": [0.0] * n,
    }  # fmt: skip
    robot = with_touching_allowed(robot_from_dict(r))[0]
    for _ in range(2000):
        q = np.r_[0.0, rng.uniform(-2.0, 2.0, n - 1)]
        if stowed_refusal(dataclasses.replace(robot, stowed=q)) is None:
            r["arm"]["stowed"] = [float(v) for v in q]
            return r
    raise AssertionError("no clear stowed posture drawn")


#: Marks of the tests that take seconds: their files go to the workers first.
HEAVY_MARKS = ("mujoco", "slow", "dask", "browser", "ros")


def pytest_collection_modifyitems(config: Any, items: list[Any]) -> None:
    """The files with the most heavy tests first, then the others by their test count.

    ``make test`` hands whole files to two workers in this order (``--dist loadfile
    --no-loadscope-reorder``): a file of one 20 s MuJoCo test sent last ran alone while the
    other worker idled, and the suite's time varied by 20 s from run to run. Within a file
    the order is kept.
    """
    heavy: dict[Any, int] = {}
    count: dict[Any, int] = {}
    for item in items:
        count[item.path] = count.get(item.path, 0) + 1
        marked = any(item.get_closest_marker(m) for m in HEAVY_MARKS)
        heavy[item.path] = heavy.get(item.path, 0) + int(marked)
    items.sort(key=lambda item: (-heavy[item.path], -count[item.path], str(item.path)))


@pytest.fixture(scope="session")
def robot():
    from mmstab.model.robot import load_robot

    return load_robot(ROBOT_YAML)


@pytest.fixture(scope="session")
def problem():
    from mmstab.core.problem import load_problem

    return load_problem(RAMP_YAML)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


def random_postures(robot, rng: np.random.Generator, n: int) -> np.ndarray:
    """Postures drawn uniformly within the joint limits."""
    return rng.uniform(robot.joint_lower, robot.joint_upper, size=(n, 4))


@functools.cache
def _default_files() -> tuple[dict[str, Any], dict[str, Any]]:
    """The default problem and its robot as parsed once per process (copied for each use)."""
    return yaml.safe_load(RAMP_YAML.read_text()), yaml.safe_load(ROBOT_YAML.read_text())


def write_problem(tmp_path: Path, edit=None, name: str = "problem.yaml") -> Path:
    """Copy the default problem (and its robot) to tmp_path, apply ``edit(problem, robot)``."""
    prob, rob = copy.deepcopy(_default_files())
    if edit is not None:
        edit(prob, rob)
    (tmp_path / "robots").mkdir(exist_ok=True)
    (tmp_path / "robots" / "cameleon.yaml").write_text(yaml.safe_dump(rob))
    prob["robot"] = prob.get("robot", "robots/cameleon.yaml")
    path = tmp_path / name
    path.write_text(yaml.safe_dump(prob))
    return path


def validation_route_file(k: int, directory: Path) -> Path:
    """Route k of ``make validate-routes`` (its seeded map and route) as a problem file."""
    sys.path.insert(0, str(ROOT))
    from experiments.validate_routes import load_settings, route_problem

    data = route_problem(load_settings(ROOT / "problems" / "validate_routes.yaml"), k)
    path = directory / f"route{k:02d}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def assert_bad_planner_key(tmp_path: Path, capsys, key: str, value: Any) -> Path:
    """``planner.<key>: value`` is bad input: ConfigError naming the field, ``mmstab plan``
    exits 2 with one line naming the file and the field, and writes nothing."""
    from mmstab.cli import main
    from mmstab.core.files import ConfigError
    from mmstab.core.problem import load_problem

    path = write_problem(tmp_path, lambda p, r: p["planner"].__setitem__(key, value))
    with pytest.raises(ConfigError) as info:
        load_problem(path)
    assert info.value.field == f"planner.{key}"
    out = tmp_path / "out"
    assert main(["plan", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"planner.{key}" in err and str(path) in err
    assert not out.exists()  # nothing half-written
    return path


#: The first release's planner search (the plan the tracking tests were written for; the
#: default search of problems/ramp.yaml now differs, docs/planner.md).
FIRST_RELEASE_PLANNER = {
    "method": "cmaes",
    "seeding": "starts",
    "starts": [2.0, 5.0],
    "sigma0": 0.05,
    "sigma0_unit": "m",
    "popsize": 16,
    "max_iterations": 20,
    "restarts": 0,
    "turret_window": None,
}


def with_first_release_planner(problem):
    """The same problem with the first release's planner search."""
    from mmstab.core.problem import problem_from_dict

    data = copy.deepcopy(problem.data)
    data["planner"].update(FIRST_RELEASE_PLANNER)
    return problem_from_dict(data, problem.path)


def assert_same_numbers(got: Any, want: Any, rel: float = 1e-9, where: str = "") -> None:
    """Two JSON-like trees equal, their floats to ``rel`` (a run on another processor rounds
    its sums in another order: the last bits move, nothing else may)."""
    if isinstance(want, dict):
        assert isinstance(got, dict) and got.keys() == want.keys(), where
        for k in want:
            assert_same_numbers(got[k], want[k], rel, f"{where}.{k}")
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), where
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            assert_same_numbers(g, w, rel, f"{where}[{i}]")
    elif isinstance(want, float) and not isinstance(got, bool):
        assert got == pytest.approx(want, rel=rel, abs=1e-300, nan_ok=True), where
    else:
        assert got == want, where


def summary_keys(tree: Any, depth: int = 4, where: str = "") -> tuple[set[str], set[str]]:
    """The key paths of a summary's nested mappings, ``depth`` levels down, and those of
    them whose value is None (an event that did not happen: ``stalled``, ``slid``): their
    sub-keys come and go with the run."""
    keys: set[str] = set()
    none: set[str] = set()
    if isinstance(tree, dict) and depth > 0:
        for k, v in tree.items():
            keys.add(f"{where}/{k}")
            if v is None:
                none.add(f"{where}/{k}")
            sub, sub_none = summary_keys(v, depth - 1, f"{where}/{k}")
            keys |= sub
            none |= sub_none
    return keys, none


def assert_committed_has_the_keys(fresh: dict[str, Any], committed: str) -> None:
    """A committed summary (``results/...``) has the keys the code writes now, and no others:
    a result folder older than its command fails here (rerun its ``make`` target)."""
    import json

    a, a_none = summary_keys(json.loads((ROOT / committed).read_text()))
    b, b_none = summary_keys(fresh)
    events = a_none | b_none
    a, b = ({k for k in x if not any(k.startswith(e + "/") for e in events)} for x in (a, b))
    assert a == b, f"{committed}: only committed {sorted(a - b)}, only written {sorted(b - a)}"
