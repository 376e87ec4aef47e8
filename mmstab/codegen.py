"""The controller step as generated C (DESIGN.md §6, issue 6): generate, compile, load.

:func:`generate` writes ``controller_step.c``/``.h`` with ``casadi.CodeGenerator`` and compiles
them into a shared library with the system C compiler (``cc -O3 -std=c99 -Wall -Wextra -Werror
-fPIC -shared``); :func:`load_step` hands the simulation the compiled step as a CasADi
``Function`` (``casadi.external``) with :attr:`Controller.step`'s signature::

    controller_step(state[9], reference[23] = [ξ_des, ξ̇_ref, q_ref, q̇_ref, ground], params[42])
        -> (qdot[6], status, objective)

Beside it, ``controller_layout.h`` (:func:`layout_header`) gives C the sizes and the packed
layouts of the arguments (``MMSTAB_N_*``, ``MMSTAB_REF_*``, ``MMSTAB_PARAM_*``), written from
:class:`~mmstab.tasks.StepReference` and :class:`~mmstab.tasks.ControllerParams`, so the
embedded example never repeats them by hand.

The same C file also exports ``controller_task`` (state -> ξ, for the embedded example's error
report) and ``controller_rollout`` (:data:`ROLLOUT_CHUNK` closed-loop steps, controller step +
exact-arc integration, rolled with ``mapaccum``; :mod:`mmstab.rollout` drives it).

**Plugins.** qrqp (default) generates self-contained C: no allocator is referenced at all.
daqp and osqp generate C that includes the headers and links the libraries shipped inside the
casadi package (``casadi.GlobalOptions.getCasadiIncludePath()`` / ``getCasadiPath()``, found at
run time through an rpath). qpOASES cannot be code-generated (CasADi emits ``#error``):
asking for it raises :class:`~mmstab.config.MmstabError` before CasADi is called.

**Post-processing** (:func:`postprocess`, two documented edits, each checked to apply once):

1. CasADi's runtime templates keep the full calling convention ``(arg, res, iw, w, mem)`` on
   every function and leave some parameters unused, which ``-Wextra`` reports
   (``-Wunused-parameter``). A ``#pragma GCC diagnostic ignored "-Wunused-parameter"`` at the
   top of the generated file silences exactly that diagnostic for that file; every other
   warning stays an error.
2. In generated code a QP plugin's own failure flag aborts the whole step (``return 1``)
   before the in-graph certificate runs, so ``casadi.external`` raises "Evaluation failed"
   and the outputs are left unwritten, whereas the interpreted step (``error_on_fail =
   False``) goes on and lets the certificate judge q̇ (:mod:`mmstab.controller`, "Failure
   handling"). The call of the QP is patched to ignore that flag, so the status is the same
   interpreted and generated: an answer that is not finite, feasible and optimal is still
   refused (``SOLVER_FAILED``, q̇ = 0), whatever the plugin said.

**Cache.** Outputs are rebuilt only when the key changes: a SHA-256 of the serialized CasADi
Functions (which carry the robot's numbers and every setting baked into the C: base offset,
certificate tolerance, plugin and its options), the casadi version, the compiler command and
:data:`FORMAT_VERSION`. Gains, weights, dt and joint limits are run-time inputs (``params``),
so changing them needs no rebuild. The library's file name carries the key, so a rebuilt
library is never confused with one the process already loaded.
"""

from __future__ import annotations

import ctypes
import dataclasses
import hashlib
import json
import os
import re
import subprocess
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import casadi as ca

from mmstab.config import ConfigError, MmstabError, _atomic, write_json
from mmstab.controller import (
    ARM_JOINTS,
    CODEGEN_PLUGINS,
    JOINT_COUNT,
    PARAMS_SIZE,
    REFERENCE_SIZE,
    STATE_SIZE,
    TASK_SIZE,
    TRACK_DATA_SIZE,
    Controller,
    ControllerParams,
    ControllerSettings,
    StepReference,
    build_controller,
)
from mmstab.robot import Robot

if TYPE_CHECKING:
    from mmstab.problem import Problem

STEP_NAME = "controller_step"  #: the exported step (and the .c/.h file stem)
TASK_NAME = "controller_task"  #: state -> ξ, exported alongside
ROLLOUT_NAME = "controller_rollout"  #: ROLLOUT_CHUNK closed-loop steps, exported alongside
ROLLOUT_CHUNK = 1000  #: closed-loop steps per ``controller_rollout`` call
LAYOUT_HEADER = "controller_layout.h"  #: sizes and packed layouts of the arguments, for C
FORMAT_VERSION = 2  #: bump when the generated content or post-processing changes
#: Compiler flags for the generated C (warnings are errors); ``-fPIC -shared`` for the library.
CFLAGS = ("-O3", "-std=c99", "-Wall", "-Wextra", "-Werror")
QPOASES_MESSAGE = "CasADi cannot generate C for qpOASES; use qrqp, daqp or osqp"
_UNUSED_PRAGMA = """\
/* mmstab post-processing (mmstab/codegen.py, postprocess()):
 * 1. CasADi's runtime templates keep the full calling convention (arg, res, iw, w, mem) on
 *    every function and leave some of those parameters unused: silence exactly
 *    -Wunused-parameter for this file; every other warning stays an error under -Werror.
 * 2. The QP plugin's own failure flag does not abort the step (see the call of the QP below):
 *    as in the interpreted step (error_on_fail = False), the in-graph certificate judges qdot. */
#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif
"""
_IGNORED_FLAG = "/* mmstab: the QP's own failure flag is ignored; the certificate judges qdot */"


# ----------------------------------------------------------------------------------- settings
@dataclasses.dataclass(frozen=True)
class CodegenSettings:
    """The ``codegen:`` section of a problem file.

    Attributes:
        plugin: QP plugin to generate C for, one of :data:`CODEGEN_PLUGINS`.
        directory: output root; a plugin's files go to ``directory/plugin`` [path].
    """

    plugin: str
    directory: str

    @classmethod
    def from_section(cls, section: Mapping[str, Any]) -> CodegenSettings:
        """Build from a validated ``codegen:`` section."""
        return cls(plugin=str(section["plugin"]), directory=str(section["directory"]))


def check_plugin(plugin: str) -> None:
    """Raise :class:`MmstabError` unless CasADi can generate C for ``plugin``."""
    if plugin == "qpoases":
        raise MmstabError(QPOASES_MESSAGE)
    if plugin not in CODEGEN_PLUGINS:
        raise MmstabError(f"unknown QP plugin {plugin!r}; choose one of {CODEGEN_PLUGINS}")


def check_settings(path: Path, section: Mapping[str, Any]) -> None:
    """Semantic check of the ``codegen:`` section (a plugin CasADi can generate C for).

    Raises:
        ConfigError: naming ``codegen.plugin``.
    """
    try:
        check_plugin(str(section["plugin"]))
    except MmstabError as exc:
        raise ConfigError(path, "codegen.plugin", str(exc)) from None


# --------------------------------------------------------------------- functions to generate
def closed_loop(ctrl: Controller) -> ca.Function:
    """One closed-loop step: controller step, then the exact-arc motion over ``params.dt``.

    Returns:
        ``Function`` (state (9), reference (23), params (42)) -> (state_next (9), qdot (6)
        [rad/s], status).
    """
    state, ref = ca.MX.sym("state", STATE_SIZE), ca.MX.sym("reference", REFERENCE_SIZE)
    p = ca.MX.sym("params", PARAMS_SIZE)
    qdot, status, _ = ctrl.step(state, ref, p)
    nxt = ctrl.model.f_integrate(state, qdot, ControllerParams.unpack(p).dt)
    return ca.Function(
        "closed_loop",
        [state, ref, p],
        [nxt, qdot, status],
        ["state", "reference", "params"],
        ["state_next", "qdot", "status"],
    )


def rollout_chunk(ctrl: Controller, steps: int = ROLLOUT_CHUNK) -> ca.Function:
    """``steps`` closed-loop steps in one Function (``mapaccum`` of :func:`closed_loop`).

    Returns:
        ``Function`` ``controller_rollout`` (state0 (9), references (23 x steps), params (42))
        -> (states after each step (9 x steps), qdot (6 x steps), status (1 x steps)).
    """
    acc = closed_loop(ctrl).mapaccum("closed_loop_acc", steps)
    x0 = ca.MX.sym("state0", STATE_SIZE)
    refs = ca.MX.sym("references", REFERENCE_SIZE, steps)
    p = ca.MX.sym("params", PARAMS_SIZE)
    states, qdot, status = acc(x0, refs, ca.repmat(p, 1, steps))
    return ca.Function(
        ROLLOUT_NAME,
        [x0, refs, p],
        [states, qdot, status],
        ["state0", "references", "params"],
        ["states", "qdot", "status"],
    )


def export_functions(ctrl: Controller) -> list[ca.Function]:
    """The Functions written to the C file: step, task (state -> ξ), rollout chunk."""
    step = ctrl.step
    if step.name() != STEP_NAME:  # the exported symbol is the Function's name
        raise RuntimeError(f"the controller's step is named {step.name()!r}, not {STEP_NAME!r}")
    m = ctrl.model
    task = ca.Function(TASK_NAME, [m.state, m.ground], [m.xi], ["state", "ground"], ["xi"])
    return [step, task, rollout_chunk(ctrl)]


def layout_header() -> str:
    """``controller_layout.h``: the step's argument sizes and packed layouts as C macros.

    ``MMSTAB_N_*`` sizes (state, joints, task, arm joints, reference, params, run-file track
    data), then the offset of each field of the reference (``MMSTAB_REF_*``) and of the
    parameters (``MMSTAB_PARAM_*``), from :class:`StepReference` and :class:`ControllerParams`.
    """
    sizes = {
        "STATE": STATE_SIZE,
        "JOINTS": JOINT_COUNT,
        "TASK": TASK_SIZE,
        "ARM": ARM_JOINTS,
        "REFERENCE": REFERENCE_SIZE,
        "PARAMS": PARAMS_SIZE,
        "TRACK": TRACK_DATA_SIZE,
    }
    lines = [
        "/* Sizes and layouts of controller_step's arguments (mmstab/codegen.py, layout_header;",
        " * from mmstab.tasks.StepReference and ControllerParams). Generated: do not edit. */",
        "#ifndef MMSTAB_CONTROLLER_LAYOUT_H",
        "#define MMSTAB_CONTROLLER_LAYOUT_H",
        "",
        *(f"#define MMSTAB_N_{name} {n}" for name, n in sizes.items()),
        "",
        "/* reference (StepReference): offset of each field */",
        *(f"#define MMSTAB_REF_{k.upper()} {v.start}" for k, v in StepReference.offsets().items()),
        "",
        "/* params (ControllerParams): offset of each field */",
        *(
            f"#define MMSTAB_PARAM_{k.upper()} {v.start}"
            for k, v in ControllerParams.offsets().items()
        ),
        "",
        "#endif /* MMSTAB_CONTROLLER_LAYOUT_H */",
        "",
    ]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- post-process
def postprocess(source: str, qp_name: str) -> str:
    """The two documented edits of the generated C (module docstring, "Post-processing").

    Args:
        source: the generated C text.
        qp_name: name of the QP Function (``Controller.conic.name()``) whose call is patched.

    Raises:
        RuntimeError: the generated code does not have the expected shape (CasADi changed):
            the QP's call must be found exactly once.
    """
    end = source.index("*/\n") + 3  # after CasADi's leading comment block
    out = source[:end] + _UNUSED_PRAGMA + source[end:]
    calls = [m.start() for m in re.finditer(rf"/\* #\d+: .*= {re.escape(qp_name)}\(", out)]
    if len(calls) != 1:
        raise RuntimeError(f"expected one call of {qp_name} in the generated C, got {len(calls)}")
    start = calls[0]
    stop = out.index("/* #", start + 4)
    block = out[start:stop]
    direct = re.compile(r"if \((casadi_f\d+\(arg1, res1, iw, w, \w+\))\) return 1;")
    block, n_direct = direct.subn(rf"(void) \1; {_IGNORED_FLAG}", block)
    block, n_flag = re.subn(r"if \(flag\) return 1;", f"(void) flag; {_IGNORED_FLAG}", block)
    if n_direct + n_flag != 1:
        raise RuntimeError(f"expected one failure check after the call of {qp_name}")
    return out[:start] + block + out[stop:]


# --------------------------------------------------------------------------------- compiling
def casadi_paths() -> tuple[str, str]:
    """The casadi package's include folder and library folder (headers/libs of daqp, osqp)."""
    return ca.GlobalOptions.getCasadiIncludePath(), ca.GlobalOptions.getCasadiPath()


def plugin_flags(plugin: str) -> tuple[list[str], list[str]]:
    """Compile flags (include path) and link flags (libraries, rpath) a plugin's C needs."""
    if plugin == "qrqp":
        return [], ["-lm"]
    include, libdir = casadi_paths()
    return [f"-I{include}"], [f"-L{libdir}", f"-Wl,-rpath,{libdir}", f"-l{plugin}", "-lm"]


def compiler() -> str:
    """The C compiler: ``$CC`` or ``cc``."""
    return os.environ.get("CC", "cc")


def compile_c(
    sources: Sequence[str | os.PathLike[str]],
    output: str | os.PathLike[str],
    plugin: str,
    *,
    shared: bool,
    include: Sequence[str | os.PathLike[str]] = (),
) -> str:
    """Compile C sources with :data:`CFLAGS` (warnings are errors); returns the compiler's stderr.

    Args:
        sources: C files.
        output: the library or program to write (atomically: compiled next to it, renamed).
        plugin: the QP plugin (adds its include path and libraries).
        shared: build a shared library (``-fPIC -shared``) rather than a program.
        include: extra include folders.

    Raises:
        MmstabError: no compiler, or the compilation failed (its messages included).
    """
    cflags, ldflags = plugin_flags(plugin)
    out = Path(output)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.")
    os.close(fd)
    cmd = [compiler(), *CFLAGS, *(["-fPIC", "-shared"] if shared else [])]
    cmd += [*cflags, *(f"-I{d}" for d in include), *map(str, sources), "-o", tmp, *ldflags]
    try:
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        except FileNotFoundError:
            raise MmstabError(f"no C compiler {cmd[0]!r} (set CC or install cc)") from None
        if proc.returncode != 0:
            raise MmstabError(f"compiling {out.name} failed:\n{' '.join(cmd)}\n{proc.stderr}")
        os.replace(tmp, out)
    finally:
        Path(tmp).unlink(missing_ok=True)
    return proc.stderr


def compile_command(plugin: str) -> list[str]:
    """The compile command's fixed part for a plugin's library (part of the cache key)."""
    cflags, ldflags = plugin_flags(plugin)
    return [compiler(), *CFLAGS, "-fPIC", "-shared", *cflags, *ldflags]


# -------------------------------------------------------------------------------- generating
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
        functions: the exported Functions' names (step, task, rollout chunk).
        rebuilt: False when the outputs were already up to date.
        compiler_stderr: what the compiler printed (empty: no warning).
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

    def load(self, name: str = STEP_NAME) -> ca.Function:
        """One exported Function of the library as a CasADi ``Function`` (``casadi.external``)."""
        if name not in self.functions:
            raise ValueError(f"{name!r} is not exported; choose one of {self.functions}")
        return ca.external(name, str(self.library.resolve()))


def _resolve(
    source: Problem | tuple[Robot, ControllerSettings],
) -> tuple[Robot, ControllerSettings, CodegenSettings]:
    if isinstance(source, tuple):
        robot, settings = source
        return robot, settings, CodegenSettings(plugin="qrqp", directory="results/codegen")
    return (
        source.robot,
        ControllerSettings.from_section(source.section("controller")),
        CodegenSettings.from_section(source.section("codegen")),
    )


def _write_text(path: Path, text: str) -> None:
    """Write a source file atomically, readable by all (mode 644)."""

    def write(tmp: Path) -> None:
        tmp.write_text(text)
        tmp.chmod(0o644)

    _atomic(path, write)


def cache_key(functions: Sequence[ca.Function], plugin: str) -> str:
    """SHA-256 of what the generated library depends on (module docstring, "Cache")."""
    h = hashlib.sha256()
    meta = [FORMAT_VERSION, ca.CasadiMeta.version(), plugin, compile_command(plugin), ROLLOUT_CHUNK]
    h.update(json.dumps(meta).encode())
    for f in functions:
        h.update(f.serialize().encode())
    return h.hexdigest()


def generate(
    source: Problem | tuple[Robot, ControllerSettings],
    out_dir: str | os.PathLike[str] | None = None,
    plugin: str | None = None,
    *,
    force: bool = False,
) -> GeneratedController:
    """Generate the controller step's C and compile it, unless already up to date.

    Args:
        source: a problem, or (robot, controller settings).
        out_dir: output folder (default ``codegen.directory/plugin``, ``results/codegen/plugin``
            for a (robot, settings) source).
        plugin: QP plugin (default the problem's ``codegen.plugin``, qrqp for a tuple).
        force: regenerate and recompile even if up to date.

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
    ctrl = build_controller(robot, dataclasses.replace(settings, plugin=plugin))
    functions = export_functions(ctrl)
    names = tuple(f.name() for f in functions)
    key = cache_key(functions, plugin)
    c_file, h_file, l_file = out / f"{STEP_NAME}.c", out / f"{STEP_NAME}.h", out / LAYOUT_HEADER
    library = out / f"lib{STEP_NAME}_{key[:16]}.so"
    meta_path = out / "build.json"
    files = (c_file, h_file, l_file, library)
    if not force and meta_path.is_file() and all(p.is_file() for p in files):
        meta = json.loads(meta_path.read_text())
        if meta.get("key") == key:
            return GeneratedController(
                *(out, *files), plugin, key, names, False, meta["compiler_stderr"]
            )
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        gen = ca.CodeGenerator(f"{STEP_NAME}.c", {"with_header": True, "prefix": "mmstab"})
        for f in functions:
            gen.add(f)
        gen.generate(f"{tmp}/")
        c_text = postprocess(Path(tmp, f"{STEP_NAME}.c").read_text(), ctrl.conic.name())
        h_text = Path(tmp, f"{STEP_NAME}.h").read_text()
    for path, text in ((c_file, c_text), (h_file, h_text), (l_file, layout_header())):
        _write_text(path, text)
    stderr = compile_c([c_file], library, plugin, shared=True)
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
            "compile_command": compile_command(plugin),
            "library": library.name,
            "functions": list(names),
            "rollout_chunk": ROLLOUT_CHUNK,
            "step_work": work_sizes(library)._asdict(),
            "compiler_stderr": stderr,
        },
    )
    return GeneratedController(*(out, *files), plugin, key, names, True, stderr)


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


# ------------------------------------------------------------------------- embedded example
EMBEDDED_DIR = Path(__file__).resolve().parents[1] / "embedded"  #: C sources of the example
EXAMPLE_PROGRAM = "mmstab_loop"  #: the closed-loop example (embedded/main.c)
BENCH_PROGRAM = "mmstab_bench"  #: the step timing program (embedded/bench.c)


class ExamplePrograms(NamedTuple):
    """The compiled embedded example.

    Attributes:
        loop: the closed-loop example (``embedded/main.c``).
        bench: the step timing program (``embedded/bench.c``).
        compiler_stderr: what the compiler printed for both (empty: no warning).
    """

    loop: Path
    bench: Path
    compiler_stderr: str


def build_programs(
    generated: GeneratedController,
    out_dir: str | os.PathLike[str] | None = None,
    sources: str | os.PathLike[str] = EMBEDDED_DIR,
) -> ExamplePrograms:
    """Compile the embedded example and the timing program against the generated C.

    Each program is ``embedded/<file>.c`` + ``controller_step.c`` (compiled in, no shared
    library), with the same warning flags as the library.

    Args:
        generated: the generated controller.
        out_dir: where to write the programs (default the generated controller's folder).
        sources: the folder holding ``main.c``, ``bench.c``, ``motion.h`` and ``run_file.h``.

    Raises:
        MmstabError: the sources are missing (not a source checkout) or do not compile.
    """
    src = Path(sources)
    if not (src / "main.c").is_file():
        raise MmstabError(f"no embedded example sources in {src} (run from a source checkout)")
    out = Path(out_dir) if out_dir is not None else generated.directory
    paths, stderr = [], ""
    for c_name, prog in (("main.c", EXAMPLE_PROGRAM), ("bench.c", BENCH_PROGRAM)):
        paths.append(out / prog)
        stderr += compile_c(
            [src / c_name, generated.source],
            out / prog,
            generated.plugin,
            shared=False,
            include=[generated.directory, src],
        )
    return ExamplePrograms(paths[0], paths[1], stderr)
