"""Seeded bad-input campaign over the command line (docs/cli.md, "Before any work").

Mutations of the shipped problems and robots, of the files they name (heightmaps, route
CSVs, recordings) and of the YAML text itself are fed to the commands that read them
(``rest``, ``urdf``, ``follow --bag``), in process. Every case must end one of two ways:
accepted (the input loaded), or exit status 2 with ONE line ``mmstab: error: ...`` naming
the file at fault and a field of it, no traceback, nothing written. A case marked
``must_refuse`` (NaN, an unknown key, a missing or garbage file, ...) may not be accepted.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import io
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import ROOT

from mmstab.cli import main

PROBLEMS = ("ramp.yaml", "rough.yaml", "kerb.yaml", "dem.yaml", "ramp_6dof.yaml")
ROBOTS = ("cameleon.yaml", "cameleon_6dof.yaml")


def _npy() -> bytes:
    out = io.BytesIO()
    np.save(out, np.zeros((8, 8)))
    return out.getvalue()


#: Bytes that are no format at all (NUL, high bytes, a stray zip/TIFF/MCAP magic), or
#: another one (a single .npy array).
GARBAGE = (
    _npy(),
    b"",
    b"\x00" * 64,
    bytes(range(256)),
    b"PK\x03\x04garbage",
    b"II*\x00\x08\x00\x00\x00junk",
    b"\x89MCAP0\r\n" + b"\x01" * 40,
    b"#ROSBAG V2.0\n" + b"\xff" * 40,
)


@dataclass
class Case:
    """One generated input.

    Attributes:
        name: what was done (for the failure message).
        files: relative path -> content (bytes, text, or a YAML-able object) of the case's folder.
        argv: the command line, ``{d}`` standing for the case's folder.
        culprit: the file the error must name (relative path).
        fields: one of these must appear in the error (empty: the file alone is enough).
        must_refuse: the input is invalid whatever the command (may not be accepted).
    """

    name: str
    files: dict[str, Any]
    argv: list[str]
    culprit: str
    fields: tuple[str, ...] = ()
    must_refuse: bool = False
    npz: dict[str, Any] = field(default_factory=dict)


@functools.cache
def _parsed(rel: str) -> dict[str, Any]:
    return yaml.safe_load((ROOT / "problems" / rel).read_text())


def _load(rel: str) -> dict[str, Any]:
    """A shipped file's content, parsed once per process (a copy each call: cases edit it)."""
    return copy.deepcopy(_parsed(rel))


def _leaves(node: Any, trail: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Paths (keys and indices) to every node below ``node``."""
    out: list[tuple[Any, ...]] = []
    items = (
        node.items()
        if isinstance(node, dict)
        else enumerate(node)
        if isinstance(node, list)
        else ()
    )
    for k, v in items:
        out.append((*trail, k))
        out += _leaves(v, (*trail, k))
    return out


def _get(node: Any, trail: tuple[Any, ...]) -> Any:
    for k in trail:
        node = node[k]
    return node


def _names(trail: tuple[Any, ...]) -> tuple[str, ...]:
    """The keys of a path (what an error may name), indices left out."""
    return tuple(str(k) for k in trail if isinstance(k, str))


def _problem_case(
    rng: np.random.Generator, what: str, edit: Callable[[dict[str, Any], dict[str, Any]], Any]
) -> Case:
    """A shipped problem and its robot copied to the case folder, then ``edit(problem, robot)``.

    ``edit`` returns (culprit, fields, must_refuse, name).
    """
    name = PROBLEMS[rng.integers(len(PROBLEMS))]
    prob = _load(name)
    robot_rel = prob["robot"]
    rob = _load(str(Path(robot_rel)))
    files: dict[str, Any] = {}
    if "file" in prob["terrain"]:  # the DEM: its file beside the copy
        files["terrain.tif"] = (ROOT / "problems" / prob["terrain"]["file"]).read_bytes()
        prob["terrain"]["file"] = "terrain.tif"
    prob["robot"] = "robot.yaml"
    culprit, fields, must, label = edit(prob, rob)
    files = {"problem.yaml": prob, "robot.yaml": rob, **files}
    ramp = isinstance(prob.get("terrain"), dict) and "slope" in prob["terrain"]
    pose = ["0.5", "0", "0.3"] if ramp else ["0", "0", "0"]
    argv = ["rest", "{d}/problem.yaml", "--pose", *pose]
    return Case(f"{name}: {what}: {label}", files, argv, culprit, fields, must)


# ------------------------------------------------------------------ samplers (take an rng)
def _pick(rng: np.random.Generator, doc: dict[str, Any], keep: Callable[[Any], bool]) -> tuple:
    trails = [t for t in _leaves(doc) if keep(_get(doc, t))]
    return trails[rng.integers(len(trails))]


def _target(rng: np.random.Generator, prob: dict, rob: dict) -> tuple[dict, str]:
    return (rob, "robot.yaml") if rng.random() < 0.4 else (prob, "problem.yaml")


def key_deleted(rng: np.random.Generator) -> Case:
    def edit(prob: dict, rob: dict) -> tuple:
        doc, culprit = _target(rng, prob, rob)
        trail = _pick(rng, doc, lambda v: True)
        parent = _get(doc, trail[:-1])
        if isinstance(parent, list):
            parent.pop(trail[-1])
        else:
            del parent[trail[-1]]
        return culprit, _names(trail), False, "/".join(map(str, trail))

    return _problem_case(rng, "key deleted", edit)


WRONG = ("heavy", [1.0, 2.0], {"a": 1}, True, None, [], "", "1e3", [[0.0]])


def wrong_type(rng: np.random.Generator) -> Case:
    def edit(prob: dict, rob: dict) -> tuple:
        doc, culprit = _target(rng, prob, rob)
        trail = _pick(rng, doc, lambda v: v is not None)
        old = _get(doc, trail)
        new = copy.deepcopy(WRONG[rng.integers(len(WRONG))])
        _get(doc, trail[:-1])[trail[-1]] = new
        number = isinstance(old, (int, float)) and not isinstance(old, bool)
        must = number and (isinstance(new, (str, list, dict, bool)) or new is None)
        if isinstance(old, str) and "terrain" in trail and "file" in trail:
            must = True  # a heightmap named by a number / list / mapping, or by ""
        return culprit, _names(trail), must, f"{'/'.join(map(str, trail))} = {new!r}"

    return _problem_case(rng, "wrong type", edit)


BAD_NUMBERS = (math.nan, math.inf, -math.inf, -1.0, 0.0, -1e-9, 1e300, 1e-300, 2**64, 10**400)


def bad_number(rng: np.random.Generator) -> Case:
    def edit(prob: dict, rob: dict) -> tuple:
        doc, culprit = _target(rng, prob, rob)
        trail = _pick(rng, doc, lambda v: isinstance(v, (int, float)) and not isinstance(v, bool))
        new = BAD_NUMBERS[rng.integers(len(BAD_NUMBERS))]
        _get(doc, trail[:-1])[trail[-1]] = new
        too_big = isinstance(new, int) and abs(new) >= 2**63  # NumPy's int64 cannot hold it
        must = too_big or not math.isfinite(new)
        return culprit, _names(trail), must, f"{'/'.join(map(str, trail))} = {new!r}"

    return _problem_case(rng, "bad number", edit)


def wrong_length(rng: np.random.Generator) -> Case:
    def edit(prob: dict, rob: dict) -> tuple:
        doc, culprit = _target(rng, prob, rob)
        trail = _pick(rng, doc, lambda v: isinstance(v, list) and v and not isinstance(v[0], dict))
        seq = _get(doc, trail)
        if rng.random() < 0.5:
            seq.pop()
        else:
            seq.append(copy.deepcopy(seq[-1]))
        return culprit, _names(trail), False, f"{'/'.join(map(str, trail))} has {len(seq)}"

    return _problem_case(rng, "wrong length", edit)


def unknown_key(rng: np.random.Generator) -> Case:
    def edit(prob: dict, rob: dict) -> tuple:
        doc, culprit = _target(rng, prob, rob)
        dicts = [()] + [t for t in _leaves(doc) if isinstance(_get(doc, t), dict)]
        trail = dicts[rng.integers(len(dicts))]
        _get(doc, trail)["zz_typo"] = 1.0
        return culprit, ("zz_typo",), True, "/".join(map(str, (*trail, "zz_typo")))

    return _problem_case(rng, "unknown key", edit)


def inverted_limit(rng: np.random.Generator) -> Case:
    def edit(prob: dict, rob: dict) -> tuple:
        limits = [link["limits"] for link in rob["arm"]["links"]]
        if "limits" in rob["base"]["flippers"]:
            limits.append(rob["base"]["flippers"]["limits"])
        lim = limits[rng.integers(len(limits))]
        if rng.random() < 0.5:
            lim["lower"], lim["upper"] = lim["upper"], lim["lower"]
        else:
            lim["upper"] = lim["lower"]
        return "robot.yaml", ("limits",), True, f"limits {lim}"

    return _problem_case(rng, "inverted limit", edit)


def broken_yaml(rng: np.random.Generator) -> Case:
    """The problem or robot file's text broken: cut, garbage, a list, tabs, many documents."""
    case = _problem_case(rng, "text", lambda prob, rob: ("", (), True, ""))
    culprit = "robot.yaml" if rng.random() < 0.4 else "problem.yaml"
    text = yaml.safe_dump(case.files[culprit])
    kind = int(rng.integers(7))
    if kind == 0:
        new: Any = text[: int(rng.integers(1, len(text)))] + "\n  : [\n"
    elif kind == 1:
        new = GARBAGE[rng.integers(len(GARBAGE))]
    elif kind == 2:
        new = "- " + text.replace("\n", "\n  ")
    elif kind == 3:
        new = "\t" + text
    elif kind == 4:
        new = text + "---\n" + text
    elif kind == 5:
        new = "key: [unclosed\n"
    else:
        new = "just a scalar\n"
    case.files[culprit] = new
    case.culprit, case.fields, case.must_refuse = culprit, (), True
    case.name = f"broken yaml #{kind} in {culprit}"
    return case


def duplicate_key(rng: np.random.Generator) -> Case:
    """A key given twice in one mapping (YAML parsers keep the last one silently)."""
    case = _problem_case(rng, "text", lambda prob, rob: ("", (), True, ""))
    culprit = "robot.yaml" if rng.random() < 0.4 else "problem.yaml"
    doc = case.files[culprit]
    key = list(doc)[rng.integers(len(doc))]
    again = yaml.safe_dump({key: doc[key]}, sort_keys=False)
    case.files[culprit] = yaml.safe_dump(doc, sort_keys=False) + again
    case.culprit, case.fields, case.must_refuse = culprit, (key,), True
    case.name = f"{key} twice in {culprit}"
    return case


def _npz_claiming(shape: tuple[int, ...]) -> bytes:
    """An .npz whose elevation header claims ``shape`` over a few bytes of data."""
    import zipfile

    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        head, {"descr": "<f8", "fortran_order": False, "shape": shape}
    )
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        z.writestr("elevation.npy", head.getvalue() + b"\0" * 64)
        for key, value in (("resolution", np.float64(0.05)), ("origin", np.zeros(2))):
            one = io.BytesIO()
            np.save(one, value)
            z.writestr(f"{key}.npy", one.getvalue())
    return out.getvalue()


#: A 10 m square of two triangles (ASCII STL).
STL = (
    "solid s\n"
    + "".join(
        f"facet normal 0 0 1\nouter loop\n{a}{b}{c}endloop\nendfacet\n"
        for a, b, c in (
            ("vertex -5 -5 0\n", "vertex 5 -5 0\n", "vertex 5 5 0\n"),
            ("vertex -5 -5 0\n", "vertex 5 5 0\n", "vertex -5 5 0\n"),
        )
    )
    + "endsolid s\n"
)


def oversized_heightmap(rng: np.random.Generator) -> Case:
    """A heightmap whose cells would not fit in memory: a lying .npz header, a fine mesh."""
    kind = int(rng.integers(2))
    name, field = ("ground.npz", "") if kind == 0 else ("ground.stl", "resolution")

    def edit(prob: dict, rob: dict) -> tuple:
        prob["terrain"] = {"file": name}
        if kind == 1:
            prob["terrain"]["resolution"] = float(10.0 ** -rng.integers(6, 12))
        return name, (field,) if field else (), True, f"{name} too large"

    case = _problem_case(rng, "oversized", edit)
    side = int(10 ** rng.integers(6, 9))
    case.files[name] = _npz_claiming((side, side)) if kind == 0 else STL
    case.argv[-3:] = ["0", "0", "0"]
    return case


SUFFIXES = (".npz", ".tif", ".stl", ".mcap", ".bag")


def bad_terrain_file(rng: np.random.Generator) -> Case:
    """``terrain: {file: ...}``: missing, a folder, empty or garbage, by every extension."""
    suffix = SUFFIXES[rng.integers(len(SUFFIXES))]
    kind = int(rng.integers(3))

    def edit(prob: dict, rob: dict) -> tuple:
        prob["terrain"] = {"file": f"ground{suffix}"}
        if suffix == ".stl":
            prob["terrain"]["resolution"] = 0.05
        return "", (), True, f"ground{suffix} #{kind}"

    case = _problem_case(rng, "terrain file", edit)
    if kind == 1:
        case.files[f"ground{suffix}/metadata.yaml"] = GARBAGE[rng.integers(len(GARBAGE))]
    elif kind == 2:
        case.files[f"ground{suffix}"] = GARBAGE[rng.integers(len(GARBAGE))]
    case.culprit = f"ground{suffix}" if kind else "problem.yaml"
    case.fields = () if kind else ("terrain.file",)
    return case


def _grid(rng: np.random.Generator) -> dict[str, Any]:
    e = rng.normal(0.0, 0.01, (80, 80))
    return {"elevation": e, "resolution": np.float64(0.05), "origin": np.array([-2.0, -2.0])}


def _heightmap_mutations() -> list[tuple[str, str, Callable[[dict[str, Any]], Any]]]:
    def put(key: str, value: Any) -> Callable[[dict[str, Any]], Any]:
        return lambda a: a.__setitem__(key, value)

    return [
        ("elevation 1-D", "elevation", put("elevation", np.zeros(50))),
        ("elevation 3-D", "elevation", put("elevation", np.zeros((4, 4, 4)))),
        ("elevation 1 row", "elevation", put("elevation", np.zeros((1, 50)))),
        ("elevation int", "elevation", put("elevation", np.zeros((40, 40), dtype=int))),
        ("elevation bool", "elevation", put("elevation", np.zeros((40, 40), dtype=bool))),
        ("elevation complex", "elevation", put("elevation", np.zeros((40, 40), dtype=complex))),
        ("elevation text", "elevation", put("elevation", np.full((40, 40), "a"))),
        ("elevation all NaN", "elevation", put("elevation", np.full((40, 40), np.nan))),
        ("elevation inf", "elevation", lambda a: a["elevation"].__setitem__((3, 3), np.inf)),
        ("elevation empty", "elevation", put("elevation", np.zeros((0, 0)))),
        ("resolution 0", "resolution", put("resolution", np.float64(0.0))),
        ("resolution -1", "resolution", put("resolution", np.float64(-1.0))),
        ("resolution NaN", "resolution", put("resolution", np.float64(np.nan))),
        ("resolution 3x3", "resolution", put("resolution", np.full((3, 3), 0.05))),
        ("resolution complex", "resolution", put("resolution", np.complex128(0.05 + 1j))),
        ("resolution text", "resolution", put("resolution", np.array("0.05"))),
        ("resolution bool", "resolution", put("resolution", np.array(True))),
        ("origin 3", "origin", put("origin", np.zeros(3))),
        ("origin NaN", "origin", put("origin", np.array([np.nan, 0.0]))),
        ("origin complex", "origin", put("origin", np.array([1j, 0.0]))),
        ("origin 40x40", "origin", put("origin", np.zeros((40, 40)))),
        ("no origin", "origin", lambda a: a.pop("origin")),
        ("extra array", "extra", put("extra", np.zeros(2))),
    ]


def bad_heightmap(rng: np.random.Generator) -> Case:
    """An ``.npz`` heightmap with a wrong shape, dtype, NaNs, sizes, keys."""
    mutations = _heightmap_mutations()
    label, key, mutate = mutations[rng.integers(len(mutations))]

    def edit(prob: dict, rob: dict) -> tuple:
        prob["terrain"] = {"file": "ground.npz"}
        return "ground.npz", (key,), True, label

    case = _problem_case(rng, "heightmap", edit)
    case.argv[-3:] = ["0", "0", "0"]
    arrays = _grid(rng)
    mutate(arrays)
    case.npz = arrays
    return case


def _geotiff(raster: np.ndarray, tags: list[tuple]) -> bytes:
    import tifffile

    out = io.BytesIO()
    photometric = "rgb" if raster.ndim == 3 else None  # as tifffile stores it (no warning)
    tifffile.imwrite(out, raster, extratags=tags, photometric=photometric)
    return out.getvalue()


def bad_geotiff(rng: np.random.Generator) -> Case:
    """A GeoTIFF DEM with tags missing, of the wrong type or value, or the wrong raster."""
    e = rng.normal(0.0, 0.01, (40, 40)).astype(np.float32)
    scale = (33550, "d", 3, (0.05, 0.05, 0.0), True)
    tie = (33922, "d", 6, (0.0, 0.0, 0.0, -1.0, 1.0, 0.0), True)
    variants = [
        ("no pixel scale", e, [tie], "ModelPixelScaleTag"),
        ("no tie point", e, [scale], "ModelTiepointTag"),
        ("scale as text", e, [(33550, "s", 0, "abc", True), tie], "ModelPixelScaleTag"),
        ("tie as text", e, [scale, (33922, "s", 0, "abcdefgh", True)], "ModelTiepointTag"),
        ("scale 0", e, [(33550, "d", 3, (0.0, 0.05, 0.0), True), tie], "ModelPixelScaleTag"),
        ("integer band", e.astype(np.int16), [scale, tie], "band"),
        ("three bands", np.stack([e] * 3, -1), [scale, tie], "band"),
        (
            "all nodata",
            np.full((40, 40), -9999, np.float32),
            [scale, tie, (42113, "s", 0, "-9999", True)],
            "elevation",
        ),
        ("nodata text", e, [scale, tie, (42113, "s", 0, "xx", True)], "GDAL_NODATA"),
        ("one pixel", e[:1, :1], [scale, tie], "elevation"),
    ]
    label, raster, tags, field = variants[rng.integers(len(variants))]

    def edit(prob: dict, rob: dict) -> tuple:
        prob["terrain"] = {"file": "ground.tif"}
        return "ground.tif", (field,), True, label

    case = _problem_case(rng, "geotiff", edit)
    case.files["ground.tif"] = _geotiff(raster, tags)
    case.argv[-3:] = ["0", "0", "0"]
    return case


def bad_route_file(rng: np.random.Generator) -> Case:
    """``path: {file: route.csv}``: garbage, one waypoint, NaN, ragged, a folder."""
    rows = ["x,y", "-3.0,0.0", "0.0,0.5", "3.0,0.0"]
    texts: list[tuple[str, Any, bool]] = [
        ("garbage", GARBAGE[2], True),
        ("empty", "", True),
        ("one waypoint", "x,y\n1,2\n", True),
        ("nan", "\n".join([*rows, "nan,1"]) + "\n", True),
        ("ragged", "\n".join([*rows, "4,0,0.1"]) + "\n", True),
        ("words", "\n".join([*rows, "a,b"]) + "\n", True),
        ("duplicate", "\n".join([*rows, "3.0,0.0"]) + "\n", False),
        ("backwards yaw", "0,0,3.1\n1,0,3.1\n2,0,3.1\n", True),
        ("huge", "\n".join([*rows, "1e300,0"]) + "\n", False),
        ("tab separated", "-3\t0\n0\t0.5\n3\t0\n", True),
    ]
    label, text, must = texts[rng.integers(len(texts))]

    def edit(prob: dict, rob: dict) -> tuple:
        prob["terrain"] = _load("rough.yaml")["terrain"]
        prob["path"] = {"file": "route.csv", "speed": 0.25, "turn_radius": 0.5}
        return "route.csv", (), must, label

    case = _problem_case(rng, "route file", edit)
    case.files["route.csv"] = text
    case.argv[-3:] = ["0", "0", "0"]
    return case


def garbage_recording(rng: np.random.Generator) -> Case:
    """``follow --bag`` on a missing, empty or garbage recording."""
    suffix = (".mcap", ".bag", "")[rng.integers(3)]
    blob = GARBAGE[rng.integers(len(GARBAGE))]
    prob = _load("rough.yaml")
    prob["robot"] = "robot.yaml"
    files: dict[str, Any] = {"problem.yaml": prob, "robot.yaml": _load("robots/cameleon.yaml")}
    name = f"run{suffix}"
    kind = int(rng.integers(3))
    if kind == 1:
        files[f"{name}/metadata.yaml" if not suffix else name] = blob
    elif kind == 2:
        files[f"{name}/metadata.yaml"] = "rosbag2_bagfile_information: {version: 5}\n"
        name = f"run{suffix}"
    argv = ["follow", "{d}/problem.yaml", "--bag", f"{{d}}/{name}", "-o", "{d}/out"]
    return Case(f"follow --bag {name} #{kind} {blob[:8]!r}", files, argv, name, (), True)


def robot_command(rng: np.random.Generator) -> Case:
    """``mmstab urdf`` on a mutated robot file (its own loader, no problem)."""
    sampler = (key_deleted, wrong_type, bad_number, unknown_key, inverted_limit)[rng.integers(5)]
    for _ in range(20):
        case = sampler(rng)
        if case.culprit == "robot.yaml":
            break
    case.argv = ["urdf", "{d}/robot.yaml", "-o", "{d}/out/robot.urdf"]
    case.name = f"urdf: {case.name}"
    return case


SAMPLERS = (
    key_deleted,
    wrong_type,
    bad_number,
    wrong_length,
    unknown_key,
    inverted_limit,
    broken_yaml,
    bad_terrain_file,
    bad_heightmap,
    bad_geotiff,
    bad_route_file,
    garbage_recording,
    robot_command,
    duplicate_key,
    oversized_heightmap,
)


def sample_case(rng: np.random.Generator) -> Case:
    """One case from a sampler drawn by ``rng``."""
    return SAMPLERS[rng.integers(len(SAMPLERS))](rng)


# ---------------------------------------------------------------------- running a case
@dataclass
class Outcome:
    status: int | None  # None: an exception escaped main (a traceback)
    err: str
    wrote: bool


def write_case(case: Case, folder: Path) -> None:
    """The case's files in ``folder``."""
    for rel, content in case.files.items():
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        elif isinstance(content, str):
            path.write_text(content)
        else:
            path.write_text(yaml.safe_dump(content, sort_keys=False))
    if case.npz:
        with open(folder / "ground.npz", "wb") as fh:
            np.savez(fh, **case.npz)


def run_case(case: Case, folder: Path) -> Outcome:
    """Run the case's command in process: its exit status, its stderr, whether it wrote."""
    write_case(case, folder)
    argv = [a.replace("{d}", str(folder)) for a in case.argv]
    err, out = io.StringIO(), io.StringIO()
    status: int | None
    with (
        contextlib.redirect_stderr(err),
        contextlib.redirect_stdout(out),
        warnings.catch_warnings(),
    ):
        warnings.simplefilter("always")  # a warning printed on stderr is a second line
        warnings.showwarning = lambda m, c, f, n, file=None, line=None: print(  # noqa: ARG005
            f"{c.__name__}: {m}", file=err
        )
        try:
            status = main(argv)
        except SystemExit as exc:  # argparse
            status = exc.code if isinstance(exc.code, int) else 1
        except Exception as exc:  # noqa: BLE001 - what the campaign looks for
            status = None
            print(f"Traceback: {type(exc).__name__}: {exc}", file=err)
    return Outcome(status, err.getvalue(), (folder / "out").exists())


def classify(case: Case, outcome: Outcome) -> str:
    """``accepted``, ``clean`` (exit 2, one line naming file and field) or what is wrong."""
    lines = outcome.err.strip().splitlines()
    if outcome.status is None:
        return "traceback"
    if outcome.status == 0 or (outcome.status == 2 and "--pose" in outcome.err):
        return "accepted-invalid" if case.must_refuse else "accepted"
    if outcome.status != 2:
        return f"exit {outcome.status}"
    if outcome.wrote:
        return "wrote output"
    if len(lines) != 1 or not lines[0].startswith("mmstab: error: "):
        return "multi-line"
    if Path(case.culprit).name not in lines[0]:
        return "names another file"
    if case.fields and not any(f in lines[0] for f in case.fields):
        return "vague"
    return "clean"


SEEDS = range(200)


@pytest.mark.parametrize("seed", SEEDS)
def test_a_generated_bad_input_is_accepted_or_refused_in_one_line(seed, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing lands in the repository's results/
    case = sample_case(np.random.default_rng([2026, seed]))
    outcome = run_case(case, tmp_path / "case")
    verdict = classify(case, outcome)
    assert verdict in ("accepted", "clean"), f"{case.name}: {verdict}: {outcome.err!r}"
