"""The documented edits of the generated C (:mod:`mmstab.codegen`, "Post-processing")."""

from __future__ import annotations

import re

_UNUSED_PRAGMA = """\
/* mmstab post-processing (mmstab/codegen.py, postprocess()):
 * 1. CasADi's runtime templates keep the full calling convention (arg, res, iw, w, mem) on
 *    every function and leave some of those parameters unused: silence exactly
 *    -Wunused-parameter for this file; every other warning stays an error under -Werror.
 * 2. The QP plugin's own failure flag does not abort the step (see the call of the QP below):
 *    as in the interpreted step (error_on_fail = False), the in-graph certificate judges qdot.
 * 3. With the box plugin, the solver's source (mmstab/control/controller/boxqp.c) is appended at
 *    the
 *    end of this file: the step calls it as CasADi calls an external function.
 * 4. casadi_fmax and casadi_fmin compare inline instead of calling libm's fmax/fmin (an
 *    out-of-line call each: about 40 per step, a third of its time); the C99 semantics are
 *    kept: a NaN argument gives the other argument. */
#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif
"""
_IGNORED_FLAG = "/* mmstab: the QP's own failure flag is ignored; the certificate judges qdot */"


def postprocess(source: str, qp_name: str, solver_source: str | None = None) -> str:
    """The documented edits of the generated C (module docstring, "Post-processing").

    Args:
        source: the generated C text.
        qp_name: name of the QP Function (``Controller.conic.name()``) whose call is patched.
        solver_source: the C of mmstab's own QP solver (the ``box`` plugin), appended to the
            file (it returns 0 and reports through its ``flag`` output; its call is patched
            like any plugin's).

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
    out = out[:start] + block + out[stop:]
    for name, op in (("fmax", ">"), ("fmin", "<")):  # edit 4
        call = f"return {name}(x, y);"
        if out.count(call) != 1:
            raise RuntimeError(f"expected one definition of casadi_{name} calling {name}")
        out = out.replace(call, f"return (y != y || x {op} y) ? x : y; /* mmstab: inline */")
    if solver_source is not None:
        out += f"\n/* mmstab post-processing 3: the box QP solver */\n{solver_source}"
    return out
