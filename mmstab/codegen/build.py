"""Generating and compiling the controller's C, with a cache; loading it back."""

from __future__ import annotations

import ctypes
import dataclasses
import hashlib
import json
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, Union

import casadi as ca

from mmstab.codegen.compiler import compile_c, compile_command
from mmstab.codegen.functions import ROLLOUT_CHUNK, STEP_NAME, export_functions
from mmstab.codegen.postprocess import postprocess
from mmstab.codegen.settings import CODEGEN_PLUGINS, CodegenSettings, check_plugin
from mmstab.control.controller import Controller, ControllerSettings, build_controller
from mmstab.control.controller.boxqp import boxqp_source
from mmstab.control.controller.qp import slot_notes
from mmstab.control.layout import layout_header
from mmstab.control.limits import Limit
from mmstab.control.tasks import Task
from mmstab.core.files import _atomic, write_json
from mmstab.model.robot import Robot

if TYPE_CHECKING:
    from mmstab.core.problem import Problem

LAYOUT_HEADER = "controller_layout.h"  #: sizes and packed layouts of the arguments, for C
#: Bump when the generated content or post-processing changes (7: the header's slot notes).
FORMAT_VERSION = 7


class GeneratedController(NamedTuple):
    """A generated and compiled controller.

    Attributes:
        directory: the output folder.
        source: the C file ``controller_step.c``.
        header: its header ``controller_step.h``.
        layout: ``controller_layout.h``: argument sizes and layouts (:func:`layout_header`).
        library: the shared library (its name carries the key).
        plugin: the QP plugin.
        hash: the cache key (SHA-256, hex) the outputs were built for.
        functions: the exported Functions' names (step, task, plant, rollout chunk).
        rebuilt: False when the outputs were already up to date.
        compiler_stderr: what the compiler printed (empty: no warning).
        native: compiled with ``-march=native`` (the embedded programs are too).
    """

    directory: Path
    source: Path
    header: Path
    layout: Path
    library: Path
    plugin: str
    hash: str
    functions: tuple[str, ...]
    rebuilt: bool
    compiler_stderr: str
    native: bool = False

    def load(self, name: str = STEP_NAME) -> ca.Function:
        """One exported Function of the library as a CasADi ``Function`` (``casadi.external``)."""
        if name not in self.functions:
            raise ValueError(f"{name!r} is not exported; choose one of {self.functions}")
        return ca.external(name, str(self.library.resolve()))


def _resolve(source: Source) -> tuple[Robot, ControllerSettings, CodegenSettings]:
    if isinstance(source, tuple) and len(source) == 3:
        return source
    if isinstance(source, tuple):
        robot, settings = source
        # the settings' plugin when C can be generated for it, else the default (box)
        plugin = settings.plugin if settings.plugin in CODEGEN_PLUGINS else "box"
        return robot, settings, CodegenSettings(plugin=plugin, directory="results/codegen")
    return (
        source.robot,
        ControllerSettings.from_section(source.section("controller")),
        CodegenSettings.from_section(source.section("codegen")),
    )


#: What the generated step is built for: a problem, or its robot and settings.
Source = Union[
    "Problem",
    tuple[Robot, ControllerSettings],
    tuple[Robot, ControllerSettings, CodegenSettings],
]


def _write_text(path: Path, text: str) -> None:
    """Write a source file atomically, readable by all (mode 644)."""

    def write(tmp: Path) -> None:
        tmp.write_text(text)
        tmp.chmod(0o644)

    _atomic(path, write)


def _read_meta(path: Path) -> dict[str, Any]:
    """``build.json``, or {} (with a one-line notice) when it cannot be read: rebuild."""
    try:
        meta = json.loads(path.read_text())
        if isinstance(meta, dict):
            return meta
        why = "not a JSON object"
    except (OSError, ValueError) as exc:
        why = f"{type(exc).__name__}: {exc}".splitlines()[0][:120]
    print(f"mmstab: notice: codegen cache {path} unreadable ({why}); rebuilding", file=sys.stderr)
    return {}


def cache_key(functions: Sequence[ca.Function], plugin: str, native: bool = False) -> str:
    """SHA-256 of what the generated library depends on (module docstring, "Cache")."""
    h = hashlib.sha256()
    command = compile_command(plugin, native)
    meta = [FORMAT_VERSION, ca.CasadiMeta.version(), plugin, command, ROLLOUT_CHUNK]
    h.update(json.dumps(meta).encode())
    for f in functions:
        h.update(f.serialize().encode())
    return h.hexdigest()


def _layout(ctrl: Controller) -> str:
    """``controller_layout.h``, with a comment line per task (its slots) and limit (its rows)."""
    notes = slot_notes(ctrl.tasks, ctrl.limits, ctrl.model)
    return layout_header(ctrl.settings.kkt_tol, ctrl.layout.arm, notes)


def generate(
    source: Source,
    out_dir: str | os.PathLike[str] | None = None,
    plugin: str | None = None,
    *,
    force: bool = False,
    native: bool = False,
    tasks: Sequence[Task] | None = None,
    limits: Sequence[Limit] | None = None,
) -> GeneratedController:
    """Generate the controller step's C and compile it, unless already up to date.

    Args:
        source: a problem, (robot, controller settings) or (robot, controller settings,
            codegen settings).
        out_dir: output folder (default ``codegen.directory/plugin``, ``results/codegen/plugin``
            for a (robot, settings) source).
        plugin: QP plugin (default the problem's ``codegen.plugin``; for a tuple the
            settings' plugin if C can be generated for it, else box).
        force: regenerate and recompile even if up to date.
        native: compile with ``-march=native`` (opt-in; the library then runs on this CPU
            family only; part of the cache key).
        tasks: the controller's tasks (default the registry's); part of the cache key.
        limits: its limits (default the registry's); part of the cache key.

    Returns:
        Paths of the C file, header and library, and the cache key.

    Raises:
        MmstabError: qpOASES or an unknown plugin (before CasADi is called), no compiler,
            or a compile error.
    """
    robot, settings, cg = _resolve(source)
    plugin = cg.plugin if plugin is None else plugin
    check_plugin(plugin)
    out = Path(out_dir) if out_dir is not None else Path(cg.directory) / plugin
    ctrl = build_controller(robot, dataclasses.replace(settings, plugin=plugin), tasks, limits)
    functions = export_functions(ctrl)
    names = tuple(f.name() for f in functions)
    key = cache_key(functions, plugin, native)
    c_file, h_file, l_file = out / f"{STEP_NAME}.c", out / f"{STEP_NAME}.h", out / LAYOUT_HEADER
    library = out / f"lib{STEP_NAME}_{key[:16]}.so"
    meta_path = out / "build.json"
    files = (c_file, h_file, l_file, library)
    if not force and meta_path.is_file() and all(p.is_file() for p in files):
        meta = _read_meta(meta_path)
        if meta.get("key") == key and isinstance(meta.get("compiler_stderr"), str):
            return GeneratedController(
                *(out, *files), plugin, key, names, False, meta["compiler_stderr"], native
            )
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        gen = ca.CodeGenerator(f"{STEP_NAME}.c", {"with_header": True, "prefix": "mmstab"})
        for f in functions:
            gen.add(f)
        gen.generate(f"{tmp}/")
        solver = boxqp_source(ctrl.layout.joints) if plugin == "box" else None
        c_text = postprocess(Path(tmp, f"{STEP_NAME}.c").read_text(), ctrl.conic.name(), solver)
        h_text = Path(tmp, f"{STEP_NAME}.h").read_text()
    for path, text in ((c_file, c_text), (h_file, h_text), (l_file, _layout(ctrl))):
        _write_text(path, text)
    stderr = compile_c([c_file], library, plugin, shared=True, native=native)
    for stale in out.glob(f"lib{STEP_NAME}_*.so"):
        if stale != library:
            stale.unlink(missing_ok=True)
    write_json(
        meta_path,
        {
            "key": key,
            "plugin": plugin,
            "casadi": ca.CasadiMeta.version(),
            "format_version": FORMAT_VERSION,
            "compile_command": compile_command(plugin, native),
            "library": library.name,
            "functions": list(names),
            "rollout_chunk": ROLLOUT_CHUNK,
            "step_work": work_sizes(library)._asdict(),
            "compiler_stderr": stderr,
        },
    )
    return GeneratedController(*(out, *files), plugin, key, names, True, stderr, native)


class WorkSizes(NamedTuple):
    """A generated function's work: pointer slots for arguments and results, ints, reals."""

    arg: int
    res: int
    iw: int
    w: int


def work_sizes(library: str | os.PathLike[str], name: str = STEP_NAME) -> WorkSizes:
    """Call a compiled function's ``<name>_work`` (what the C example sizes its arrays by)."""
    lib = ctypes.CDLL(str(Path(library).resolve()))
    fn = getattr(lib, f"{name}_work")
    sizes = [ctypes.c_longlong() for _ in range(4)]  # casadi_int = long long int
    if fn(*(ctypes.byref(v) for v in sizes)) != 0:
        raise RuntimeError(f"{name}_work failed")
    return WorkSizes(*(int(v.value) for v in sizes))


def load_step(problem: Problem, plugin: str | None = None) -> ca.Function:
    """The compiled controller step for a problem (generated and compiled if missing/outdated).

    Args:
        problem: the problem (robot, ``controller:`` and ``codegen:`` sections).
        plugin: QP plugin (default ``codegen.plugin``).

    Returns:
        ``casadi.external`` Function with :attr:`Controller.step`'s signature: (state (9),
        reference (23), params (42)) -> (qdot (6) [rad/s], status, objective).
    """
    return generate(problem, plugin=plugin).load(STEP_NAME)
