"""The two documented edits of the generated C (:mod:`mmstab.codegen`, "Post-processing")."""

from __future__ import annotations

import re

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
