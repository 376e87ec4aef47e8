"""The ``box`` QP plugin: a dedicated solver for the step's 6-variable box-constrained QP.

The step's QP has no linear constraints, only bounds on q̇ (:mod:`mmstab.control.controller.qp`),
and a
positive definite 6 × 6 Hessian, so a primal active-set method on the bounds with a Cholesky
factorisation of the free block is exact (finite, ends at the unique optimum) and small: on
most steps no limit is active and one 6 × 6 Cholesky is the whole solve. The solver is C
(``boxqp.c``, CasADi's calling convention, no heap, no static state). The interpreted
controller calls it as ``casadi.external`` of a shared library compiled from that file on first
use (cached, :mod:`mmstab.core.clib`); the code generator appends the same file to the
generated C (:func:`mmstab.codegen.postprocess`), so the interpreted and generated steps run the
same solver code.

Signature: ``mmstab_boxqp(h (6x6), g (6), lbx (6), ubx (6)) -> (x (6), flag)``, flag 0 optimal,
1 H not positive definite (x = NaN), 2 iteration limit; the step's certificate judges x either
way (:mod:`mmstab.control.controller`, "Failure handling").
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import casadi as ca

from mmstab.core.clib import LIB_CFLAGS, compiled_library

BOXQP_NAME = "mmstab_boxqp"  #: the solver's C symbol (and the CasADi Function's name)
BOXQP_SOURCE = Path(__file__).with_name("boxqp.c")  #: its C source
#: Flags of the interpreted solver's library (the generated C uses the code generator's).
BOXQP_CFLAGS = LIB_CFLAGS


def boxqp_source() -> str:
    """The solver's C source text."""
    return BOXQP_SOURCE.read_text()


@lru_cache(maxsize=1)
def boxqp_library() -> Path:
    """The solver compiled as a shared library (once per source and compiler, cached).

    Raises:
        MmstabError: no C compiler, or the source does not compile.
    """
    return compiled_library(BOXQP_SOURCE, BOXQP_NAME, BOXQP_CFLAGS)


def build_boxqp() -> ca.Function:
    """The solver as a CasADi Function (``casadi.external`` of :func:`boxqp_library`)."""
    return ca.external(BOXQP_NAME, str(boxqp_library()))
