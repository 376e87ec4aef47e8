"""The figure of ``make validate-routes`` (``validate_routes.png``).

Four panels: the confusion table (the plan's verdict and exit status against MuJoCo's
outcome), μ predicted against simulated (route medians, coloured by the plan's verdict), the
accepted routes' largest base errors (body origin and control point, the bar) and every
route's outcome against its map's side slope.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def draw(summary: dict[str, Any]) -> Any:
    """The confusion table, μ predicted vs simulated, tracking errors, acceptance by slope."""
    import matplotlib.pyplot as plt

    records = [r for r in summary["records"] if r["mujoco"] is not None]
    PLAN_VERDICTS = summary["plan_exit_statuses"]  # noqa: N806 (verdict -> exit status)
    OUTCOMES = tuple(summary["mujoco_outcomes"])  # noqa: N806 (in the outcomes' order)
    fig, ((a, b), (c, d)) = plt.subplots(2, 2, figsize=(12, 9))
    rows, cols = list(PLAN_VERDICTS), list(OUTCOMES)
    table = np.array([[summary["confusion"][v][o] for o in cols] for v in rows])
    a.imshow(table, cmap="Blues")
    for (i, j), n in np.ndenumerate(table):
        a.text(j, i, str(n), ha="center", va="center", fontsize=11)
    a.set(xticks=range(len(cols)), xticklabels=cols, yticks=range(len(rows)),
          yticklabels=[f"{v} ({PLAN_VERDICTS[v]})" for v in rows],
          xlabel="MuJoCo", ylabel="mmstab plan (exit status)",
          title=f"{summary['routes']} routes: plan's verdict vs MuJoCo's")  # fmt: skip
    colour = {"accepted": "C2", "tips": "C3", "slides": "C1", "no plan": "k"}
    for v in PLAN_VERDICTS:
        rs = [r for r in records if r["plan"] == v and r["mu_predicted_median"] is not None]
        if rs:
            b.scatter([r["mu_predicted_median"] for r in rs],
                      [r["mu_simulated_median"] for r in rs],
                      s=18, color=colour[v], label=v)  # fmt: skip
    lim = b.get_xlim()
    b.plot(lim, lim, "k-", lw=0.7)
    b.set(xlabel="mmstab mu at the simulated pose, route median [N rad]",
          ylabel="MuJoCo loaded contacts' mu, route median [N rad]",
          title="mu predicted vs simulated")  # fmt: skip
    b.legend(fontsize=8, title="plan")
    acc = [r for r in records if r["plan"] == "accepted"]
    x = np.arange(len(acc))
    c.bar(x - 0.2, [100 * r["base_origin_error_max_m"] for r in acc], 0.4, label="body origin")
    c.bar(x + 0.2, [100 * r["base_error_max_m"] for r in acc], 0.4, label="control point")
    c.axhline(100 * summary["settings"]["bars"]["tracking_m"], color="k", ls="--", lw=0.8)
    c.set(xticks=x, xticklabels=[str(r["route"]) for r in acc], xlabel="accepted route",
          ylabel="largest base error [cm]",
          title="tracking in MuJoCo (accepted routes)")  # fmt: skip
    c.tick_params(axis="x", labelsize=6)
    c.legend(fontsize=8)
    for v in PLAN_VERDICTS:
        rs = [r for r in summary["records"] if r["plan"] == v]
        if rs:
            d.scatter([r["slope_deg"] for r in rs],
                      [OUTCOMES.index(r["mujoco"]) if r["mujoco"] else -1 for r in rs],
                      color=colour[v], s=22, alpha=0.7, label=f"plan: {v}")  # fmt: skip
    d.set(yticks=range(-1, len(OUTCOMES)), yticklabels=["not simulated", *OUTCOMES],
          xlabel="side slope of the map [deg]", title="verdicts by slope")  # fmt: skip
    d.axvline(summary["settings"]["bars"]["slope_limit_deg"], color="k", ls=":", lw=0.8)
    d.legend(fontsize=8)
    fig.tight_layout()
    return fig
