"""Benchmark: MuJoCo drops per pose, a Python loop with early stop vs ``mujoco.rollout``.

Usage: ``python benchmarks/bench_drop.py [--poses N] [--runs R]``; writes
``results/bench/drop.json``. The loop (:func:`mmstab.physics.mujoco_drop.drop`) stops
each drop once it has settled; ``mujoco.rollout`` runs every pose for a fixed horizon
(the longest settling time the loop needed) on its own thread pool. Medians over runs:
the machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np
from common import machine_info
from mujoco import rollout

from mmstab.core.files import write_json
from mmstab.model.robot import load_robot
from mmstab.physics.drop_validation import build_terrain, sample_poses
from mmstab.physics.mujoco_drop import DropModel, _quat, drop

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    """Time both ways on one steep plane and write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=30)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    robot = load_robot(ROOT / "problems" / "robots" / "cameleon.yaml")
    spec = {"name": "steep", "kind": "plane", "slope": 0.4, "azimuth": -1.2}
    t = build_terrain(spec | {"size": [4.0, 4.0], "resolution": 0.05})
    poses = sample_poses(t, args.poses, 0.8, np.random.default_rng(0))
    dm = DropModel(robot, t.elevation, t.resolution, t.origin)
    loop, results = [], None
    for _ in range(args.runs):
        start = time.perf_counter()
        results = drop(dm, poses)
        loop.append((time.perf_counter() - start) / len(poses))
    assert results is not None
    nstep = int(np.ceil(results.time.max() / dm.settings.timestep))
    m = dm.model
    size = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    states = np.zeros((len(poses), size))
    d = mujoco.MjData(m)
    for i, p in enumerate(poses):
        T0 = dm.initial_pose(p)
        mujoco.mj_resetData(m, d)
        d.qpos[:3], d.qpos[3:7] = T0[:3, 3], _quat(T0[:3, :3])
        mujoco.mj_getState(m, d, states[i], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    threads = os.cpu_count() or 1
    datas = [mujoco.MjData(m) for _ in range(threads)]
    roll = []
    for _ in range(args.runs):
        start = time.perf_counter()
        out, _ = rollout.rollout(m, datas, states, nstep=nstep)
        roll.append((time.perf_counter() - start) / len(poses))
    final_z = out[:, -1, 3]  # state = [time, qpos...]: qpos[2] is z
    data = {
        "poses": len(poses),
        "settle_time_s": {
            "median": float(np.median(results.time)),
            "max": float(results.time.max()),
        },
        "loop_early_stop_s_per_pose": statistics.median(loop),
        "rollout_fixed_horizon_s_per_pose": statistics.median(roll),
        "rollout_threads": threads,
        "rollout_nstep": nstep,
        "rollout_vs_loop_max_dz_m": float(np.max(np.abs(final_z - results.z))),
        **machine_info(mujoco=mujoco.__version__),
    }
    write_json(ROOT / "results" / "bench" / "drop.json", data)
    print(
        f"loop (early stop) {1000 * data['loop_early_stop_s_per_pose']:.1f} ms/pose, "
        f"rollout ({nstep} steps, {threads} threads) "
        f"{1000 * data['rollout_fixed_horizon_s_per_pose']:.1f} ms/pose"
    )


if __name__ == "__main__":
    main()
