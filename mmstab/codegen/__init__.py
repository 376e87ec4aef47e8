"""The controller step as generated C (``docs/design.md``, "Controller"): generate, compile, load.

:func:`generate` writes ``controller_step.c``/``.h`` with ``casadi.CodeGenerator`` and compiles
them into a shared library with the system C compiler (``cc -O3 -std=c99 -Wall -Wextra -Werror
-fPIC -shared``); :func:`load_step` hands the simulation the compiled step as a CasADi
``Function`` (``casadi.external``) with :attr:`Controller.step`'s signature::

    controller_step(state[9], reference[23] = [ξ_des, ξ̇_ref, q_ref, q̇_ref, ground], params[42])
        -> (qdot[6], status, objective)

Beside it, ``controller_layout.h`` (:func:`layout_header`) gives C the sizes and the packed
layouts of the arguments (``MMSTAB_N_*``, ``MMSTAB_REF_*``, ``MMSTAB_PARAM_*``), written from
:class:`~mmstab.control.layout.StepReference` and :class:`~mmstab.control.layout.ControllerParams`,
so the
embedded example never repeats them by hand.

The same C file also exports ``controller_task`` ((state, ground) -> ξ, for the embedded
example's error report), ``controller_plant`` (the simulation's plant, :mod:`mmstab.control.plant`:
the embedded example moves the robot with it, so ground-following motion is written once) and
``controller_rollout`` (:data:`ROLLOUT_CHUNK` closed-loop steps, controller step +
exact-arc integration, rolled with ``mapaccum``; :mod:`mmstab.runs.rollout` drives it).

**Plugins.** qrqp (default) generates self-contained C: no allocator is referenced at all.
daqp and osqp generate C that includes the headers and links the libraries shipped inside the
casadi package (``casadi.GlobalOptions.getCasadiIncludePath()`` / ``getCasadiPath()``, found at
run time through an rpath). qpOASES cannot be code-generated (CasADi emits ``#error``):
asking for it raises :class:`~mmstab.core.files.MmstabError` before CasADi is called.

**Post-processing** (:func:`postprocess`, two documented edits, each checked to apply once):

1. CasADi's runtime templates keep the full calling convention ``(arg, res, iw, w, mem)`` on
   every function and leave some parameters unused, which ``-Wextra`` reports
   (``-Wunused-parameter``). A ``#pragma GCC diagnostic ignored "-Wunused-parameter"`` at the
   top of the generated file silences exactly that diagnostic for that file; every other
   warning stays an error.
2. In generated code a QP plugin's own failure flag aborts the whole step (``return 1``)
   before the in-graph certificate runs, so ``casadi.external`` raises "Evaluation failed"
   and the outputs are left unwritten, whereas the interpreted step (``error_on_fail =
   False``) goes on and lets the certificate judge q̇ (:mod:`mmstab.control.controller`, "Failure
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

from mmstab.codegen.build import (
    FORMAT_VERSION,
    LAYOUT_HEADER,
    GeneratedController,
    WorkSizes,
    cache_key,
    generate,
    load_step,
    work_sizes,
)
from mmstab.codegen.compiler import (
    CFLAGS,
    NATIVE_CFLAGS,
    compile_c,
    compile_command,
    plugin_flags,
)
from mmstab.codegen.embedded import (
    BENCH_PROGRAM,
    EMBEDDED_DIR,
    EXAMPLE_PROGRAM,
    ExamplePrograms,
    build_programs,
)
from mmstab.codegen.functions import (
    JACOBIAN_NAME,
    QP_NAME,
    ROLLOUT_CHUNK,
    ROLLOUT_NAME,
    STEP_NAME,
    TASK_NAME,
    closed_loop,
    export_functions,
    rollout_chunk,
)
from mmstab.codegen.postprocess import postprocess
from mmstab.codegen.settings import (
    QPOASES_MESSAGE,
    CodegenSettings,
    check_plugin,
    check_settings,
)
from mmstab.control.controller import CODEGEN_PLUGINS
from mmstab.control.plant import PLANT_NAME

__all__ = [
    "BENCH_PROGRAM",
    "CFLAGS",
    "CODEGEN_PLUGINS",
    "EMBEDDED_DIR",
    "EXAMPLE_PROGRAM",
    "FORMAT_VERSION",
    "LAYOUT_HEADER",
    "NATIVE_CFLAGS",
    "JACOBIAN_NAME",
    "PLANT_NAME",
    "QP_NAME",
    "QPOASES_MESSAGE",
    "ROLLOUT_CHUNK",
    "ROLLOUT_NAME",
    "STEP_NAME",
    "TASK_NAME",
    "CodegenSettings",
    "ExamplePrograms",
    "GeneratedController",
    "WorkSizes",
    "build_programs",
    "cache_key",
    "check_plugin",
    "check_settings",
    "closed_loop",
    "compile_c",
    "compile_command",
    "export_functions",
    "generate",
    "load_step",
    "plugin_flags",
    "postprocess",
    "rollout_chunk",
    "work_sizes",
]
