"""The C heap's freed blocks kept for reuse (``mmstab.core.heap``): a freed block's pages
come back without faulting in again.

Each case runs in a fresh process (the setting is once a process): a 16 MB block is
allocated, written, freed, then allocated and written again; the second block's minor page
faults are counted (``getrusage``). With glibc's own thresholds the first block is mapped
and unmapped and the second faults its 4,096 pages in again; with
:func:`mmstab.core.heap.keep_freed_memory` it reuses the first's.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from mmstab.core.heap import keep_freed_memory

SCRIPT = """
import ctypes, json, resource, sys
from mmstab.core.heap import keep_freed_memory
kept = keep_freed_memory() if sys.argv[1] == "keep" else False
libc = ctypes.CDLL(None)
libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, [ctypes.c_size_t]
libc.free.argtypes = [ctypes.c_void_p]
size = 16 * 2**20
def block():
    p = libc.malloc(size)
    ctypes.memset(p, 1, size)
    return p
libc.free(block())
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
p = block()
faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
libc.free(p)
print(json.dumps({"kept": kept, "faults": faults, "pages": size // 4096}))
"""


def _run(mode: str) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, mode], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_freed_block_is_reused_without_page_faults() -> None:
    if not sys.platform.startswith("linux") or not _run("keep")["kept"]:
        pytest.skip("no glibc mallopt here")
    kept, default = _run("keep"), _run("default")
    assert kept["kept"] and not default["kept"]
    assert default["faults"] > 0.5 * default["pages"]  # glibc's own: faulted in again
    assert kept["faults"] < 0.05 * kept["pages"]  # kept: the same pages reused


def test_keep_freed_memory_is_once_a_process() -> None:
    first = keep_freed_memory()
    assert keep_freed_memory() is first
