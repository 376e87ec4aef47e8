"""The drop-test validation run: many poses over several terrains, one predictor.

Settings come from a YAML file (``problems/validate_terrain.yaml``); the run writes
``summary.json`` (settings, per-terrain and overall error distributions, outliers
with explanations, timings) and ``validation.png`` (error histograms) to its output
folder (default ``results/terrain``). Predictors are chosen by name from
:data:`PREDICTORS`: ``plane`` (the analytic plane rest, planes only) and ``rest``
(``mmstab.terrain``'s resting pose, when that module is installed).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.files import ConfigError, MmstabError, read_yaml, validate, write_json, write_yaml
from mmstab.model.robot import FloatArray, Robot, load_robot
from mmstab.physics.compare import (
    Comparison,
    compare,
    default_explanation,
    distribution,
    rest_state_check,
)
from mmstab.physics.plane import Prediction, Predictor, plane_predictor

#: factory(robot, elevation [m], resolution [m/cell], origin [m], flipper_angle [rad] | None,
#: arm_posture (4,) [rad]) -> predictor(poses (N, 3)) -> (roll, pitch [rad], z [m]).
PredictorFactory = Callable[
    [Robot, FloatArray, float, FloatArray, "float | None", FloatArray], Predictor
]


def _plane(
    robot: Robot, e: FloatArray, res: float, origin: FloatArray, flip: float | None, q: FloatArray
) -> Predictor:
    return plane_predictor(e, res, origin)


def _rest(
    robot: Robot, e: FloatArray, res: float, origin: FloatArray, flip: float | None, q: FloatArray
) -> Predictor:
    try:
        from mmstab.terrain.heightmap import Heightmap
        from mmstab.terrain.heightmap_terrain import (
            HeightmapTerrain,
        )
    except ImportError as exc:
        raise MmstabError(
            f"predictor 'rest': mmstab.terrain's resting pose is missing ({exc})"
        ) from None
    terrain = HeightmapTerrain(Heightmap.build(e, res, origin, "validation")).with_robot(
        robot, flip, q
    )

    def predict(poses: FloatArray) -> Prediction:
        r = terrain.rest(np.asarray(poses, dtype=float), strict=False)
        return Prediction(np.asarray(r.roll), np.asarray(r.pitch), np.asarray(r.z))

    return predict


#: Predictors by name; :func:`register_predictor` adds one.
PREDICTORS: dict[str, PredictorFactory] = {"plane": _plane, "rest": _rest}


def register_predictor(name: str, factory: PredictorFactory) -> None:
    """Make ``factory`` selectable as ``predictor: NAME`` in the settings file."""
    PREDICTORS[name] = factory


SCHEMA: dict[str, Any] = {
    "type": "object",
    "additionalProperties": False,
    "required": ["robot", "predictor", "seed", "poses_per_terrain", "margin", "terrains"],
    "properties": {
        "robot": {"type": "string"},
        "predictor": {"type": "string"},
        "seed": {"type": "integer", "minimum": 0},
        "poses_per_terrain": {"type": "integer", "minimum": 1},
        "margin": {"type": "number", "minimum": 0},
        "flipper_angle": {"type": ["number", "null"]},
        "arm": {
            "oneOf": [
                {"const": "stowed"},
                {"type": "array", "items": {"type": "number"}, "minItems": 4, "maxItems": 4},
            ]
        },
        "compare_at": {"enum": ["settled", "commanded"]},
        "outlier_deg": {"type": "number", "exclusiveMinimum": 0},
        "outlier_z": {"type": "number", "exclusiveMinimum": 0},
        "drop": {"type": "object"},
        "terrains": {
            "type": "array",
            "minItems": 1,
            "items": {
                "type": "object",
                "required": ["name", "kind", "size", "resolution"],
                "properties": {
                    "name": {"type": "string"},
                    "kind": {"type": "string"},
                    "size": {
                        "type": "array",
                        "items": {"type": "number", "exclusiveMinimum": 0},
                        "minItems": 2,
                        "maxItems": 2,
                    },
                    "resolution": {"type": "number", "exclusiveMinimum": 0},
                },
            },
        },
    },
}


class Terrain(NamedTuple):
    """A generated validation terrain: name and grid_map arrays ([m], [m/cell], [m])."""

    name: str
    elevation: FloatArray
    resolution: float
    origin: FloatArray


def build_terrain(spec: dict[str, Any]) -> Terrain:
    """Make one terrain from its settings (``mmstab.terrain.generators`` when installed).

    Without that module only ``kind: plane`` (``slope`` [rad], ``azimuth`` [rad] uphill
    direction, through height 0 at the map centre) can be built.
    """
    try:
        from mmstab.terrain.generators import generate
    except ImportError:
        return _plane_terrain(spec)
    hm = generate({"seed": 0, **spec})
    return Terrain(
        spec["name"], np.asarray(hm.elevation), float(hm.resolution), np.asarray(hm.origin)
    )


def _plane_terrain(spec: dict[str, Any]) -> Terrain:
    if spec["kind"] != "plane":
        raise MmstabError(
            f"terrain {spec['name']}: kind {spec['kind']!r} needs mmstab.terrain.generators"
        )
    res = float(spec["resolution"])
    n = [int(np.ceil(s / res - 1e-9)) + 1 for s in spec["size"]]
    origin = -res * (np.array(n, dtype=float) - 1) / 2
    x = origin[0] + res * np.arange(n[0])
    y = origin[1] + res * np.arange(n[1])
    X, Y = np.meshgrid(x, y)
    az = float(spec["azimuth"])
    e = np.tan(float(spec["slope"])) * (X * np.cos(az) + Y * np.sin(az))
    return Terrain(spec["name"], e, res, origin)


def sample_poses(t: Terrain, n: int, margin: float, rng: np.random.Generator) -> FloatArray:
    """``n`` poses (x, y, yaw) uniform over the map less ``margin`` [m] at each edge (n, 3)."""
    ny, nx = t.elevation.shape
    lo = t.origin + margin
    hi = t.origin + t.resolution * np.array([nx - 1, ny - 1]) - margin
    if np.any(hi <= lo):
        raise MmstabError(f"terrain {t.name}: map smaller than twice the margin {margin} m")
    xy = rng.uniform(lo, hi, size=(n, 2))
    return np.column_stack([xy, rng.uniform(-np.pi, np.pi, n)])


class Run(NamedTuple):
    """One terrain's drops, comparison and timings [s]."""

    terrain: Terrain
    comparison: Comparison
    drop_wall: FloatArray
    predict_time: float


def load_settings(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read and check the validation settings file (errors name the file and field)."""
    data = read_yaml(path)
    validate(path, data, SCHEMA)
    if data["predictor"] not in PREDICTORS:
        raise ConfigError(
            path, "predictor", f"unknown {data['predictor']!r}; known: {sorted(PREDICTORS)}"
        )
    from mmstab.physics.mujoco_drop import DropSettings

    known = {f.name for f in dataclasses.fields(DropSettings)}
    for key in data.get("drop", {}):
        if key not in known:
            raise ConfigError(path, f"drop.{key}", f"unknown setting; known: {sorted(known)}")
    data["robot_path"] = str((Path(path).parent / data["robot"]).resolve())
    return data


def run_validation(settings: dict[str, Any], log: Callable[[str], None] = print) -> list[Run]:
    """Drop and predict on every terrain of ``settings`` (see :func:`load_settings`)."""
    from mmstab.physics.mujoco_drop import DropModel, DropSettings, drop

    robot = load_robot(settings["robot_path"])
    arm = settings.get("arm", "stowed")
    q = robot.stowed if arm == "stowed" else np.asarray(arm, dtype=float)
    flip = settings.get("flipper_angle")
    drop_settings = DropSettings(**_tuples(settings.get("drop", {})))
    rng = np.random.default_rng(settings["seed"])
    runs = []
    for spec in settings["terrains"]:
        t = build_terrain(spec)
        poses = sample_poses(t, settings["poses_per_terrain"], settings["margin"], rng)
        dm = DropModel(robot, t.elevation, t.resolution, t.origin, flip, q, drop_settings)
        drops = drop(dm, poses)
        predict = PREDICTORS[settings["predictor"]](
            robot, t.elevation, t.resolution, t.origin, flip, q
        )
        start = time.perf_counter()
        predict(drops.settled_poses)  # timed alone: compare() below also runs the hooks
        elapsed = time.perf_counter() - start
        cmp = compare(
            predict,
            drops,
            at=settings.get("compare_at", "settled"),
            outlier_deg=settings.get("outlier_deg", 2.0),
            outlier_z=settings.get("outlier_z", 0.01),
            explain=(default_explanation, rest_state_check(dm, predict)),
        )
        s = cmp.stats
        log(
            f"{t.name}: {s['settled']}/{s['drops']} settled; median/p95/max roll "
            f"{_triple(s['roll_deg'])} deg, pitch {_triple(s['pitch_deg'])} deg, "
            f"z {_triple(s['z_m'], 1000)} mm; {len(cmp.outliers)} outliers"
        )
        runs.append(Run(t, cmp, drops.wall_time, elapsed))
    return runs


def _tuples(d: dict[str, Any]) -> dict[str, Any]:
    return {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}


def _triple(d: dict[str, float], scale: float = 1.0) -> str:
    return "/".join(f"{scale * d[k]:.3g}" for k in ("median", "p95", "max"))


def summary(settings: dict[str, Any], runs: list[Run]) -> dict[str, Any]:
    """The JSON written as ``summary.json``."""
    from mmstab.physics.mujoco_drop import DropSettings

    def errors(cmps: list[Comparison]) -> dict[str, Any]:
        ok = np.concatenate([c.settled for c in cmps])
        cat = {
            k: np.concatenate([getattr(c, k) for c in cmps])[ok]
            for k in ("roll_deg", "pitch_deg", "z_m")
        }
        return {k: distribution(v) for k, v in cat.items()} | {
            "drops": int(len(ok)),
            "settled": int(ok.sum()),
        }

    terrains = {
        r.terrain.name: r.comparison.stats | {"outliers": r.comparison.outliers} for r in runs
    }
    walls = np.concatenate([r.drop_wall for r in runs])
    drops = sum(len(r.drop_wall) for r in runs)
    return {
        "predictor": settings["predictor"],
        "overall": errors([r.comparison for r in runs]),
        "terrains": terrains,
        "timing": {
            "drop_wall_s": distribution(walls),
            "predict_per_pose_s": sum(r.predict_time for r in runs) / max(drops, 1),
        },
        "drop_settings": dataclasses.asdict(DropSettings(**_tuples(settings.get("drop", {})))),
        "settings": {k: v for k, v in settings.items() if k != "robot_path"},
    }


def figure(runs: list[Run]) -> Any:
    """Histograms of |Δroll|, |Δpitch| [deg] and |Δz| [mm] (log axes), one colour per terrain.

    Dashed lines: the targets (median 0.5 deg, 95th percentile 2 deg; height 10 mm).
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    for ax, key, label, scale, targets in (
        (axes[0], "roll_deg", "|Δroll| [deg]", 1.0, (0.5, 2.0)),
        (axes[1], "pitch_deg", "|Δpitch| [deg]", 1.0, (0.5, 2.0)),
        (axes[2], "z_m", "|Δz| [mm]", 1000.0, (10.0,)),
    ):
        floor = 1e-6
        data = [
            np.maximum(scale * getattr(r.comparison, key)[r.comparison.settled], floor)
            for r in runs
        ]
        top = max([float(d.max()) for d in data if d.size] + [max(targets)])
        bins = np.logspace(np.log10(floor), np.log10(top * 1.5), 40)
        ax.hist(data, bins=bins, stacked=True, label=[r.terrain.name for r in runs])
        for t in targets:
            ax.axvline(t, color="k", linestyle="--", linewidth=0.8)
        ax.set_xscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("drops")
    axes[0].legend(fontsize=8)
    fig.suptitle("resting pose: prediction minus MuJoCo heightfield drop (settled drops)")
    fig.tight_layout()
    return fig


def main_validation(
    path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    predictor: str | None = None,
    extra: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Load settings, run, write ``summary.json``/``.png``/``_settings.yaml``; the summary."""
    settings = load_settings(path)
    if predictor is not None:
        if predictor not in PREDICTORS:
            raise MmstabError(f"--predictor: unknown {predictor!r}; known: {sorted(PREDICTORS)}")
        settings["predictor"] = predictor
    runs = run_validation(settings)
    out = Path(out_dir)
    data = summary(settings, runs) | {"source": str(path)} | (extra or {})
    from mmstab.core.files import write_figure

    write_json(out / "summary.json", _finite(data))
    write_figure(out / "validation.png", figure(runs))
    write_yaml(out / "validation_settings.yaml", data["settings"] | {"source": str(path)})
    return data


def _finite(node: Any) -> Any:
    """NaN/inf (an empty distribution) -> None, so the JSON stays strict."""
    if isinstance(node, dict):
        return {k: _finite(v) for k, v in node.items()}
    if isinstance(node, list | tuple):
        return [_finite(v) for v in node]
    if isinstance(node, float) and not np.isfinite(node):
        return None
    return node
