"""The embedded example (``embedded/``): compiled against the generated C."""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

from mmstab.codegen.build import GeneratedController
from mmstab.codegen.compiler import compile_c
from mmstab.core.files import MmstabError

EMBEDDED_DIR = Path(__file__).resolve().parents[2] / "embedded"  #: C sources of the example
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
        sources: the folder holding ``main.c``, ``bench.c``, ``run_file.h`` and ``plant_step.h``.

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
            native=generated.native,
        )
    return ExamplePrograms(paths[0], paths[1], stderr)
