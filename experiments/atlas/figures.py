"""The operator's envelope, the atlas figures and ``summary.json``, read from the store.

Envelope: for each heading, the steepest slope [rad] up to which mu stays at or above the
margin, walking up the slope axis from its first value; the crossing between the last
slope above the margin and the first below is interpolated linearly in mu. If mu never
drops below the margin the limit is the last slope and is marked censored (the true
limit is steeper); if it is below at the first slope the limit is NaN.

Slip limit (:mod:`mmstab.stability.slip`): the tracks slide once the slope exceeds
``atan(terrain.friction)``, whatever the heading (a rigid robot on a plane; on a generated
heightmap the slope axis is the generator's nominal slope, the local tilt at rest is not
stored). Per heading and arm choice the summary says which limit binds first: ``slip``
when the slip limit is below the tip envelope (a censored envelope counts as its axis end,
a NaN one as 0), else ``tip``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import write_figure
from mmstab.model.robot import FloatArray
from mmstab.terrain.base import DEFAULT_FRICTION

MEASURES = (("mu_planned", "planned"), ("mu_stowed", "stowed"), ("mu_arm_removed", "arm removed"))


class Envelope(NamedTuple):
    """Steepest slope per heading at which mu >= margin.

    Attributes:
        limit: slope limit per heading (H,) [rad]; NaN when below margin at the first slope.
        censored: the limit is the last slope of the axis (mu never dropped below) (H,).
    """

    limit: FloatArray
    censored: np.ndarray


def envelope(slopes: ArrayLike, mu: ArrayLike, margin: float) -> Envelope:
    """The envelope of one measure.

    Args:
        slopes: slope axis (S,), increasing [rad].
        mu: measure (S, H) [N rad] (NaN cells give a NaN limit).
        margin: threshold [N rad].
    """
    s = np.asarray(slopes, dtype=float)
    m = np.asarray(mu, dtype=float)
    limit = np.full(m.shape[1], np.nan)
    censored = np.zeros(m.shape[1], dtype=bool)
    for h in range(m.shape[1]):
        col = m[:, h]
        if np.isnan(col).any() or col[0] < margin:
            continue
        below = np.flatnonzero(col < margin)
        if len(below) == 0:
            limit[h], censored[h] = s[-1], True
            continue
        k = int(below[0])
        frac = (col[k - 1] - margin) / (col[k - 1] - col[k])
        limit[h] = s[k - 1] + frac * (s[k] - s[k - 1])
    return Envelope(limit, censored)


def _edges(centres: FloatArray, default_width: float) -> FloatArray:
    if len(centres) == 1:
        return centres[0] + np.array([-0.5, 0.5]) * default_width
    mid = (centres[1:] + centres[:-1]) / 2
    return np.concatenate([[2 * centres[0] - mid[0]], mid, [2 * centres[-1] - mid[-1]]])


def atlas_variants(ds: Any) -> list[tuple[dict[str, Any], str]]:
    """Every (robot, flipper, payload, terrain) of the store: its ``sel`` and a title."""
    out = []
    several_payloads = ds.sizes["payload"] > 1
    for rb in ds["robot"].values:
        for fl in ds["flipper"].values:
            for pl in ds["payload"].values:
                for tr in ds["terrain"].values:
                    title = f"{rb}, flippers {fl}"
                    if several_payloads or float(pl) != 0.0:
                        title += f", payload {float(pl):g} kg"
                    if str(tr) != "ramp":
                        title += f", {tr}"
                    out.append(({"robot": rb, "flipper": fl, "payload": pl, "terrain": tr}, title))
    return out


def _polar_axes(fig: Any, rows: int, cols: int, k: int) -> Any:
    ax = fig.add_subplot(rows, cols, k, projection="polar")
    ax.set_theta_zero_location("E")
    ax.set_theta_direction(1)
    ax.set_xticks(np.radians([0, 90, 180, 270]))
    ax.set_xticklabels(["0 across", "90 uphill", "180", "270 downhill"], fontsize=7)
    ax.tick_params(labelsize=7)
    return ax


def heatmap_figure(ds: Any, path: Path) -> Path:
    """Polar heatmaps over heading x slope: planned mu, and planned minus stowed mu."""
    from mmstab.viz.plotting import new_figure

    heading = ds["heading"].values
    slope_deg = np.degrees(ds["slope"].values)
    th = _edges(heading, 2 * math.pi)
    r = _edges(slope_deg, 2.0)
    r = np.clip(r, 0.0, None)
    variants = atlas_variants(ds)
    fig = new_figure(figsize=(9, 4.2 * len(variants)))[0]
    fig.clf()
    mu = ds["mu_planned"].values
    vmin, vmax = float(np.nanmin(mu)), float(np.nanmax(mu))
    gain = ds["mu_planned"].values - ds["mu_stowed"].values
    gmax = float(np.nanmax(np.abs(gain))) or 1.0
    margin = float(ds.attrs["margin"])
    for k, (sel, title) in enumerate(variants):
        cell = ds.sel(sel)
        ax = _polar_axes(fig, len(variants), 2, 2 * k + 1)
        z = cell["mu_planned"].values
        m = ax.pcolormesh(th, r, z, vmin=vmin, vmax=vmax, cmap="viridis")
        if len(heading) > 1 and len(slope_deg) > 1 and np.nanmin(z) < margin < np.nanmax(z):
            ax.contour(heading, slope_deg, z, levels=[margin], colors="w", linewidths=1.2)
        fig.colorbar(m, ax=ax, shrink=0.7, pad=0.1, label="planned mu [N rad]")
        ax.set_title(f"{title}: planned mu (white: margin)", fontsize=9)
        ax2 = _polar_axes(fig, len(variants), 2, 2 * k + 2)
        g = cell["mu_planned"].values - cell["mu_stowed"].values
        m2 = ax2.pcolormesh(th, r, g, vmin=-gmax, vmax=gmax, cmap="RdBu")
        fig.colorbar(m2, ax=ax2, shrink=0.7, pad=0.1, label="planned - stowed [N rad]")
        ax2.set_title(f"{title}: gain over the stowed arm", fontsize=9)
    fig.suptitle(
        "radius: slope [deg] (a generated map's slope parameter); angle: heading [deg] "
        "about the slope normal",
        fontsize=9,
    )
    return write_figure(path, fig)


def slip_limit_rad(ds: Any) -> float:
    """The slope at which the tracks slide [rad]: ``atan(friction)`` (``ds.attrs``)."""
    return math.atan(float(ds.attrs.get("friction", DEFAULT_FRICTION)))


def binds_first(env: Envelope, slip: float) -> list[str]:
    """Per heading: ``slip`` when the tracks slide before the envelope's tip limit, else ``tip``.

    Args:
        env: the tip envelope (limits [rad]).
        slip: the slip limit [rad].
    """
    tip = np.nan_to_num(env.limit, nan=0.0)
    return ["slip" if slip < t else "tip" for t in tip]


def variant_envelopes(ds: Any, sel: dict[str, Any], margin: float) -> dict[str, Envelope]:
    """The three envelopes (planned, stowed, arm removed) of one variant (``ds.sel(sel)``)."""
    cell = ds.sel(sel)
    return {
        label: envelope(ds["slope"].values, cell[name].values, margin) for name, label in MEASURES
    }


def envelope_figure(ds: Any, path: Path) -> Path:
    """Per variant: the steepest slope per heading with mu >= margin, three arm choices."""
    from mmstab.viz.plotting import new_figure

    heading = ds["heading"].values
    margin = float(ds.attrs["margin"])
    variants = atlas_variants(ds)
    cols = min(2, len(variants))
    rows = -(-len(variants) // cols)
    fig = new_figure(figsize=(5 * cols, 4.6 * rows))[0]
    fig.clf()
    closed = len(heading) > 2 and math.isclose(
        heading[-1] + (heading[1] - heading[0]) - heading[0], 2 * math.pi, abs_tol=1e-6
    )
    for k, (sel, title) in enumerate(variants):
        ax = _polar_axes(fig, rows, cols, k + 1)
        for (label, env), style in zip(
            variant_envelopes(ds, sel, margin).items(), ("-", "--", ":"), strict=True
        ):
            th, lim = heading, np.degrees(env.limit)
            if closed:
                th, lim = np.append(th, th[0] + 2 * math.pi), np.append(lim, lim[0])
            ax.plot(th, lim, style, lw=1.6, label=label, marker="." if len(th) < 40 else None)
        top = float(np.degrees(ds["slope"].values[-1]))
        ring = np.linspace(0, 2 * math.pi, 200)
        slip = math.degrees(slip_limit_rad(ds))
        label = f"tracks slide (friction {float(ds.attrs.get('friction', DEFAULT_FRICTION)):g})"
        ax.plot(ring, np.full_like(ring, slip), color="tab:red", lw=1.0, ls="-.", label=label)
        ax.plot(ring, np.full_like(ring, top), color="0.6", lw=0.8, label="axis end (censored)")
        ax.set_rmin(0.0)
        ax.set_rmax(top * 1.04)
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(-0.15, -0.15))
    fig.suptitle(
        f"operator's envelope: steepest slope [deg] per heading with mu >= {margin:g} N rad",
        fontsize=10,
    )
    return write_figure(path, fig)


def _num(x: float) -> float | None:
    return None if not math.isfinite(x) else round(float(x), 6)


def _list(a: ArrayLike) -> list[float | None]:
    return [_num(float(v)) for v in np.asarray(a, dtype=float)]


def summary(ds: Any, run: dict[str, Any]) -> dict[str, Any]:
    """``summary.json``: axes, per-variant envelopes and statistics, and the run."""
    margin = float(ds.attrs["margin"])
    done = ds["chunk_done"].values
    slip = slip_limit_rad(ds)
    out: dict[str, Any] = {
        "margin_N_rad": margin,
        "friction": float(ds.attrs.get("friction", DEFAULT_FRICTION)),
        "slip_limit_deg": _num(math.degrees(slip)),
        "cells": int(ds["mu_planned"].size),
        "chunks_stored": int(done.sum()),
        "chunks": int(done.size),
        "axes": {
            "robot": [str(v) for v in ds["robot"].values],
            "flipper": [str(v) for v in ds["flipper"].values],
            "payload_kg": _list(ds["payload"].values),
            "terrain": [str(v) for v in ds["terrain"].values],
            "slope_rad": _list(ds["slope"].values),
            "heading_rad": _list(ds["heading"].values),
        },
        "variants": [],
        "run": run,
    }
    for sel, _ in atlas_variants(ds):
        cell = ds.sel(sel)
        envs = variant_envelopes(ds, sel, margin)
        lim = {k: np.degrees(e.limit) for k, e in envs.items()}
        gain = lim["planned"] - lim["stowed"]
        out["variants"].append(
            {
                "robot": str(sel["robot"]),
                "flipper": str(sel["flipper"]),
                "payload_kg": _num(float(sel["payload"])),
                "terrain": str(sel["terrain"]),
                "flipper_angle_rad": _num(float(cell["flipper_angle"])),
                "mu_max_N_rad": _num(float(cell["mu_max"])),
                "mu_planned_N_rad": [
                    _num(float(np.nanmin(cell["mu_planned"]))),
                    _num(float(np.nanmax(cell["mu_planned"]))),
                ],
                "cells_without_rest": int(np.isnan(cell["mu_stowed"].values).sum()),
                "planner_seconds_median": _num(float(np.nanmedian(cell["planner_seconds"]))),
                "envelope_deg": {k: _list(v) for k, v in lim.items()},
                "censored": {k: e.censored.tolist() for k, e in envs.items()},
                "binds_first": {k: binds_first(e, slip) for k, e in envs.items()},
                "slip_binds_share": {
                    k: _num(float(np.mean([b == "slip" for b in binds_first(e, slip)])))
                    for k, e in envs.items()
                },
                "min_limit_deg": {k: _num(float(np.nanmin(v))) for k, v in lim.items()},
                "mean_limit_deg": {k: _num(float(np.nanmean(v))) for k, v in lim.items()},
                "planning_gain_over_stowed_deg": {
                    "mean": _num(float(np.nanmean(gain))),
                    "min": _num(float(np.nanmin(gain))),
                    "max": _num(float(np.nanmax(gain))),
                },
            }
        )
    return out
