"""Figures of the analyses with one consistent matplotlib style (Agg backend, PNG + PDF).

- ``paths``: individual paths (thin), means (bold), orientation arrows along the means (in metres,
  visible at the panel size), a figure legend naming every line and arrow; walking conditions in a
  start position x start orientation grid.
- ``boxplots``: distances by group; box = quartiles, line = median, whiskers to the most extreme
  value within 1.5 IQR, outliers shown (docs/methods.md sec. 4); n under each box.
- ``proportions``: shares of categories (configuration patterns, optimal choices) as bars with
  95 % Wilson intervals, panels on one 0-100 % axis.
- ``scatter_r``: a distance against the global distance with Pearson r and n (the p is the statistics
  table's, Holm-corrected).
- ``check_figure``: what a reviewer would refuse in any Figure (axis labels without units, several
  series without a legend naming them).
"""

from __future__ import annotations

import math
import re

import numpy as np

from cobot_analysis.plotting import pyplot, settle_layout

#: one colour per entity, used in every figure.
COLORS = {"walker": "#1f77b4", "subject1": "#d62728", "subject2": "#2ca02c", "table": "#7f7f7f"}
#: how figures name the entities.
NAMES = {"walker": "walker", "subject1": "Subject 1", "subject2": "Subject 2", "table": "table"}
#: start-orientation columns of the walking grid: letter -> header.
WALKING_COLUMNS = {"N": "start facing N (θ0 = π/2)", "E": "start facing E (θ0 = 0)",
                   "S": "start facing S (θ0 = -π/2)", "O": "start facing O (θ0 = π)"}


# ---- path panels ---------------------------------------------------------------------------------
def walking_grid(conditions, codes) -> dict[str, tuple[int, int]] | None:
    """Walking start conditions -> (row, column): rows are start positions by increasing global
    distance, columns the start orientations N, E, S, O. None when a condition is not one of ``codes``
    (the labels that are walking-2020 codes the data agree with, ``design.table_codes``)."""
    from cobot_analysis.design import walking_condition

    conds = {str(c): walking_condition(str(c)) for c in conditions if str(c) in codes}
    if not conds or len(conds) < len(set(map(str, conditions))):
        return None
    distance = {c[1:]: round(w.global_distance, 3) for c, w in conds.items()}
    positions = sorted(distance, key=lambda pos: (distance[pos], pos))
    cols = [o for o in WALKING_COLUMNS if any(w.orientation == o for w in conds.values())]
    return {c: (positions.index(c[1:]), cols.index(w.orientation)) for c, w in conds.items()}


def walking_title(condition: str) -> str:
    """Panel title of a walking condition: its code and global distance."""
    from cobot_analysis.design import walking_condition

    try:
        return f"{condition}, {walking_condition(condition).global_distance:.1f} m from the goal"
    except ValueError:
        return str(condition)


def path_grid(cells: list[tuple[int, int]], size: float):
    """A figure with one square panel (``size`` inches) per cell (row, column); the unused ones hidden."""
    plt = pyplot()
    nrows = max(r for r, _ in cells) + 1
    ncols = max(c for _, c in cells) + 1
    fig, axes = plt.subplots(nrows, ncols, figsize=(size * ncols + 0.6, size * nrows + 1.4), squeeze=False, layout="constrained")
    used = set(cells)
    for r in range(nrows):
        for c in range(ncols):
            axes[r][c].set_visible((r, c) in used)
    return fig, axes


def square_groups(used, keys) -> list[float]:
    """``square_limits`` over the panels of each group (same key: one window size and scale);
    returns the window side of each panel."""
    groups = {}
    for i, k in enumerate(keys):
        groups.setdefault(k, []).append(i)
    sides = [0.0] * len(used)
    for members in groups.values():
        side = square_limits([used[i] for i in members])
        for i in members:
            sides[i] = side
    return sides


def panel_titles(used, cells, titles, col_titles=None, fontsize: float = 8) -> None:
    """Title of each used panel, wrapped to the panel's width (a study's own long condition names would run
    into the next panel's title); the top panel of each column also carries ``col_titles[column]``."""
    import textwrap

    top = {}
    for i, (r, c) in sorted(enumerate(cells[:len(used)]), key=lambda t: t[1]):
        top.setdefault(c, i)
    for i, (ax, title) in enumerate(zip(used, titles)):
        header = col_titles[cells[i][1]] if col_titles and top[cells[i][1]] == i else ""
        spec = ax.get_subplotspec()  # the panel's cell (its position is the one before the layout)
        inches = ax.figure.get_figwidth() / spec.get_gridspec().ncols if spec else ax.get_position().width * ax.figure.get_figwidth()
        chars = max(12, int(0.85 * inches * 72 / (0.6 * fontsize)))  # a character: about 0.6 of the font size wide
        ax.set_title("\n".join(textwrap.fill(t, chars) for t in (header, title) if t), fontsize=fontsize)


def square_limits(axes_list, margin: float = 0.06) -> float:
    """Give the panels one square window around all their data (equal aspect, one scale for the
    group); returns its side (m)."""
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for ax in axes_list:
        ax.relim()
        b = ax.dataLim
        if np.isfinite([b.x0, b.y0, b.x1, b.y1]).all():
            lo, hi = np.minimum(lo, [b.x0, b.y0]), np.maximum(hi, [b.x1, b.y1])
    return window_limits(axes_list, lo, hi, margin=margin)[0]


def window_limits(axes_list, lo, hi, aspect: float = 1.0, margin: float = 0.06) -> tuple[float, float]:
    """Give the panels one window around the box ``lo``..``hi`` (x, y), ``aspect`` = height / width, the
    short side widened about the box's centre so that an equal-aspect panel fills its axes instead of
    shrinking to a strip; tick labels that do not collide. Returns the window's (width, height) (m)."""
    from matplotlib.ticker import MaxNLocator

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        return 1.0, aspect
    width = max((hi[0] - lo[0]) * (1 + 2 * margin), (hi[1] - lo[1]) * (1 + 2 * margin) / aspect) or 1.0
    height = width * aspect
    mid = (lo + hi) / 2
    for ax in axes_list:
        ax.set_xlim(mid[0] - width / 2, mid[0] + width / 2)
        ax.set_ylim(mid[1] - height / 2, mid[1] + height / 2)
        ax.set_aspect("equal", adjustable="box")
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_locator(MaxNLocator(4, steps=[1, 2, 5, 10]))  # tick labels that do not collide
    return width, height


def orientation_arrows(ax, x, y, theta, count: int, length: float, color, label: str | None = None, zorder: float = 4):
    """``count`` arrows of ``length`` metres along a path, pointing along theta (in data units,
    so their size follows the axes). Nothing when theta has NaN."""
    x, y, theta = (np.asarray(v, float) for v in (x, y, theta))
    if len(x) == 0 or not np.isfinite(theta).all():
        return None
    k = np.unique(np.linspace(0, len(x) - 1, count).round().astype(int))
    return ax.quiver(x[k], y[k], length * np.cos(theta[k]), length * np.sin(theta[k]), color=color, angles="xy",
                     scale_units="xy", scale=1, units="inches", width=0.012, headwidth=4, headlength=4.5,
                     headaxislength=4, zorder=zorder, label=label)


def arrow_handler():
    """Legend handler drawing a quiver (orientation arrows) as one arrow in its colour."""
    from matplotlib.legend_handler import HandlerBase
    from matplotlib.patches import FancyArrow

    class HandlerArrow(HandlerBase):
        def create_artists(self, legend, orig, xdescent, ydescent, width, height, fontsize, trans):
            color = orig.get_facecolor()[0] if len(orig.get_facecolor()) else "k"
            return [FancyArrow(-xdescent, height / 2 - ydescent, width, 0, width=height * 0.12, head_width=height * 0.6,
                               head_length=width * 0.3, length_includes_head=True, color=color, transform=trans)]

    return HandlerArrow()


def figure_legend(fig, axes_list, ncols: int = 3, title: str | None = None, group=None, order=None):
    """One legend for the figure, above the panels, with every labelled artist once; ``title`` (the
    figure's title) above its entries (a suptitle would collide with it). ``group(label)``: entries
    with the same key share a legend column (e.g. one column per entity; integer keys sorted, others
    in order of appearance); ``order(label)``: sort key of
    the entries (default: order of appearance)."""
    from matplotlib.lines import Line2D
    from matplotlib.quiver import Quiver

    seen = {}
    for ax in axes_list:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    if not seen:
        if title:
            fig.suptitle(title)
        return None
    labels = sorted(seen, key=order) if order is not None else list(seen)
    handles = [seen[lab] for lab in labels]
    if group is not None:
        cols = {}
        for h, lab in zip(handles, labels):
            cols.setdefault(group(lab), []).append((h, lab))
        if all(isinstance(k, int) for k in cols):
            cols = dict(sorted(cols.items()))
        rows = max(len(v) for v in cols.values())
        blank = Line2D([], [], alpha=0)
        handles = [h for v in cols.values() for h, _ in v + [(blank, "")] * (rows - len(v))]
        labels = [lab for v in cols.values() for _, lab in v + [(blank, "")] * (rows - len(v))]
        ncols = len(cols)
    return fig.legend(handles, labels, loc="outside upper center", ncols=min(ncols, len(handles)), title=title,
                      title_fontproperties={"size": 10}, frameon=False, handler_map={Quiver: arrow_handler()})


#: at most this many named trajectories in a figure: each gets its own colour and legend entry.
FEW_PATHS = 10


def paths(panels: list[dict], ncols: int = 4, arrows: int = 8, title: str = "", *, share: str | bool = False,
          col_titles: list[str] | None = None, size: float = 2.6, names: dict | None = None):
    """One square axis per panel: ``{"title", "lines": [(x, y, entity[, name])], "means": [(x, y, theta, entity[,
    linestyle[, name]])], optional "cell": (row, column)}``; without cells, reading order with ``ncols``
    columns. ``share``: "row" gives each row one scale, True the whole figure, False each panel its own.

    Legend (with ``title`` above it): "<entity>: <names['lines']>" for the thin lines, "<entity>: <name>"
    for each mean (default names['means']), "<entity>: <names['arrows']>" for its arrows (7 % of the
    panel side), and the start of the means; the entity is left out when the figure shows only one.
    A figure of at most ``FEW_PATHS`` named trajectories (e.g. a few recordings of a small study) draws
    each in its own colour, named by the legend, with its start marked: thin faint lines are for crowds."""
    from matplotlib.collections import LineCollection

    names = {"lines": "individual trajectories", "means": "mean", "arrows": "orientation θ of the mean", **(names or {})}
    cells = [tuple(p["cell"]) if p.get("cell") is not None else divmod(i, ncols) for i, p in enumerate(panels)] or [(0, 0)]
    fig, axes = path_grid(cells, size)
    entities = {e for p in panels for _, _, e, *_ in p.get("lines", [])} | {m[3] for p in panels for m in p.get("means", [])}
    line_names = [ln[3] if len(ln) > 3 else None for p in panels for ln in p.get("lines", [])]
    few = 0 < len(line_names) <= FEW_PATHS and None not in line_names
    palette = {n: f"C{k}" for k, n in enumerate(sorted(set(line_names), key=str))} if few else {}

    def who(ent, what):
        return what if len(entities) <= 1 else f"{NAMES.get(ent, ent)}: {what}"

    used = [axes[r][c] for r, c in cells[:len(panels)]]
    panel_titles(used, cells, [p.get("title", "") for p in panels], col_titles)
    for i, (ax, panel) in enumerate(zip(used, panels)):
        by_entity = {}
        for x, y, ent, *name in panel.get("lines", []):
            if few:
                ax.plot(x, y, color=palette[name[0]], lw=1.2, zorder=2, label=who(ent, str(name[0])))
                ok = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
                if len(ok):
                    ax.plot(x[ok[:1]], y[ok[:1]], "o", color="k", ms=4, mfc="white", mec="k", zorder=5, label="start of a path")
                continue
            by_entity.setdefault(ent, []).append(np.column_stack([x, y]))
        for ent, segs in by_entity.items():  # one collection per entity: fast with thousands of paths
            ax.add_collection(LineCollection(segs, colors=COLORS.get(ent, "k"), linewidths=0.5, alpha=0.35, zorder=1,
                                             rasterized=True, label=who(ent, names["lines"])))
        for x, y, th, ent, *style in panel.get("means", []):
            ls = style[0] if style else "-"
            name = style[1] if len(style) > 1 and style[1] else names["means"]
            ax.plot(x, y, color=COLORS.get(ent, "k"), lw=1.8, ls=ls, zorder=3, label=who(ent, name))
            ax.plot(x[:1], y[:1], "o", color="k", ms=4, mfc="white", mec="k", zorder=5,
                    label="start of a path" if few else "start of a mean path")
    keys = [r if share == "row" else (0 if share else -1 - i) for i, (r, _) in enumerate(cells[:len(panels)])]
    sides = square_groups(used, keys)
    for i, (ax, panel) in enumerate(zip(used, panels)):
        length = 0.07 * sides[i]
        if share == "row" and cells[i][1] != min(c for (r, c) in cells[:len(panels)] if r == cells[i][0]):
            ax.tick_params(labelleft=False)  # same y scale as the first panel of the row
        missing = 0
        for x, y, th, ent, *_ in panel.get("means", []):
            if th is None or orientation_arrows(ax, x, y, th, arrows, length, COLORS.get(ent, "k"), who(ent, names["arrows"])) is None:
                missing += 1
        if missing:
            ax.text(0.03, 0.03, "no orientation: no arrows" if missing == len(panel["means"]) else f"{missing} mean(s) without orientation",
                    transform=ax.transAxes, fontsize=7, color="0.3")
    fig.supxlabel("x (m)")
    fig.supylabel("y (m)")
    prefixes = {f"{NAMES.get(e, e)}: ": k for k, e in enumerate(sorted(entities, key=lambda e: list(NAMES).index(e) if e in NAMES else 9))}
    figure_legend(fig, used, ncols=4, title=title,
                  group=None if len(entities) <= 1 else lambda lab: next((k for p, k in prefixes.items() if lab.startswith(p)), len(prefixes)),
                  order=lambda lab: (lab.endswith(names["arrows"]), not lab.endswith(names["lines"]), lab))
    return fig


def boxplots(groups: dict, ylabel: str, title: str = "", colors: list | None = None, xlabel: str = "group"):
    """Box plot per group (label -> values): median, quartiles, whiskers to the most extreme value
    within 1.5 IQR, outliers (docs/methods.md sec. 4); "label (n = ...)" under each box, n the finite values."""
    plt = pyplot()
    labels = list(groups)
    values = [np.asarray(groups[k], float) for k in labels]
    values = [v[np.isfinite(v)] for v in values]
    per = max(0.6, 0.075 * max((len(line) for k in labels for line in str(k).split("\n")), default=0))  # inches per box
    rotate = per * len(labels) > 20  # many boxes: one vertical line per label, 0.3 in apart (no overlap)
    fig, ax = plt.subplots(figsize=(max(4.0, (0.3 if rotate else per) * len(labels) + 1.5), 3.8))
    bp = ax.boxplot(values, whis=1.5, showfliers=True, patch_artist=True, widths=0.6,
                    medianprops={"color": "k", "lw": 1.5}, flierprops={"marker": "o", "ms": 3, "mfc": "none", "alpha": 0.7})
    ticks = [f"{k} (n = {len(v)})".replace("\n", " ") if rotate else f"{k}\n(n = {len(v)})" for k, v in zip(labels, values)]
    ax.set_xticks(range(1, len(labels) + 1), ticks, rotation=90 if rotate else 0, ha="center", fontsize=8)
    for patch, c in zip(bp["boxes"], colors or ["#9ecae1"] * len(labels)):
        patch.set_facecolor(c)
        patch.set_alpha(0.7)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    return fig


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of a proportion k / n (95 % with z = 1.96):
    (p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)."""
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def proportions(charts: dict, title: str = "", chance: dict | None = None):
    """One panel per chart ``{name: {category: count}}``: the share of each category as a bar with its
    95 % Wilson interval, "k / n" under it; panels share the 0-100 % axis; ``chance[name]`` (a share)
    is drawn as a dashed line."""
    plt = pyplot()
    widths = [max(2.2, 0.75 * len(c) + 1.0) for c in charts.values()]
    fig, axes = plt.subplots(1, len(charts), figsize=(sum(widths) + 0.6, 3.6), squeeze=False, sharey=True,
                             gridspec_kw={"width_ratios": widths}, layout="constrained")
    for ax, (name, counts) in zip(axes.ravel(), charts.items()):
        n = sum(counts.values())
        cats = list(counts)
        share = [100 * counts[c] / n if n else math.nan for c in cats]
        ci = [wilson(counts[c], n) for c in cats]
        err = np.array([[s - 100 * lo, 100 * hi - s] for s, (lo, hi) in zip(share, ci)]).T
        ax.bar(range(len(cats)), share, yerr=err, capsize=4, color="#9ecae1", edgecolor="k", lw=0.6,
               error_kw={"lw": 1, "label": "95 % interval (Wilson)"}, label="share")
        if chance and name in chance:
            ax.axhline(100 * chance[name], color="0.3", ls="--", lw=1, label="chance")
        ax.set_xticks(range(len(cats)), [f"{c}\n{counts[c]} / {n}" for c in cats], fontsize=8)
        ax.set_title(f"{name} (n = {n})")
        ax.set_ylim(0, 100)
        ax.set_xlabel("category")
    axes[0][0].set_ylabel("share of the trials or goals (%)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncols=3, title=title or None, frameon=False,
               title_fontproperties={"size": 10})
    return fig


def scatter_r(series: dict, xlabel: str, ylabel: str, title: str = ""):
    """Scatter of (x, y) per entity with the Pearson r and n in the legend (its p, Holm-corrected and with its
    notes, is the statistics table's: not a second, uncorrected one here)."""
    from scipy import stats

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(4.5, 3.5))
    for ent, (x, y) in series.items():
        x, y = np.asarray(x, float), np.asarray(y, float)
        ok = np.isfinite(x) & np.isfinite(y)
        label = ent
        if ok.sum() >= 3 and np.ptp(x[ok]) > 0 and np.ptp(y[ok]) > 0:
            label = f"{ent}: r = {stats.pearsonr(x[ok], y[ok]).statistic:.2f} (n = {ok.sum()})"
        ax.scatter(x[ok], y[ok], s=8, alpha=0.6, color=COLORS.get(ent), label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend()
    return fig


# ---- what a reviewer checks ----------------------------------------------------------------------
#: a unit at the end of an axis label: "x (m)", "time [s]", "ratio (-)".
UNIT = re.compile(r"[(\[][^()\[\]]*[^\s()\[\]][^()\[\]]*[)\]]\s*$")


def _rgba(c) -> tuple:
    from matplotlib.colors import to_rgba_array

    arr = to_rgba_array(c) if c is not None and len(np.atleast_1d(c)) else np.zeros((0, 4))
    return tuple(sorted({tuple(np.round(v, 3)) for v in arr}))


def _style(a) -> tuple:
    """What tells a series apart from another on the page: kind, colours, line style, marker, width."""
    from matplotlib.collections import Collection
    from matplotlib.lines import Line2D

    if isinstance(a, Line2D):
        return ("line", _rgba(a.get_color()), a.get_linestyle(), a.get_marker(), round(a.get_linewidth(), 2),
                _rgba(a.get_markerfacecolor()), a.get_alpha())
    if isinstance(a, Collection):
        return (type(a).__name__, _rgba(a.get_facecolor()), _rgba(a.get_edgecolor()),
                tuple(np.round(np.atleast_1d(a.get_linewidth()), 2)), a.get_alpha())
    return (type(a).__name__, _rgba(a.get_facecolor()), _rgba(a.get_edgecolor()), a.get_linestyle(), a.get_fill())


def _data_artists(ax) -> list:
    """The artists of ``ax`` that draw data (lines with points, non-empty collections, patches, images)."""
    out = [a for a in ax.lines if a.get_visible() and len(a.get_xdata())]
    for c in ax.collections:
        n = getattr(c, "N", None)
        n = len(c.get_offsets()) if n is None and type(c).__name__ == "PathCollection" else n
        if c.get_visible() and (n if n is not None else len(c.get_paths())):
            out.append(c)
    return out + [p for p in ax.patches if p.get_visible()] + [i for i in ax.images if i.get_visible()]


def _numeric(axis) -> bool:
    """Whether an axis shows a numeric scale (numbers as ticks, log scale included), as opposed to
    text ticks naming categories (e.g. one box per group)."""
    from matplotlib.ticker import LogFormatter, ScalarFormatter

    if isinstance(axis.get_major_formatter(), ScalarFormatter | LogFormatter):
        return True
    texts = [re.sub(r"\$[^$]*\$", "", t.get_text()).replace("\u2212", "-").strip() for t in axis.get_ticklabels()]
    try:
        [float(t) for t in texts if t]
    except ValueError:
        return False
    return True


def _axis_label(ax, which: str) -> str:
    """The label of an axis: its own, else a shared sibling's, else the figure's super label."""
    get = (lambda a: a.get_xlabel()) if which == "x" else (lambda a: a.get_ylabel())
    shared = ax.get_shared_x_axes() if which == "x" else ax.get_shared_y_axes()
    for a in [ax, *shared.get_siblings(ax)]:
        if get(a).strip():
            return get(a)
    sup = getattr(ax.figure, "_supxlabel" if which == "x" else "_supylabel", None)
    return sup.get_text() if sup is not None else ""


def overlapping_ticks(ax) -> list[str]:
    """Tick labels of ``ax`` that overlap a neighbour on the page (after drawing), per axis."""
    out = []
    renderer = ax.figure.canvas.get_renderer()
    for which, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
        boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in axis.get_ticklabels()
                 if t.get_visible() and t.get_text().strip()]
        for (a, ba), (b, bb) in zip(boxes, boxes[1:]):
            if ba.overlaps(bb) and ba.intersection(ba, bb) is not None and \
                    ba.intersection(ba, bb).width * ba.intersection(ba, bb).height > 1.0:
                out.append(f"{which} tick labels {a!r} and {b!r} overlap")
                break
    return out


def _texts_in_view(ax) -> list:
    """The texts an axes draws around its panel: titles, axis labels and the tick labels of the ticks in view."""
    out = [ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label]
    for axis, (lo, hi) in ((ax.xaxis, sorted(ax.get_xlim())), (ax.yaxis, sorted(ax.get_ylim()))):
        tol = 1e-9 * (hi - lo)
        out += [t for t, v in zip(axis.get_majorticklabels(), axis.get_majorticklocs()) if lo - tol <= v <= hi + tol]
    return [t for t in out if t.get_visible() and t.get_text().strip()]


def overlapping_panels(fig) -> list[str]:
    """Texts of one axes (title, axis labels, tick labels) that overlap a text of another on the page (after drawing),
    e.g. a panel's title on the tick labels of the panel above it."""
    renderer = fig.canvas.get_renderer()
    boxes = [(i, ax.get_title() or f"axes {i}", t.get_text(), t.get_window_extent(renderer))
             for i, ax in enumerate(fig.axes) if ax.get_visible() for t in _texts_in_view(ax)]
    out, seen = [], set()
    for k, (i, name_i, a, ba) in enumerate(boxes):
        for j, name_j, b, bb in boxes[k + 1:]:
            if i != j and (i, j) not in seen and ba.overlaps(bb):
                inter = ba.intersection(ba, bb)
                if inter is not None and inter.width * inter.height > 1.0:
                    seen.add((i, j))
                    out.append(f"axes {i} ({name_i!r}) and axes {j} ({name_j!r}): texts {a!r} and {b!r} overlap")
    return out


def check_figure(fig) -> list[str]:
    """What a reviewer would refuse in ``fig``, one line each (empty: nothing).

    Every axes that shows data needs an x and a y label; on a numeric axis the label ends with its
    unit in parentheses or brackets ("x (m)", "time [s]"), a categorical axis (text ticks, e.g. one box
    per group) needs non-empty tick labels. Every axes with more than one series (artists that differ
    in kind, colour, line style, marker or width) needs each of them named by a legend of the axes or
    of the figure, except on a categorical axis, whose ticks name its series. Tick labels must not
    overlap their neighbours, nor the texts of one panel those of another (``overlapping_panels``). Pies are exempt.
    The figure is checked as ``plotting.save`` writes it: laid out until its axes stop moving."""
    from matplotlib.patches import Wedge

    settle_layout(fig)
    fig.canvas.draw()
    legend_texts = {t.get_text() for lg in [*fig.legends, *(a.get_legend() for a in fig.axes)] if lg is not None
                    for t in lg.get_texts() if t.get_text().strip()}
    all_artists = [a for ax in fig.axes for a in _data_artists(ax)]
    named = {}
    for a in all_artists:
        if a.get_label() in legend_texts:
            named.setdefault(_style(a), a.get_label())
    problems = []
    for i, ax in enumerate(fig.axes):
        data = _data_artists(ax)
        if not ax.get_visible() or not data or all(isinstance(a, Wedge) for a in data):
            continue
        where = f"axes {i} ({ax.get_title() or ax.get_title('left') or 'untitled'!r})"
        categorical = False
        for which in ("x", "y"):
            axis = ax.xaxis if which == "x" else ax.yaxis
            ticks = axis.get_ticklabels()
            label = _axis_label(ax, which)
            numeric = _numeric(axis)
            categorical |= not numeric
            if not label.strip():
                problems.append(f"{where}: no {which} label")
            elif numeric and not UNIT.search(label):
                problems.append(f"{where}: {which} label {label!r} gives no unit in parentheses or brackets")
            if not numeric and any(not t.get_text().strip() for t in ticks):
                problems.append(f"{where}: empty {which} tick label on a categorical axis")
        problems += [f"{where}: {p}" for p in overlapping_ticks(ax)]
        if categorical:
            continue
        styles = {_style(a) for a in data}
        if len(styles) > 1:
            for st in styles:
                if st not in named:
                    kind = next(a for a in data if _style(a) == st)
                    problems.append(f"{where}: {len(styles)} series, one ({type(kind).__name__} {kind.get_label()!r}) "
                                    "is named by no legend")
    return problems + overlapping_panels(fig)
