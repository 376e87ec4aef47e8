"""The ``box`` QP plugin: a dedicated solver for the step's 6-variable box-constrained QP.

The step's QP has no linear constraints, only bounds on q̇ (:mod:`mmstab.controller.qp`), and a
positive definite 6 × 6 Hessian, so a primal active-set method on the bounds with a Cholesky
factorisation of the free block is exact (finite, ends at the unique optimum) and small: on
most steps no limit is active and one 6 × 6 Cholesky is the whole solve. The solver is C
(``boxqp.c``, CasADi's calling convention, no heap, no static state). The interpreted
controller calls it as ``casadi.external`` of a shared library compiled from that file on first
use (cached, see :func:`boxqp_library`); the code generator appends the same file to the
generated C (:func:`mmstab.codegen.postprocess`), so the interpreted and generated steps run the
same solver code.

Signature: ``mmstab_boxqp(h (6x6), g (6), lbx (6), ubx (6)) -> (x (6), flag)``, flag 0 optimal,
1 H not positive definite (x = NaN), 2 iteration limit; the step's certificate judges x either
way (:mod:`mmstab.controller`, "Failure handling").
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
from functools import lru_cache
from pathlib import Path

import casadi as ca

from mmstab.config import MmstabError

BOXQP_NAME = "mmstab_boxqp"  #: the solver's C symbol (and the CasADi Function's name)
BOXQP_SOURCE = Path(__file__).with_name("boxqp.c")  #: its C source
#: Flags of the interpreted solver's library (the generated C uses the code generator's).
BOXQP_CFLAGS = ("-O3", "-std=c99", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared")


def cache_dir() -> Path:
    """Where compiled solver libraries are kept: ``$MMSTAB_CACHE``, else the user cache folder."""
    if os.environ.get("MMSTAB_CACHE"):
        return Path(os.environ["MMSTAB_CACHE"]).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "mmstab"


def boxqp_source() -> str:
    """The solver's C source text."""
    return BOXQP_SOURCE.read_text()


@lru_cache(maxsize=1)
def boxqp_library() -> Path:
    """The solver compiled as a shared library (built once per source and compiler, cached).

    The file name carries a SHA-256 of the source and the compile command, so an edited
    source is never confused with an old build; the library is written atomically.

    Raises:
        MmstabError: no C compiler, or the source does not compile.
    """
    cc = os.environ.get("CC", "cc")
    cmd = [cc, *BOXQP_CFLAGS]
    key = hashlib.sha256((boxqp_source() + "\0" + " ".join(cmd)).encode()).hexdigest()[:16]
    out = cache_dir() / f"lib{BOXQP_NAME}_{key}.so"
    if out.is_file():
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.")
    os.close(fd)
    try:
        try:
            proc = subprocess.run(
                [*cmd, str(BOXQP_SOURCE), "-o", tmp, "-lm"], capture_output=True, text=True
            )
        except FileNotFoundError:
            raise MmstabError(
                f"the box QP plugin needs a C compiler: no {cc!r} (set CC or install cc)"
            ) from None
        if proc.returncode != 0:
            raise MmstabError(f"compiling {BOXQP_SOURCE.name} failed:\n{proc.stderr}")
        if proc.stderr:
            print(proc.stderr, file=sys.stderr)
        os.replace(tmp, out)
    finally:
        Path(tmp).unlink(missing_ok=True)
    return out


def build_boxqp() -> ca.Function:
    """The solver as a CasADi Function (``casadi.external`` of :func:`boxqp_library`)."""
    return ca.external(BOXQP_NAME, str(boxqp_library()))
