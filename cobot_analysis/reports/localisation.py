"""Figures and the results fragment of the localisation stage (docs/methods.md sec. 9, step 6):
paths overlaid in the plane with the goals, per-axis time series after delay and offset removal,
error over time, error distributions, delay cost curves.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from cobot_analysis.plotting import pyplot

_AXIS_UNIT = {"x": "m", "y": "m", "z": "m", "yaw": "rad"}


# ---- figures -----------------------------------------------------------------------------------
# The motion capture is drawn as a black line above the ICP samples (small orange dots), so that
# both stay visible; runs get one panel each (identical runs would hide each other in one).
TRUTH_STYLE = {"color": "k", "lw": 0.8, "zorder": 3}
ICP_STYLE = {"color": "tab:orange", "marker": ".", "ls": "none", "ms": 3.5, "alpha": 0.6, "zorder": 2}


def _scale(a: str) -> tuple[float, str]:
    """Display factor and unit of an error on axis ``a``: positions in mm, yaw in mrad (ticks of a few
    milliradians written in rad, "-0.015", collide on a histogram's x axis)."""
    return (1000.0, "mrad") if a == "yaw" else (1000.0, "mm")


#: the window of the running statistics of ``figure_error_time`` (s, centred): at the 10 Hz of an ICP
#: it holds about 50 poses, enough for a steady median and 10-90 % band, short next to a run of minutes.
ROLLING_WINDOW = 5.0
ROLLING_BAND = (0.10, 0.90)


def rolling_band(t, e, window: float = ROLLING_WINDOW, band: tuple[float, float] = ROLLING_BAND) -> pd.DataFrame:
    """Running median and ``band`` quantiles of the error ``e`` sampled at times ``t`` (s) over a centred
    window of ``window`` seconds (time based: gaps in the ICP do not stretch it); columns t, median, low, high."""
    s = pd.Series(np.asarray(e, float), index=pd.to_timedelta(np.asarray(t, float), unit="s")).sort_index()
    roll = s.rolling(pd.Timedelta(seconds=window), center=True, min_periods=1)
    return pd.DataFrame({"t": s.index.total_seconds(), "median": roll.median().to_numpy(),
                         "low": roll.quantile(band[0]).to_numpy(), "high": roll.quantile(band[1]).to_numpy()})


def figure_paths(results: list[dict]):
    """Both paths in the plane (goal / ICP map frame) with the commanded goals, one panel per run."""
    from cobot_analysis.reports.figures import arrow_handler, square_limits
    from matplotlib.quiver import Quiver

    plt = pyplot()
    n = len(results)
    fig, axes = plt.subplots(1, n, figsize=(4.6 * n, 5), squeeze=False, layout="constrained")
    for ax, r in zip(axes[0], results):
        s = r["samples"]
        al = r["comparison"].alignment
        truth_xy, _ = al.to_icp_frame(np.column_stack([s["truth_x"], s["truth_y"], s["truth_z"]]), s["truth_yaw"].to_numpy())
        ax.plot(s["icp_x"], s["icp_y"], label="ICP (raw, map frame)", **ICP_STYLE)
        ax.plot(truth_xy[:, 0], truth_xy[:, 1], label="motion capture (moved into the map frame)", **TRUTH_STYLE)
        side = square_limits([ax])
        g = r.get("goals")
        if g is not None and len(g):
            L = 0.08 * side
            ax.quiver(g["goal_x"], g["goal_y"], L * np.cos(g["goal_yaw"]), L * np.sin(g["goal_yaw"]), color="tab:blue",
                      angles="xy", scale_units="xy", scale=1, units="inches", width=0.02, zorder=4, label="commanded goals (pose)")
            for _, row in g.iterrows():
                ax.annotate(str(row["goal"]), (row["goal_x"], row["goal_y"]), xytext=(4, 4), textcoords="offset points", fontsize=8,
                            color="tab:blue")
        ax.set_title(f"{r['run']} ({r['row']['map']} map)" if r["row"]["map"] else r["run"])
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncols=len(labels), frameon=False, markerscale=4,
               handler_map={Quiver: arrow_handler()})
    return fig


def figure_timeseries(r: dict):
    """Per-axis time series of the truth (line) and the ICP (dots) after delay and offset removal."""
    plt = pyplot()
    s = r["samples"]
    t = s["t_truth"] - s["t_truth"].iloc[0]
    fig, axes = plt.subplots(4, 1, figsize=(9, 8.5), sharex=True, layout="constrained")
    for ax, a in zip(axes, ("x", "y", "z", "yaw")):
        ax.plot(t, s[f"aligned_{a}"], label="ICP, delay and offset removed (one dot per pose)", **ICP_STYLE)
        ax.plot(t, s[f"truth_{a}"], label="motion capture at the ICP stamps minus the delay", **TRUTH_STYLE)
        ax.set_ylabel(f"{a} ({_AXIS_UNIT[a]})")
    axes[-1].set_xlabel("time (s)")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncols=2, frameon=False, markerscale=4,
               title=f"{r['run']}: delay {r['row']['delay']:.3f} s, alignment {r['row']['alignment']}",
               title_fontproperties={"size": 10})
    return fig


def figure_error_time(results: list[dict]):
    """Position and yaw error over time, one row per run (same scales), as evo draws an error (the raw
    values light, its statistics on top): the running median and 10-90 % band over ``ROLLING_WINDOW``
    seconds (``rolling_band``) and the RMSE of the run (position) / ± RMSE (yaw)."""
    from matplotlib.ticker import MaxNLocator

    plt = pyplot()
    n = len(results)
    lo, hi = (round(100 * q) for q in ROLLING_BAND)
    fig, axes = plt.subplots(n, 2, figsize=(11, 1.9 * n + 0.9), sharex=True, sharey="col", squeeze=False, layout="constrained")
    for (ax_p, ax_y), r in zip(axes, results):
        s = r["samples"]
        t = (s["t_truth"] - s["t_truth"].iloc[0]).to_numpy()
        for ax, e, color, what in ((ax_p, 1000 * s["err_xyz"].to_numpy(), "tab:blue", "3-D position"),
                                   (ax_y, 1000 * s["err_yaw"].to_numpy(), "tab:purple", "yaw")):
            ok = np.isfinite(e)
            b = rolling_band(t[ok], e[ok])
            ax.plot(t, e, ls="none", marker=".", ms=1.5, mew=0, color="0.55", zorder=1, label="error of each ICP pose")
            ax.fill_between(b["t"], b["low"], b["high"], color=color, alpha=0.25, lw=0, zorder=2,
                            label=f"{lo}-{hi} % of the poses within {ROLLING_WINDOW:g} s")
            ax.plot(b["t"], b["median"], lw=1.3, color=color, zorder=3, label=f"running median ({ROLLING_WINDOW:g} s)")
            rmse = np.sqrt(np.nanmean(e ** 2))
            if what == "yaw":
                ax.axhline(rmse, color="k", ls=":", lw=1, zorder=4, label="± yaw RMSE of the run")
                ax.axhline(-rmse, color="k", ls=":", lw=1, zorder=4)
                ax.set_title(f"{r['run']}: yaw error (aligned ICP - motion capture), RMSE {rmse:.1f} mrad", fontsize=9)
            else:
                ax.axhline(rmse, color="k", ls="--", lw=1, zorder=4, label="RMSE of the run")
                ax.set_title(f"{r['run']}: 3-D position error, RMSE {rmse:.1f} mm", fontsize=9)
            ax.yaxis.set_major_locator(MaxNLocator(5, steps=[1, 2, 2.5, 5, 10]))
        ax_p.set_ylabel("position error (mm)")
        ax_y.set_ylabel("yaw error (mrad)")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    handles, labels = [], []
    for ax in axes[0]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles, labels = handles + [h], labels + [lab]
    fig.legend(handles, labels, loc="outside upper center", ncols=3, frameon=False, markerscale=4)
    return fig


def figure_error_distribution(results: list[dict]):
    """Histograms of the signed errors per axis, one row per run (same bins per axis; yaw in mrad)."""
    from matplotlib.ticker import MaxNLocator

    plt = pyplot()
    n = len(results)
    axes_names = ("x", "y", "z", "yaw")
    fig, axes = plt.subplots(n, 4, figsize=(13, 2.1 * n + 0.6), sharex="col", squeeze=False, layout="constrained")
    for j, a in enumerate(axes_names):
        k, unit = _scale(a)
        values = [r["samples"][f"err_{a}"].to_numpy() * k for r in results]
        finite = np.concatenate([v[np.isfinite(v)] for v in values]) if values else np.zeros(0)
        bins = np.histogram_bin_edges(finite, bins=40) if len(finite) else 10
        for i, (r, v) in enumerate(zip(results, values)):
            ax = axes[i][j]
            v = v[np.isfinite(v)]
            ax.hist(v, bins=bins, color="tab:blue", alpha=0.75)
            ax.xaxis.set_major_locator(MaxNLocator(6))
            sd = np.std(v, ddof=1) if len(v) > 1 else np.nan
            ax.set_title(f"{r['run']}: {a}, mean {_num(np.mean(v))}, sd {_num(sd)} {unit} (n = {len(v)})", fontsize=8)
            if i == n - 1:
                ax.set_xlabel(f"error {a}, aligned ICP - motion capture ({unit})")
            ax.set_ylabel("ICP poses (count)")
    return fig


def _num(x: float, digits: int = 1) -> str:
    """``x`` to ``digits`` decimals without a negative zero ("-0.0" -> "0.0")."""
    return f"{round(x, digits) + 0.0:.{digits}f}" if np.isfinite(x) else "-"


def figure_delay(results: list[dict]):
    """The delay cost J(d) / min J, one panel per run, with the estimated delay."""
    plt = pyplot()
    n = len(results)
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 3.4), sharey=True, squeeze=False, layout="constrained")
    for ax, r in zip(axes[0], results):
        grid = r["comparison"].delay.grid
        if len(grid):
            ax.plot(grid[:, 0], grid[:, 1] / grid[:, 1].min(), lw=1.2, color="tab:blue", marker=".", ms=3,
                    label="J(d) / min J on the search grid")
        ax.axvline(r["row"]["delay"], color="k", ls="--", lw=1, label="delay used")
        given = " (given)" if r["row"]["delay_method"] == "given" else ""
        ax.set_title(f"{r['run']}: delay {r['row']['delay']:.3f} s{given}", fontsize=9)
        ax.set_xlabel("delay d (s)")
        ax.set_yscale("log")
    axes[0][0].set_ylabel("cost J(d) / min J (-)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncols=2, frameon=False)
    return fig


# ---- results fragment ----------------------------------------------------------------------------
def _pm(mean, sd, scale=1.0, digits=1):
    if mean is None or not np.isfinite(mean):
        return "-"
    return f"{mean * scale:.{digits}f} ± {sd * scale:.{digits}f}" if np.isfinite(sd) else f"{mean * scale:.{digits}f}"


def _delay_cell(r) -> str:
    if r["delay_method"] == "given":
        return f"{r['delay']:.3f} (given)"
    if r["delay_at_edge"]:
        return f"{r['delay']:.3f} (at the window edge: see the warnings)"
    return _pm(r["delay"], r["delay_sd"], 1, 3)


_ASSOC = {"interpolate": "interpolated there (linear, slerp)", "nearest": "nearest sample within --max-diff"}


def results_markdown(runs: pd.DataFrame, figures: list[str], tol_xy: float, tol_yaw: float) -> str:
    """Markdown fragment: method statement, per-run table, goal accuracy, figure list."""
    al = sorted(set(runs["alignment"]))
    lines = [
        "## Localisation accuracy (LiDAR/ICP vs motion capture)", "",
        f"Generated by `cobot-analysis localisation` from {len(runs)} run(s). Time base: the ICP stamps minus the "
        f"delay, motion capture {' / '.join(_ASSOC[a] for a in sorted(set(runs['association'])))}; delay: "
        f"{'; '.join(sorted(set(runs['delay_method'])))}; offset removal: {', '.join(al)} "
        "(mean = per-axis mean difference, docs/methods.md sec. 9; se3/yaw = Umeyama rigid alignment). "
        "Errors are mean ± sd of the absolute differences after delay and offset removal.", "",
        "| run | map | distance (m) | delay (s) | offset x, y, z (mm) | offset yaw (rad) | error x (mm) | error y (mm) "
        "| error z (mm) | error yaw (rad) | RMSE 3-D (mm) | max 3-D (mm) | drift (mm/m) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for _, r in runs.iterrows():
        lines.append(
            f"| {r['run']} | {r['map'] or '-'} | {r['distance']:.2f} | "
            f"{_delay_cell(r)} | "
            f"{1000 * r['offset_x']:.1f}, {1000 * r['offset_y']:.1f}, {1000 * r['offset_z']:.1f} | {r['offset_yaw']:.4f} | "
            f"{_pm(r['err_x_mean'], r['err_x_sd'], 1000)} | {_pm(r['err_y_mean'], r['err_y_sd'], 1000)} | "
            f"{_pm(r['err_z_mean'], r['err_z_sd'], 1000)} | {_pm(r['err_yaw_mean'], r['err_yaw_sd'], 1, 4)} | "
            f"{1000 * r['ape_rmse']:.1f} | {1000 * r['ape_max']:.1f} | {_pm(r['drift'], r['drift_sd'], 1000, 2)} |")
    if "goals_commanded" in runs and runs["goals_commanded"].notna().any():
        lines += ["", f"Goal accuracy (reached pose from the motion capture in the goal frame; tolerances {tol_xy} m, "
                      f"{tol_yaw} rad):", "",
                  "| run | goals found | within tolerance | error x (mm) | error y (mm) | planar error (mm) | error yaw (rad) |",
                  "|---|---|---|---|---|---|---|"]
        for _, r in runs.iterrows():
            if pd.isna(r.get("goals_commanded")):
                continue
            lines.append(
                f"| {r['run']} | {int(r['goals_found'])}/{int(r['goals_commanded'])} | {int(r['goals_within_tolerance'])} | "
                f"{_pm(r['goal_err_x_mean'], r['goal_err_x_sd'], 1000)} | {_pm(r['goal_err_y_mean'], r['goal_err_y_sd'], 1000)} | "
                f"{_pm(r['goal_err_xy_mean'], r['goal_err_xy_sd'], 1000)} | {_pm(r['goal_err_yaw_mean'], r['goal_err_yaw_sd'], 1, 4)} |")
    warned = runs[runs["warnings"].astype(str).str.len() > 0]
    if len(warned):
        lines += ["", "Warnings:", ""] + [f"- {r['run']}: {w}" for _, r in warned.iterrows() for w in str(r["warnings"]).split(" | ")]
    levelled = runs[~runs["up_truth"].str.startswith("z ") | ~runs["up_icp"].str.startswith("z ")]
    if len(levelled):
        lines += ["", "Frames not z-up (positions, errors and offsets in the frame levelled to the vertical axis, "
                      "docs/methods.md sec. 9): " + ", ".join(f"{r['run']} (truth {r['up_truth']}, ICP {r['up_icp']})"
                                                           for _, r in levelled.iterrows()) + "."]
    if figures:
        lines += ["", "Figures: " + ", ".join(f"`{f}`" for f in figures) + "."]
    return "\n".join(lines) + "\n"
