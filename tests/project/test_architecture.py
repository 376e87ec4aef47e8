"""The import graph: every module imports alone, and dependencies point one way.

Layers, lowest first (``docs/architecture.md``): inputs → model/terrain → problem →
stability → workspace → planner → controller → codegen → application (simulation, rollouts,
drawing) → app → outputs (what a command writes) → CLI. The paper's figures and the studies
(the repository's ``experiments/``, not installed) sit above them all: nothing in mmstab
imports them. A module may import from its own layer or below, never
above. The static check reads every ``import`` of every module (function-level ones too);
the dynamic check imports each module with no other mmstab module loaded before it, in a
fresh interpreter (no cycle, no reliance on import order).
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT

PACKAGE = ROOT / "mmstab"

#: Layer of each package or module (prefix match: the longest listed prefix wins). The folder
#: tells the stage: a package's modules share its layer unless listed on their own.
LAYERS: dict[str, int] = {
    "mmstab": 12,  # the public API re-exports from every stage (lazily)
    "mmstab.core": 0,  # configuration files, schema, settings, sizes; C cache, pool, masks
    "mmstab.core.problem": 2,  # a validated problem: robot + terrain + path (the model below it)
    "mmstab.model": 1,
    "mmstab.terrain": 1,
    "mmstab.paths": 1,
    "mmstab.stability": 3,
    "mmstab.workspace": 4,
    "mmstab.planner": 5,
    "mmstab.control": 6,
    "mmstab.codegen": 7,
    "mmstab.runs": 8,
    "mmstab.physics": 8,
    "mmstab.viz": 8,
    "mmstab.app": 9,
    "mmstab.outputs": 10,  # what a command writes: its run, figures and summary
    "mmstab.viz.viewer": 10,  # the browser viewer replays runs and outputs
    "mmstab.cli": 11,
    "mmstab.__main__": 11,
}
#: Known upward imports, each with its reason; nothing else may point up.
ALLOWED_UP: set[tuple[str, str]] = set()  # none: the settings registry (mmstab.core.setting_checks)


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = sorted(module_name(p) for p in PACKAGE.rglob("*.py"))


def layer(module: str) -> int:
    best = max((p for p in LAYERS if module == p or module.startswith(p + ".")), key=len)
    return LAYERS[best]


def imports_of(module: str) -> set[str]:
    """Every mmstab module ``module`` imports, anywhere in its source."""
    path = ROOT / Path(*module.split("."))
    path = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "mmstab"}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.split(".")[0] == "mmstab":
                found.add(node.module)
                # ``from mmstab.runs import rollout``: a submodule, not a name
                found |= {
                    f"{node.module}.{a.name}"
                    for a in node.names
                    if f"{node.module}.{a.name}" in MODULES
                }
    return found - {module}


def top_level_entries() -> list[str]:
    """The packages and modules directly under ``mmstab/`` (dunder files aside)."""
    return sorted(
        p.stem if p.suffix == ".py" else p.name
        for p in PACKAGE.iterdir()
        if not p.name.startswith(("__", "."))
        and (p.suffix == ".py" or (p / "__init__.py").exists())
    )


def first_line(name: str) -> str:
    """The first line of a top-level entry's docstring (its one-line role)."""
    path = PACKAGE / name / "__init__.py"
    path = path if path.exists() else PACKAGE / f"{name}.py"
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    return doc.splitlines()[0] if doc else ""


def architecture_block() -> str:
    """The layer diagram and the package table of ``docs/architecture.md``, from the code."""
    entries = sorted(top_level_entries(), key=lambda e: (layer(f"mmstab.{e}"), e))
    by_layer: dict[int, list[str]] = {}
    for e in entries:
        by_layer.setdefault(layer(f"mmstab.{e}"), []).append(e)
    lines = ["```"]
    lines += [f"{k:>2}  {' | '.join(v)}" for k, v in sorted(by_layer.items())]
    lines += ["```", "", "| entry | layer | role |", "|---|---|---|"]
    for e in entries:
        shown = f"`{e}/`" if (PACKAGE / e).is_dir() else f"`{e}.py`"
        lines.append(f"| {shown} | {layer(f'mmstab.{e}')} | {first_line(e)} |")
    return "\n".join(lines)


def test_architecture_doc_is_drawn_from_the_code():
    """docs/architecture.md's diagram and table are the code's (regenerate: the message)."""
    doc = (ROOT / "docs" / "architecture.md").read_text()
    begin, end = "<!-- drawn from the code: begin -->\n", "\n<!-- drawn from the code: end -->"
    assert begin in doc and end in doc
    shown = doc[doc.index(begin) + len(begin) : doc.index(end)]
    assert shown == architecture_block(), (
        "docs/architecture.md should read:\n" + architecture_block()
    )


def test_the_top_level_is_the_pipeline():
    """Few entries at the top, each a stage or service with a one-line role."""
    entries = top_level_entries()
    assert len(entries) <= 15, entries
    assert all(first_line(e) for e in entries)


def test_every_module_has_a_layer():
    for m in MODULES:
        named = [p for p in LAYERS if p != "mmstab" or m == "mmstab"]
        assert any(m == p or m.startswith(p + ".") for p in named), m


def test_dependencies_point_down():
    upward = []
    for m in MODULES:
        for dep in imports_of(m):
            if layer(dep) > layer(m) and (m, dep) not in ALLOWED_UP:
                upward.append(f"{m} (layer {layer(m)}) imports {dep} (layer {layer(dep)})")
    assert upward == []


def import_cycles() -> list[list[str]]:
    """The strongly connected components (more than one module) of the import graph.

    Every import counts, module level and function level: an import moved into a function
    hides a circle from the interpreter, not from the reader.
    """
    graph = {m: sorted(imports_of(m) & set(MODULES)) for m in MODULES}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:  # Tarjan; the graph is small (recursion depth < 200)
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for m in MODULES:
        if m not in index:
            visit(m)
    return found


#: Circles still to break, each with its reason (none may be added).
KNOWN_CYCLES: list[list[str]] = []  # none: the task model imports no task


def test_nothing_in_mmstab_imports_the_experiments():
    """The repository's ``experiments/`` is not installed: no mmstab module imports it."""
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            offenders += [
                f"{path.relative_to(ROOT)}:{node.lineno} {n}"
                for n in names
                if n.split(".")[0] == "experiments"
            ]
    assert offenders == []
    assert (ROOT / "experiments" / "__main__.py").is_file()  # the check looks at the right name


def test_no_import_cycles():
    assert [c for c in import_cycles() if c not in KNOWN_CYCLES] == []


def test_the_check_sees_an_upward_import():
    """The checker itself: a stability module importing the controller is flagged."""
    assert layer("mmstab.stability.static") < layer("mmstab.control.controller")
    assert "mmstab.terrain.base" in imports_of("mmstab.terrain.ramp")
    assert "mmstab.runs.rollout" in imports_of(
        "mmstab.cli.commands"
    )  # ``from mmstab.runs import rollout``


#: Run in a fresh interpreter: import each module with no mmstab module loaded before it
#: (third-party libraries stay loaded between modules, which keeps this fast).
_IMPORT_EACH = """
import importlib, json, sys, traceback
failed = {}
for name in sys.argv[1:]:
    for loaded in [m for m in sys.modules if m == "mmstab" or m.startswith("mmstab.")]:
        del sys.modules[loaded]
    try:
        importlib.import_module(name)
    except BaseException:
        failed[name] = traceback.format_exc(limit=3)
print(json.dumps(failed))
"""


@pytest.mark.slow
def test_each_module_imports_alone():
    # (``mmstab.__main__`` runs the CLI when imported: it is ``python -m mmstab``)
    modules = [m for m in MODULES if m != "mmstab.__main__"]
    proc = subprocess.run(
        [sys.executable, "-c", _IMPORT_EACH, *modules], capture_output=True, text=True, cwd=ROOT
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(proc.stdout.splitlines()[-1]) == {}


def test_no_stage_knows_the_ramp():
    """Above mmstab.terrain, the ground is a Terrain: no Ramp, no slope angle.

    The atlas, whose axes *are* ramp slopes (an envelope over planar slopes x headings),
    is a study outside the package (``experiments/atlas``): it builds its ramps and hands
    them to the stages as Terrains.
    """
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        if path.is_relative_to(PACKAGE / "terrain"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Name) and node.id == "Ramp":
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} Ramp")
            if isinstance(node, ast.Attribute) and node.attr in ("slope", "G_R_S", "G_T_S"):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} .{node.attr}")
    assert offenders == []


def test_public_api_resolves_lazily():
    """``import mmstab`` loads no stage; each public name then comes from its stage."""
    code = (
        "import sys, mmstab\n"
        "light = not any(m.startswith(('casadi', 'mmstab.')) for m in sys.modules)\n"
        "assert sorted(mmstab.__all__) == sorted(mmstab._EXPORTS)\n"
        "names = {n: getattr(mmstab, n).__module__ for n in mmstab.__all__}\n"
        "import json; print(json.dumps([light, names]))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    light, names = json.loads(proc.stdout)
    assert light
    assert {"load_problem", "plan", "track", "stance", "Terrain", "Robot"} <= set(names)
    assert all(module.startswith("mmstab.") for module in names.values())
