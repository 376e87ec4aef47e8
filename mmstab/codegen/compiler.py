"""Compiling the generated C with the system compiler (warnings are errors)."""

from __future__ import annotations

import os
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import casadi as ca

from mmstab.core.files import MmstabError

#: Compiler flags for the generated C (warnings are errors); ``-fPIC -shared`` for the library.
CFLAGS = ("-O3", "-std=c99", "-Wall", "-Wextra", "-Werror")
#: Opt-in flags (``native=True``): code for this machine's instruction set only (not portable).
NATIVE_CFLAGS = ("-march=native",)


def casadi_paths() -> tuple[str, str]:
    """The casadi package's include folder and library folder (headers/libs of daqp, osqp)."""
    return ca.GlobalOptions.getCasadiIncludePath(), ca.GlobalOptions.getCasadiPath()


def plugin_flags(plugin: str) -> tuple[list[str], list[str]]:
    """Compile flags (include path) and link flags (libraries, rpath) a plugin's C needs."""
    if plugin in ("qrqp", "box"):  # self-contained C
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
    native: bool = False,
) -> str:
    """Compile C sources with :data:`CFLAGS` (warnings are errors); returns the compiler's stderr.

    Args:
        sources: C files.
        output: the library or program to write (atomically: compiled next to it, renamed).
        plugin: the QP plugin (adds its include path and libraries).
        shared: build a shared library (``-fPIC -shared``) rather than a program.
        include: extra include folders.
        native: add :data:`NATIVE_CFLAGS` (opt-in: the binary runs on this CPU family only).

    Raises:
        MmstabError: no compiler, or the compilation failed (its messages included).
    """
    cflags, ldflags = plugin_flags(plugin)
    out = Path(output)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.")
    os.close(fd)
    cmd = [compiler(), *CFLAGS, *(NATIVE_CFLAGS if native else ())]
    cmd += ["-fPIC", "-shared"] if shared else []
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


def compile_command(plugin: str, native: bool = False) -> list[str]:
    """The compile command's fixed part for a plugin's library (part of the cache key)."""
    cflags, ldflags = plugin_flags(plugin)
    flags = [*CFLAGS, *(NATIVE_CFLAGS if native else ())]
    return [compiler(), *flags, "-fPIC", "-shared", *cflags, *ldflags]
