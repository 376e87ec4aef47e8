"""``make rest-mu``: mmstab's μ on its loaded support against MuJoCo's robot settled at rest.

The support mmstab's μ is taken on (:mod:`mmstab.stability.support`) is the contacts that
carry the load: the touching ones and the tracks' bottom run within ``compliance`` of the
ground. MuJoCo's robot stands on rows of sprung road wheels. This experiment measures which
compliance makes the two agree, at rest, so the difference in motion is not a difference
of assumptions: seeded maps drawn by the validation's generator (another seed), the robot
(arm stowed) set at poses along each map's route and left braked for ``settle_s`` in
MuJoCo; at its settled pose, the μ of MuJoCo's loaded contacts beside mmstab's μ for each
compliance in the list. States where MuJoCo came to rest off mmstab's resting attitude
(``same_rest_deg``) are reported apart: there the support differs for another reason.

Writes ``summary.json`` (settings, per-state records, per compliance the relative
difference (mmstab − MuJoCo) / MuJoCo: median of its magnitude, median, 10-90 %, shares
within ±5 % and optimistic by more than 5 %; over all states, those at the same rest, and
the maps with and without egg-box bumps) and ``rest_mu.png``.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from experiments.common import experiment_run
from mmstab.core.files import read_yaml, validate, write_figure, write_json

_NUMS = {"type": "array", "items": {"type": "number", "minimum": 0}, "minItems": 1}
SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "required": ["generator", "seed", "maps", "poses_per_map", "settle_s", "compliance_m"],
    "properties": {
        "generator": {"type": "string"},
        "seed": {"type": "integer"},
        "maps": {"type": "integer", "minimum": 1},
        "poses_per_map": {"type": "integer", "minimum": 1},
        "settle_s": {"type": "number", "exclusiveMinimum": 0},
        "same_rest_deg": {"type": "number", "minimum": 0},
        "compliance_m": _NUMS,
        "workers": {"type": "integer", "minimum": 1},
    },
}


def load_settings(path: str | Path) -> dict[str, Any]:
    """Read and check the settings file and its generator's (errors name file and field)."""
    from experiments.validate_routes import load_settings as load_generator

    data = read_yaml(path)
    validate(path, data, SCHEMA)
    generator = load_generator(Path(path).parent / data["generator"])
    data["generator_settings"] = {**generator, "seed": data["seed"]}
    return data


def map_states(task: tuple[dict[str, Any], int, str]) -> list[dict[str, Any]]:
    """Map k's states (the pool's job): MuJoCo's settled μ and mmstab's per compliance."""
    from experiments.validate_routes import ground_record, route_problem
    from mmstab.core.problem import load_problem
    from mmstab.physics.loop_checks import contact_points, simulated_mu
    from mmstab.physics.robot_sim import RobotSim
    from mmstab.stability.support import loaded_mu

    settings, k, out = task
    data = route_problem(settings["generator_settings"], k)
    path = Path(out) / "problems" / f"map{k:02d}.yaml"
    path.write_text(yaml.safe_dump(data))
    problem = load_problem(path)
    from mmstab.terrain import HeightmapTerrain

    robot, terrain = problem.robot, problem.terrain
    if not isinstance(terrain, HeightmapTerrain):  # the generator writes heightmaps
        raise TypeError(f"map {k}: expected a heightmap terrain, got {terrain.kind!r}")
    n = settings["poses_per_map"]
    fractions = (np.arange(n) + 0.5) / n
    M_T_G = np.linalg.inv(terrain.G_T_M())
    records = []
    for pose in problem.base_path.pose_at(fractions):
        sim = RobotSim(robot, terrain, pose=pose)
        st = sim.step((0.0, 0.0), None, settings["settle_s"])
        m, d = sim.model, sim.data
        wheels = [g for g in range(m.ngeom) if m.geom(g).name.startswith("wheel_")]
        mu_sim = simulated_mu(contact_points(sim, wheels), d.subtree_com[0].copy(),
                              float(m.body_subtreemass[0]))  # fmt: skip
        M_T_B = M_T_G @ st.G_T_B
        settled = np.array([M_T_B[0, 3], M_T_B[1, 3], np.arctan2(M_T_B[1, 0], M_T_B[0, 0])])
        rest = terrain.rest(settled[None], strict=False)
        z_rest = rest.G_T_B[0, :3, 2]
        off = float(np.degrees(np.arccos(np.clip(z_rest @ st.G_T_B[:3, 2], -1.0, 1.0))))
        q = st.arm_q[None]
        mu_pred = [
            float(loaded_mu(robot, dataclasses.replace(
                terrain, settings=terrain.settings._replace(compliance=c)),
                settled[None], robot.arm_com(q), q, strict=False)[0])
            for c in settings["compliance_m"]
        ]  # fmt: skip
        records.append({"map": k, **ground_record(data), "pose": settled.tolist(),
                        "off_rest_deg": off, "speed_m_s": float(np.linalg.norm(st.velocity_body)),
                        "mu_simulated": mu_sim, "mu_predicted": mu_pred})  # fmt: skip
    return records


def compliance_table(settings: dict[str, Any], records: list[dict[str, Any]]) -> dict[str, Any]:
    """Per compliance: the relative difference (mmstab − MuJoCo) / MuJoCo's statistics."""
    sim = np.array([r["mu_simulated"] for r in records])
    pred = np.array([r["mu_predicted"] for r in records]).reshape(len(records), -1)
    same = np.array([r["off_rest_deg"] <= settings.get("same_rest_deg", 1.0) for r in records])
    bumps = np.array([bool(r["bumps"]) for r in records])
    ok = np.isfinite(sim) & (np.abs(sim) > 1e-9)
    table = {}
    for j, c in enumerate(settings["compliance_m"]):
        row = {}
        groups = (("all", ok), ("same_rest", ok & same), ("bumps", ok & bumps),
                  ("no_bumps", ok & ~bumps))  # fmt: skip
        for name, mask in groups:
            rel = (pred[mask, j] - sim[mask]) / np.abs(sim[mask])
            rel = rel[np.isfinite(rel)]
            row[name] = {
                "n": int(rel.size),
                "median_abs": float(np.median(np.abs(rel))) if rel.size else None,
                "median": float(np.median(rel)) if rel.size else None,
                "p10_p90": np.percentile(rel, [10, 90]).tolist() if rel.size else None,
                "within_5pc": float(np.mean(np.abs(rel) <= 0.05)) if rel.size else None,
                "optimistic_over_5pc": float(np.mean(rel > 0.05)) if rel.size else None,
            }
        table[f"{c:g}"] = row
    best = min(table, key=lambda c: table[c]["same_rest"]["median_abs"] or np.inf)
    return {"by_compliance_m": table, "best_same_rest_m": float(best)}


def draw(summary: dict[str, Any]) -> Any:
    """Median |difference| and the optimistic share against the compliance."""
    import matplotlib.pyplot as plt

    table = summary["by_compliance_m"]
    c = np.array([float(k) for k in table]) * 100
    fig, ax = plt.subplots(figsize=(6.0, 3.4), constrained_layout=True)
    for name, style in (("same_rest", "-o"), ("all", "--s")):
        ax.plot(c, [100 * table[k][name]["median_abs"] for k in table], style, color="C0",
                label=f"median |difference| ({name.replace('_', ' ')})")  # fmt: skip
        ax.plot(
            c,
            [100 * table[k][name]["optimistic_over_5pc"] for k in table],
            style,
            color="C3",
            label=f"share mmstab > MuJoCo + 5 % ({name.replace('_', ' ')})",
        )
    ax.axhline(5, color="0.6", lw=0.8, ls=":")
    ax.set(
        xlabel="compliance of the tracks' bottom run [cm]",
        ylabel="[%]",
        title=f"mu at rest: mmstab's loaded support vs MuJoCo ({summary['states']} states)",
    )
    ax.legend(fontsize=7)
    return fig


def run_rest_mu(settings: dict[str, Any], out: str | Path) -> dict[str, Any]:
    """Settle the robot at every map's poses, compare, write the summary and figure."""
    out = Path(out)
    (out / "problems").mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    tasks = [(settings, k, str(out)) for k in range(settings["maps"])]
    workers = settings.get("workers", 1)
    if workers == 1:
        records = [r for t in tasks for r in map_states(t)]
    else:
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=ctx) as pool:
            records = [r for rs in pool.map(map_states, tasks) for r in rs]
    summary = {
        "states": len(records),
        **compliance_table(settings, records),
        "seconds": time.perf_counter() - t0,
        "settings": {k: v for k, v in settings.items() if k != "generator_settings"},
        "records": records,
    }
    write_json(out / "summary.json", summary)
    write_figure(out / "rest_mu.png", draw(summary))
    return summary


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.rest_mu [SETTINGS] [-o DIR]``; exit status."""
    got = experiment_run(argv, __doc__, "problems/rest_mu.yaml", "results/rest_mu",
                         run_rest_mu, load_settings)  # fmt: skip
    if isinstance(got, int):
        return got
    s, out = got
    for c, row in s["by_compliance_m"].items():
        a, b = row["same_rest"], row["all"]
        print(f"compliance {c} m: median |diff| {100 * a['median_abs']:.1f} % "
              f"(all {100 * b['median_abs']:.1f} %), optimistic > 5 %: "
              f"{100 * a['optimistic_over_5pc']:.0f} %")  # fmt: skip
    best = s["best_same_rest_m"]
    print(f"best (same rest): {best:g} m -> {out}/summary.json ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
