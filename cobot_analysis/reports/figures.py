"""Figures of the analyses with one consistent matplotlib style (Agg backend, PNG + PDF).

- ``paths``: individual paths (thin), the mean (bold) and orientation arrows along the mean.
- ``boxplots``: distances by group; box = quartiles, line = median, whiskers to the most extreme
  value within 1.5 IQR, outliers shown (docs/methods.md sec. 4).
- ``pies``: shares of categories (configuration patterns, optimal choices).
- ``scatter_r``: a distance against the global distance with Pearson r and its p.
"""

from __future__ import annotations

import math

import numpy as np

#: one colour per entity, used in every figure.
COLORS = {"walker": "#1f77b4", "subject1": "#d62728", "subject2": "#2ca02c", "table": "#7f7f7f"}
STYLE = {
    "figure.dpi": 100, "font.size": 9, "axes.titlesize": 9, "axes.labelsize": 9, "legend.fontsize": 8,
    "axes.spines.top": False, "axes.spines.right": False, "axes.grid": True, "grid.alpha": 0.3,
    "savefig.bbox": "tight",
}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update(STYLE)
    return plt


def paths(panels: list[dict], ncols: int = 4, arrows: int = 8, title: str = ""):
    """One axis per panel: ``{"title", "lines": [(x, y, entity)], "means": [(x, y, theta, entity[, linestyle])]}``."""
    from matplotlib.collections import LineCollection

    plt = _plt()
    nrows = max(1, math.ceil(len(panels) / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(2.6 * ncols, 2.6 * nrows), squeeze=False, sharex=True, sharey=True)
    for ax, panel in zip(axes.ravel(), panels):
        lines = panel.get("lines", [])
        if lines:  # one collection per panel: fast to draw even with thousands of paths
            segs = [np.column_stack([x, y]) for x, y, _ in lines]
            ax.add_collection(LineCollection(segs, colors=[COLORS.get(e, "k") for _, _, e in lines], linewidths=0.5, alpha=0.35,
                                             rasterized=True))  # thousands of thin paths: a bitmap inside the PDF
            ax.autoscale_view()
        for x, y, th, ent, *style in panel.get("means", []):
            ls = style[0] if style else "-"
            ax.plot(x, y, color=COLORS.get(ent, "k"), lw=2.0, ls=ls, label=ent if ls == "-" else None)
            if th is not None and np.isfinite(th).all():
                idx = np.linspace(0, len(x) - 1, arrows).astype(int)
                ax.quiver(x[idx], y[idx], np.cos(th[idx]), np.sin(th[idx]), color=COLORS.get(ent, "k"),
                          angles="xy", scale=18, width=0.006)
        ax.set_title(panel.get("title", ""))
        ax.set_aspect("equal", adjustable="box")
    for ax in axes.ravel()[len(panels):]:
        ax.set_visible(False)
    handles, labels = axes.ravel()[0].get_legend_handles_labels()
    if handles:
        uniq = dict(zip(labels, handles))
        fig.legend(uniq.values(), uniq.keys(), loc="upper right")
    if title:
        fig.suptitle(title)
    fig.supxlabel("x (m)")
    fig.supylabel("y (m)")
    return fig


def boxplots(groups: dict, ylabel: str, title: str = "", colors: list | None = None):
    """Box plot per group (label -> values)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(max(4.0, 0.6 * len(groups) + 2), 3.5))
    labels = list(groups)
    bp = ax.boxplot([np.asarray(groups[k], float) for k in labels], whis=1.5, showfliers=True, patch_artist=True)
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=30 if len(labels) > 6 else 0)
    for patch, c in zip(bp["boxes"], colors or ["#9ecae1"] * len(labels)):
        patch.set_facecolor(c)
        patch.set_alpha(0.7)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    return fig


def pies(charts: dict, title: str = ""):
    """One pie per chart: ``{name: {category: count}}``."""
    plt = _plt()
    fig, axes = plt.subplots(1, len(charts), figsize=(3.2 * len(charts), 3.4), squeeze=False)
    for ax, (name, counts) in zip(axes.ravel(), charts.items()):
        vals = [v for v in counts.values() if v > 0]
        labels = [k for k, v in counts.items() if v > 0]
        if vals:
            ax.pie(vals, labels=labels, autopct=lambda p: f"{p:.0f} %", startangle=90, textprops={"fontsize": 8})
        ax.set_title(f"{name} (n = {sum(vals)})")
    if title:
        fig.suptitle(title)
    return fig


def scatter_r(series: dict, xlabel: str, ylabel: str, title: str = ""):
    """Scatter of (x, y) per entity with the Pearson r and p in the legend."""
    from scipy import stats

    plt = _plt()
    fig, ax = plt.subplots(figsize=(4.5, 3.5))
    for ent, (x, y) in series.items():
        x, y = np.asarray(x, float), np.asarray(y, float)
        ok = np.isfinite(x) & np.isfinite(y)
        label = ent
        if ok.sum() >= 3 and np.ptp(x[ok]) > 0 and np.ptp(y[ok]) > 0:
            r, p = stats.pearsonr(x[ok], y[ok])
            label = f"{ent}: r = {r:.2f}, p = {p:.2g}"
        ax.scatter(x[ok], y[ok], s=8, alpha=0.6, color=COLORS.get(ent), label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend()
    return fig
