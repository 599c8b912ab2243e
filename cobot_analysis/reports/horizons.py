"""The horizon sweep's results fragment and figure (docs/methods.md sec. 7.2; the sweep is
``models.prediction.horizons``)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from cobot_analysis.models.prediction.horizons import BASELINE, WHOLE, wins_from
from cobot_analysis.plotting import PREDICTOR_COLOURS


def horizon_markdown(summary: pd.DataFrame, inference: pd.DataFrame) -> list[str]:
    """The results fragment: delta_xy (FDE) per horizon and predictor, the horizon from which each beats
    constant velocity, and the goal inference against the walked fraction."""
    lines = ["## Prediction error against the horizon (docs/methods.md sec. 7.2)", ""]
    fmt = lambda h: "whole path" if h == WHOLE else f"{h}"  # noqa: E731
    for study, g in summary.groupby("study", sort=True):
        preds = list(dict.fromkeys(g["predictor"]))
        hs = sorted(set(g["horizon"]), key=lambda h: np.inf if h == WHOLE else h)
        lines += [f"**{study}** ({int(g['n'].max())} trajectories), mean delta_xy (FDE) in m:", "",
                  "| horizon (samples) | " + " | ".join(preds) + " |", "|---" * (len(preds) + 1) + "|"]
        for h in hs:
            cells = []
            for p in preds:
                r = g[(g["predictor"] == p) & (g["horizon"] == h)]
                cells.append(f"{r['delta_xy'].iloc[0]:.3f} ({r['fde'].iloc[0]:.3f})" if len(r) else "")
            lines.append(f"| {fmt(h)} | " + " | ".join(cells) + " |")
        lines.append("")
        if BASELINE in preds:
            for p in [p for p in preds if p != BASELINE]:
                w = wins_from(summary, study, p)
                whole = g[(g["predictor"] == p) & (g["horizon"] == WHOLE)]
                ratio = f"; over the whole remaining path {1 / whole['ratio_cv'].iloc[0]:.2f}x better than cv" \
                    if len(whole) and whole["ratio_cv"].iloc[0] < 1 else \
                    (f"; over the whole remaining path {whole['ratio_cv'].iloc[0]:.2f}x cv's error" if len(whole) else "")
                beats = ("never beats cv at every longer horizon" if w is None else "beats cv over the whole path only" if w == WHOLE
                         else f"beats cv from {w} samples ahead on")
                lines.append(f"- {p}: {beats}{ratio}")
            lines.append("")
    if len(summary):
        lines += ["Figure: `horizons.png` in the stage's directory (delta_xy and FDE against the horizon, one column per study, "
                  "the whole remaining path at the right end).", ""]
    if len(inference):
        bins = np.linspace(0, 1, 6)
        inference = inference.assign(part=pd.cut(inference["walked"], bins, include_lowest=True))
        t = inference.groupby("part", observed=True).agg(p_true=("p_true", "mean"), correct=("correct", "mean"), n=("k", "size"))
        lines += ["Goal inference (goal-inferred, candidate goals of the study), by fraction of the path walked:", "",
                  "| walked | mean p(true goal) | most probable = true | windows |", "|---|---|---|---|"]
        lines += [f"| {max(iv.left, 0.0):.0%}-{iv.right:.0%} | {r.p_true:.2f} | {r.correct:.0%} | {int(r.n)} |" for iv, r in t.iterrows()]
        a = inference_at(inference)
        lines += ["", "Per trajectory, at the first window past each fraction of its path:", "",
                  "| walked | trajectories whose most probable goal is the true one | mean p(true goal) |", "|---|---|---|"]
        lines += [f"| {f:.0%} | {int(r.correct)}/{int(r.n)} ({r.correct / r.n:.0%}) | {r.p_true:.2f} |" for f, r in a.iterrows()]
        lines.append("")
    return lines


def inference_at(inference: pd.DataFrame, fractions=(0.25, 0.5, 0.75, 0.99)) -> pd.DataFrame:
    """Per fraction f of the path walked: over the trajectories, how many have their most probable goal the true
    one at their first window with ``walked >= f`` (``correct``, of ``n``), and the mean p(true goal) there."""
    rows = []
    for f in fractions:
        first = inference[inference["walked"] >= f].sort_values("k").groupby(["study", "trial", "entity"], observed=True).head(1)
        rows.append({"walked": f, "correct": int(first["correct"].sum()), "n": len(first), "p_true": float(first["p_true"].mean())})
    return pd.DataFrame(rows).set_index("walked")


def horizon_figure(summary: pd.DataFrame):
    """delta_xy and FDE against the horizon, one column per study (the whole path at the right end)."""
    import matplotlib.pyplot as plt

    studies = sorted(set(summary["study"]))
    fig, axes = plt.subplots(2, len(studies), figsize=(5.5 * len(studies), 7), squeeze=False)
    for j, study in enumerate(studies):
        g = summary[summary["study"] == study]
        hs = sorted(set(g["horizon"]) - {WHOLE})
        x_whole = (hs[-1] * 2) if hs else 1
        for row, metric in enumerate(("delta_xy", "fde")):
            ax = axes[row, j]
            for p, gp in g.groupby("predictor", sort=True):
                gp = gp.assign(x=gp["horizon"].where(gp["horizon"] != WHOLE, x_whole)).sort_values("x")
                ax.plot(gp["x"], gp[metric], "o-", label=p, color=PREDICTOR_COLOURS.get(p))
            ax.set_xscale("log")
            ax.set_xticks(hs + [x_whole], [str(h) for h in hs] + ["whole"])
            ax.set_xlabel("horizon (samples ahead)")
            ax.set_ylabel(f"{metric} (m)")
            ax.set_title(f"{study}: {metric}")
            ax.grid(alpha=0.3)
        axes[0, j].legend()
    fig.tight_layout()
    return fig
