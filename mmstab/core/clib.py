"""mmstab's own C, compiled on first use into a cached shared library.

Hand-written C, stage by stage: the controller's box QP solver (``controller/boxqp.c``),
the resting pose of the base on a heightmap and its polish (``terrain/rest/kernel.c``), the
arm's link frames and link shapes' poses (``model/frames.c``: BLAS's products, checked bit
for bit against NumPy's before use), the bounds on the arm's collision distances
(``model/collision_distance.c``), A* over the posture roadmap
(``planner/searches/roadmap/astar.c``), the turns' slide priced on a grid of CoMs
(``planner/turning.c``), the ground under the arm
(``planner/ground/kernel.c``: at a route's poses offline, on each live map online), the
skid-steer model's Newton loop (``stability/skid.c``), the loaded support's μ of many
states (``stability/support_mu.c``), the climb limit's wheel rolled over the ground ahead
(``stability/climb_rolls.c``) and the arm's height above the ground (``runs/arm_heights.c``).
Each is compiled once per source text and compile command with the system compiler and kept in
the cache folder; the file name carries a hash of both, so an edited source is never
confused with an old build, and the library is written atomically (compiled next to it,
renamed).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import MmstabError


def array_pointer(dtype: Any) -> type[ctypes.c_void_p]:
    """A ctypes argument type: a C-contiguous NumPy array of ``dtype``, passed by address.

    ``np.ctypeslib.ndpointer(dtype, flags="C_CONTIGUOUS")``'s checks (any other argument
    is refused: a ``ctypes.ArgumentError``) without its ctypes objects made at every call
    (a kernel called a hundred times a pose takes 2-3 µs less per array).
    """
    kind = np.dtype(dtype)

    class ArrayPointer(ctypes.c_void_p):
        @classmethod
        def from_param(cls, obj: Any) -> ArrayPointer:
            if not isinstance(obj, np.ndarray) or obj.dtype != kind or not obj.flags.c_contiguous:
                raise TypeError(f"a C-contiguous {kind} array expected, not {type(obj)}")
            return cls(obj.ctypes.data)

    ArrayPointer.__name__ = f"ArrayPointer_{kind}"
    return ArrayPointer


#: ctypes argument types of the kernels: C-contiguous float64, int64 and uint8 arrays, scalars
DOUBLES = array_pointer(np.float64)
LONGS = array_pointer(np.int64)
BYTES = array_pointer(np.uint8)
LONG, DOUBLE = ctypes.c_long, ctypes.c_double

#: Flags of mmstab's own C libraries (warnings are errors).
LIB_CFLAGS = ("-O3", "-std=c99", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared")


#: The environment variable that moves mmstab's cache folder (:func:`cache_dir`).
CACHE_ENV = "MMSTAB_CACHE"


def cache_dir() -> Path:
    """Mmstab's cache folder, shared by every working folder (read at every call).

    ``$MMSTAB_CACHE``, else ``$XDG_CACHE_HOME/mmstab``, else ``~/.cache/mmstab``: compiled
    libraries, the workspaces V and the posture roadmaps (each file named by a key of what
    it was built from, so robots and settings never mix).
    """
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "mmstab"


def compiled_library(source: Path, name: str, cflags: Sequence[str] = LIB_CFLAGS) -> Path:
    """``source`` compiled as the shared library ``lib{name}_{hash}.so`` in :func:`cache_dir`.

    Args:
        source: the C file.
        name: the library's name (its main symbol, by convention).
        cflags: compiler flags (``-fPIC -shared`` among them).

    Raises:
        MmstabError: no C compiler, or the source does not compile.
    """
    cc = os.environ.get("CC", "cc")
    cmd = [cc, *cflags]
    text = source.read_text()
    key = hashlib.sha256((text + "\0" + " ".join(cmd)).encode()).hexdigest()[:16]
    out = cache_dir() / f"lib{name}_{key}.so"
    if out.is_file():
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.")
    os.close(fd)
    try:
        try:
            proc = subprocess.run(
                [*cmd, str(source), "-o", tmp, "-lm"], capture_output=True, text=True
            )
        except FileNotFoundError:
            raise MmstabError(
                f"{source.name} needs a C compiler: no {cc!r} (set CC or install cc)"
            ) from None
        if proc.returncode != 0:
            raise MmstabError(f"compiling {source.name} failed:\n{proc.stderr}")
        if proc.stderr:
            print(proc.stderr, file=sys.stderr)
        os.replace(tmp, out)
    finally:
        Path(tmp).unlink(missing_ok=True)
    return out


def kernel_function(source: Path, name: str, argtypes: Sequence[Any]) -> Any:
    """The C function ``name`` (returning int) of ``source`` compiled, with its ``argtypes``.

    Raises:
        MmstabError: no C compiler, or the source does not compile.
    """
    fn = getattr(ctypes.CDLL(str(compiled_library(source, name))), name)
    fn.restype = ctypes.c_int
    fn.argtypes = list(argtypes)
    return fn


def optional_kernel(source: Path, name: str, argtypes: Sequence[Any]) -> Any:
    """:func:`kernel_function`, or None where it cannot be built (the caller's NumPy path runs)."""
    try:
        return kernel_function(source, name, argtypes)
    except (MmstabError, OSError):
        return None
