"""A problem's filled-in sections come out in one order, whatever Python's string hashing.

``with_defaults`` fills the omitted sections; the saved ``problem.yaml`` of every run lists them
in that order, so two runs of the same command write the same file (a set of section names
iterated in hash order moved whole sections between runs).
"""

from __future__ import annotations

import os
import subprocess
import sys

from conftest import ROOT

_SCRIPT = (
    "import json; from mmstab.core.defaults import with_defaults; "
    "print(json.dumps(list(with_defaults({'robot': 'r.yaml'}))))"
)


def test_section_order_does_not_depend_on_the_hash_seed() -> None:
    orders = []
    for seed in ("1", "2", "3"):
        env = {**os.environ, "PYTHONHASHSEED": seed, "PYTHONPATH": str(ROOT)}
        out = subprocess.run([sys.executable, "-c", _SCRIPT], env=env, cwd=ROOT,
                             capture_output=True, text=True, check=True)  # fmt: skip
        orders.append(out.stdout.strip())
    assert orders[0] == orders[1] == orders[2]
    assert '"robot"' in orders[0] and '"physics"' in orders[0] and '"online"' in orders[0]
