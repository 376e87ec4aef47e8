"""Benchmark: how long until a browser can load the viewer, viser against MeshCat.

Usage: ``python benchmarks/bench_view.py [PROBLEM.yaml] [--run DIR] [--runs N]
[--meshcat-python PY]``; writes ``results/bench/view.json``. Each case is a fresh process,
timed from its start to the first HTTP 200 of its page (a browser could load it then):

- ``viser_bare``: ``import viser`` and an empty ``ViserServer``;
- ``mmstab_view``: the whole ``mmstab view PROBLEM --run DIR`` (problem, run, scene);
- ``meshcat_bare``: ``import meshcat`` and a ``Visualizer`` (its ZMQ + web server), the
  peer, with the interpreter given by ``--meshcat-python`` (MeshCat is not a project
  dependency: ``python -m venv /tmp/mc && /tmp/mc/bin/pip install meshcat``); skipped
  without it.

Medians over ``--runs`` (the machine may be shared).
"""

from __future__ import annotations

import argparse
import re
import signal
import statistics
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

from common import machine_info

from mmstab.core.files import write_json

VISER = (
    "import viser, time; s = viser.ViserServer(host='127.0.0.1', port=0, verbose=False); "
    "print(f'URL http://127.0.0.1:{s.get_port()}/', flush=True); time.sleep(60)"
)
MESHCAT = (
    "import meshcat, time; v = meshcat.Visualizer(); "
    "print('URL ' + v.url(), flush=True); time.sleep(60)"
)


def time_to_page(cmd: list[str], timeout: float = 60.0) -> float:
    """Seconds from starting ``cmd`` to an HTTP 200 from the URL it prints (``... URL ...``)."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert proc.stdout is not None
        url = None
        while url is None:
            line = proc.stdout.readline()
            if not line:
                raise RuntimeError(f"{cmd[:3]}: ended without printing a URL")
            found = re.search(r"(http://\S+)", line)
            url = found.group(1) if found else None
        while True:
            try:
                with urllib.request.urlopen(url, timeout=5) as page:
                    if page.status == 200:
                        return time.perf_counter() - start
            except OSError:
                if time.perf_counter() - start > timeout:
                    raise
                time.sleep(0.01)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def main() -> None:
    """Run the benchmark and write its JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("--run", default="results/tracking")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--meshcat-python", default=None)
    ap.add_argument("--out", default="results/bench/view.json")
    args = ap.parse_args()
    view = [sys.executable, "-m", "mmstab", "view", args.problem, "--port", "0", "--no-browser"]
    if Path(args.run, "run.npz").is_file():
        view += ["--run", args.run]
    cases = {"viser_bare": [sys.executable, "-c", VISER], "mmstab_view": view}
    if args.meshcat_python:
        cases["meshcat_bare"] = [args.meshcat_python, "-c", MESHCAT]
    results = {}
    for name, cmd in cases.items():
        times = [time_to_page(cmd) for _ in range(args.runs)]
        results[name] = {"median_s": statistics.median(times), "runs_s": times}
        print(f"{name:13s} {statistics.median(times):.3f} s to the first page (median)")
    import viser

    write_json(
        args.out,
        {
            "what": "seconds from process start to the first HTTP 200 of the viewer page",
            "with_run": "--run" in view,
            "results": results,
            "machine": machine_info(viser=viser.__version__),
        },
    )


if __name__ == "__main__":
    main()
