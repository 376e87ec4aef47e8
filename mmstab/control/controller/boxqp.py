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

The source is written for 6 variables (2 sprockets + a 4-DoF arm); for another joint count n
:func:`boxqp_source` sets ``MMSTAB_BOXQP_N`` and the External interface's sparsities to n.

Signature: ``mmstab_boxqp(h (6x6), g (6), lbx (6), ubx (6)) -> (x (6), flag)``, flag 0 optimal,
1 H not positive definite (x = NaN), 2 iteration limit; the step's certificate judges x either
way (:mod:`mmstab.control.controller`, "Failure handling").
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import casadi as ca

from mmstab.core.clib import LIB_CFLAGS, cache_dir, compiled_library
from mmstab.core.files import write_text

BOXQP_NAME = "mmstab_boxqp"  #: the solver's C symbol (and the CasADi Function's name)
BOXQP_SOURCE = Path(__file__).with_name("boxqp.c")  #: its C source
#: Flags of the interpreted solver's library (the generated C uses the code generator's).
BOXQP_CFLAGS = LIB_CFLAGS


#: The variables the C source is written for.
BOXQP_SOURCE_N = 6


def _sparsity(name: str, rows: int, cols: int) -> str:
    """A dense ``rows`` x ``cols`` CasADi sparsity as a C array ``name``."""
    pattern = [rows, cols, *(rows * j for j in range(cols + 1)), *(list(range(rows)) * cols)]
    return f"static const casadi_int {name}[] = {{{', '.join(map(str, pattern))}}};"


def boxqp_source(n: int = BOXQP_SOURCE_N) -> str:
    """The solver's C source text for ``n`` variables (the file itself for n = 6).

    Raises:
        ValueError: n < 1.
    """
    text = BOXQP_SOURCE.read_text()
    if n == BOXQP_SOURCE_N:
        return text
    if n < 1:
        raise ValueError(f"the box QP needs at least one variable, got {n}")
    text = text.replace(
        f"#define MMSTAB_BOXQP_N {BOXQP_SOURCE_N}\n", f"#define MMSTAB_BOXQP_N {int(n)}\n"
    )
    for name, cols in (("mmstab_boxqp_sp_h", n), ("mmstab_boxqp_sp_v", 1)):
        text = re.sub(
            rf"static const casadi_int {name}\[\] = \{{[^}}]*\}};", _sparsity(name, n, cols), text
        )
    return text


@lru_cache(maxsize=8)
def boxqp_library(n: int = BOXQP_SOURCE_N) -> Path:
    """The solver for ``n`` variables compiled as a shared library (cached per source).

    Raises:
        MmstabError: no C compiler, or the source does not compile.
    """
    if n == BOXQP_SOURCE_N:
        return compiled_library(BOXQP_SOURCE, BOXQP_NAME, BOXQP_CFLAGS)
    source = cache_dir() / f"{BOXQP_NAME}_n{int(n)}.c"
    if not source.is_file() or source.read_text() != boxqp_source(n):
        source.parent.mkdir(parents=True, exist_ok=True)
        write_text(source, boxqp_source(n))
    return compiled_library(source, BOXQP_NAME, BOXQP_CFLAGS)


def build_boxqp(n: int = BOXQP_SOURCE_N) -> ca.Function:
    """The solver for ``n`` variables as a CasADi Function (``casadi.external``)."""
    return ca.external(BOXQP_NAME, str(boxqp_library(n)))
