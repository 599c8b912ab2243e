"""Prediction results beside the papers and across conventions (docs/methods.md sec. 7, 11).

- ``paper_rows``: at (N0, N_OC) = (50, 100), the papers' delta_xy, delta_theta, d_pred (mean +- sd
  over trajectories) beside this run's OC, CV and CTRV values on the same study;
- ``conventions_table``: ONE table "OC vs CV vs CTRV under both conventions" from the outputs of a
  ``published`` and a ``continuous`` predict stage (their ``prediction_summary`` and
  ``prediction_comparison`` tables).

Mean and sd over trajectories, the sd with each convention's ``sd_ddof``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.conventions import NAMES, Convention

PAPER_SETTING = (50, 100)


@dataclass(frozen=True)
class PaperResult:
    """A published prediction result: (mean, sd) per metric over the paper's trajectories."""

    study: str
    entity: str
    kind: str  # the trajectories of this workspace it is compared with: "trial" or "mean"
    source: str
    values: dict[str, tuple[float, float]]
    note: str
    #: the differences to the paper, each measured by switching one element (published convention,
    #: (50, 100), every trajectory of the study; 2026-11-22)
    accounts: tuple[str, ...] = ()


PAPER = (
    PaperResult("walking-2020", "walker", "trial", "RA-L 2021 (thesis ch. 2)",
                {"delta_xy": (0.08, 0.02), "delta_theta": (0.28, 0.01), "d_pred": (0.48, 0.17)},
                "400 subject trajectories of walking-2020",
                ("delta_xy depends mostly on which orientations are tracked: OC 0.059 +- 0.061 m with the 100 unflagged "
                 "ones (default `--orientation auto`), 0.109 +- 0.080 m tracking all 275 measured ones (`--orientation "
                 "track`), 0.115 +- 0.075 m tracking the authors' files as they are (zeros where the orientation is "
                 "missing, all 400); the paper's 0.08 lies between.",
                 "delta_theta: 0.490 +- 0.190 rad on the 100 tracked, 0.549 +- 0.196 on the 275 measured, 0.378 +- 0.302 "
                 "on all 400 with the zero rows (their zero errors pull it down); no element switched gives the paper's "
                 "0.28 +- 0.01, and CV has the same delta_theta as OC (0.490): the measured theta itself moves that much.",
                 "d_pred is the time the 50-sample horizon spans: 0.314 m here, where 500 time-normalised samples cover an "
                 "assumed 1 m/s walk (0.37 s per 50 samples); resampled at 100 Hz (`--t-oc 0.01`, 0.5 s) it is 0.437 m "
                 "(CV 0.497), the paper's 0.48.",
                 "The rest start costs 5 mm: 0.054 +- 0.058 m with the start velocity estimated instead (all else published).")),
    PaperResult("pair-carriage-2022", "table", "mean", "Humanoids 2022 (thesis ch. 5)",
                {"delta_xy": (0.04, 0.02)},
                "the paper predicts the individual trials, not published; here the pair-carriage-2022 table means",
                ("The rest start costs 10 mm: 0.057 +- 0.021 m with the start velocity estimated; Euler vs the "
                 "midpoint step 1 mm (0.066), the weights 1 mm (0.068 with table-2022); the remaining 2-3 cm are not "
                 "explained by any element switched here (not measured: the paper's individual trials, unpublished, and "
                 "its distance script, arc-length resampled paths from the first future sample cut where either ends).",)),
)
METRIC_UNITS = {"delta_xy": "m", "delta_theta": "rad", "d_pred": "m"}


def _pm(mean: float, sd: float, digits: int = 3) -> str:
    if mean is None or not np.isfinite(mean):
        return "n/a"
    return f"{mean:.{digits}f} +- {sd:.{digits}f}" if np.isfinite(sd) else f"{mean:.{digits}f}"


def paper_rows(metrics: pd.DataFrame, convention: Convention) -> list[str]:
    """Markdown table: each paper result whose study and entity this run holds, beside this run's
    mean +- sd at (50, 100) per predictor (sd = sqrt(sum (v - mean)^2 / (n - sd_ddof)))."""
    n0, n_oc = PAPER_SETTING
    at = metrics[(metrics["n0"] == n0) & (metrics["n_oc"] == n_oc)]
    ddof = convention.comparison.sd_ddof
    lines, accounts, verdict = [], [], []
    for paper in PAPER:
        sel = at[(at["study"] == paper.study) & (at["entity"] == paper.entity) & (at["kind"] == paper.kind)]
        if sel.empty:
            continue
        preds = [p for p in ("oc", "cv", "ctrv") if p in set(sel["predictor"])]
        if not lines:
            lines = [f"### The papers' results beside ours, (N0, N_OC) = ({n0}, {n_oc}), {convention.name} convention", "",
                     "| study | metric | paper | " + " | ".join(f"{p} (ours)" for p in preds) + " | trajectories | paper's source |",
                     "|---|---|---|" + "---|" * len(preds) + "---|---|"]
        for metric, (mean, sd) in paper.values.items():
            cells = []
            for p in preds:
                v = sel.loc[sel["predictor"] == p, metric].dropna()
                cells.append(_pm(v.mean(), v.std(ddof=ddof) if len(v) > ddof else float("nan")) if len(v) else "n/a")
            n = int(sel.loc[sel["predictor"] == preds[0], metric].notna().sum())
            lines.append(f"| {paper.study} {paper.entity} | {metric} ({METRIC_UNITS[metric]}) | {mean:.2f} +- {sd:.2f} | "
                         + " | ".join(cells) + f" | {n} | {paper.source}: {paper.note} |")
        accounts += [f"- {paper.study}: {a}" for a in paper.accounts]
        if {"oc", "cv"} <= set(preds):
            oc, cv = (sel.loc[sel["predictor"] == p, "delta_xy"].mean() for p in ("oc", "cv"))
            verdict.append(f"{paper.study} {paper.entity}: the OC predictor {'loses to' if oc > cv else 'beats'} constant "
                           f"velocity ({oc:.3f} vs {cv:.3f} m).")
    if lines:
        lines += ["", "delta_theta is over the trajectories whose orientation was tracked (the others have none); "
                  "sd: " + ("population (ddof 0)" if ddof == 0 else "sample (ddof 1)") + ". " + " ".join(verdict)]
        if accounts:
            lines += ["", "The differences to the papers, each measured by switching one element of the published "
                      "convention or of the input at (50, 100) on every trajectory of the study (2026-11-22; OC mean +- "
                      "population sd):", "", *accounts]
    return lines


# ---- both conventions -------------------------------------------------------------------------
def _summary(stage_dir: Path) -> tuple[str, pd.DataFrame, pd.DataFrame]:
    from cobot_analysis.models.prediction.sweep import PREDICTION_COMPARISON, PREDICTION_SUMMARY
    from cobot_analysis.schema import read_table

    s = read_table(Path(stage_dir) / "prediction_summary.parquet", PREDICTION_SUMMARY)
    c = read_table(Path(stage_dir) / "prediction_comparison.parquet", PREDICTION_COMPARISON)
    names = set(s["convention"])
    if len(names) != 1:
        from cobot_analysis.errors import InputError

        raise InputError(f"prediction_summary holds {len(names)} conventions", path=Path(stage_dir) / "prediction_summary.parquet",
                         remedy="re-run the predict stage")
    return names.pop(), s, c


def conventions_table(stage_dirs: list[Path]) -> pd.DataFrame:
    """ONE table, OC vs CV vs CTRV under both conventions, from the outputs of two predict stages
    (one ``published``, one ``continuous``): per setting and predictor and per convention, the
    mean +- sd over trajectories of delta_xy, delta_theta, d_pred and, for a baseline, the share of
    trajectories where the OC predictor has the smaller delta_xy (``prediction_comparison``)."""
    rows = []
    for d in stage_dirs:
        conv, summary, comparison = _summary(d)
        allc = comparison[comparison["group"] == "all"].set_index(["n0", "n_oc", "baseline"])
        for (n0, n_oc, pred), g in summary.groupby(["n0", "n_oc", "predictor"], sort=True):
            cell = g.set_index("metric")
            row = {"n0": int(n0), "n_oc": int(n_oc), "predictor": pred, "convention": conv,
                   "n": int(cell.loc["delta_xy", "n"])}
            for m in METRIC_UNITS:
                row[f"{m}_mean"], row[f"{m}_sd"] = float(cell.loc[m, "mean"]), float(cell.loc[m, "sd"])
            key = (n0, n_oc, pred)
            row["oc_better"] = float(allc.loc[key, "oc_wins"]) if key in allc.index else float("nan")
            rows.append(row)
    df = pd.DataFrame(rows)
    order = {n: i for i, n in enumerate(NAMES)}
    return df.sort_values(["n0", "n_oc", "predictor", "convention"], key=lambda c: c.map(order) if c.name == "convention" else c,
                          ignore_index=True)


def conventions_markdown(table: pd.DataFrame) -> list[str]:
    """``conventions_table`` as a markdown table: one row per setting and predictor, the two
    conventions side by side."""
    convs = [c for c in NAMES if c in set(table["convention"])]
    head = ["N0", "N_OC", "predictor"]
    for m, unit in METRIC_UNITS.items():
        head += [f"{m} ({unit}) {c}" for c in convs]
    head += [f"OC better ({c})" for c in convs]
    lines = ["### OC vs CV vs CTRV under both conventions (mean +- sd over trajectories)", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for (n0, n_oc, pred), g in table.groupby(["n0", "n_oc", "predictor"], sort=True):
        g = g.set_index("convention")
        cells = [str(n0), str(n_oc), pred]
        for m in METRIC_UNITS:
            cells += [_pm(g.loc[c, f"{m}_mean"], g.loc[c, f"{m}_sd"]) if c in g.index else "n/a" for c in convs]
        for c in convs:
            v = g.loc[c, "oc_better"] if c in g.index else float("nan")
            cells.append("-" if pred == "oc" else ("n/a" if math.isnan(v) else f"{100 * v:.0f} %"))
        lines.append("| " + " | ".join(cells) + " |")
    ns = table.drop_duplicates("convention").set_index("convention")["n"]
    lines += ["", "Trajectories: " + ", ".join(f"{c} {int(ns[c])}" for c in convs)
              + ". 'OC better': share of trajectories where the OC predictor's delta_xy is smaller than this "
              "baseline's (same windows). The baselines extrapolate per sample: the same under both conventions, "
              "except for the sd (population under published, sample under continuous)."]
    return lines


# ---- the predict stage's figures and results fragment ------------------------------------------
def figure_setting(config) -> tuple[int, int]:
    return (50, 100) if (50, 100) in config.settings else config.settings[0]


def example_trajectory(metrics, trajs, config):
    """The trajectory with the median delta_xy of the first predictor at the figure setting."""
    import numpy as np

    n0, n_oc = figure_setting(config)
    m = metrics[(metrics["n0"] == n0) & (metrics["n_oc"] == n_oc) & (metrics["predictor"] == config.predictors[0])]
    m = m[np.isfinite(m["delta_xy"])].sort_values("delta_xy")
    row = m.iloc[len(m) // 2]
    return next(t for t in trajs if (t.study, t.trial, t.entity) == (row["study"], row["trial"], row["entity"]))


def figures(metrics, traj, config) -> dict:
    """The stage's figures by file stem: every prediction of one trajectory (``prediction_overlay``, one window of
    the figure's aspect around the path and the predictions), the predictions at six samples k (``prediction_at_k``,
    each panel zoomed on its window) and the error against the global distance (``prediction_error_vs_distance``)."""
    import numpy as np

    from cobot_analysis.plotting import pyplot
    from matplotlib.collections import LineCollection
    from matplotlib.legend_handler import HandlerTuple

    from cobot_analysis.models.prediction.predictor import make_predictor
    from cobot_analysis.models.prediction.sweep import predictor_options

    plt = pyplot()
    n0, n_oc = figure_setting(config)
    preds = {}
    for name in config.predictors:
        options = predictor_options(name, traj, config)
        preds[name] = make_predictor(name, n0, n_oc, traj.dt, convention=config.convention, **options).predict_offline(traj.seen)
    xy = traj.poses[:, :2]
    from cobot_analysis.plotting import PREDICTOR_COLOURS as colours
    from cobot_analysis.reports.figures import window_limits
    conv = config.convention
    span = np.nanmax(xy, axis=0) - np.nanmin(xy, axis=0)
    aspect = float(np.clip(span[1] / max(span[0], 1e-9), 0.3, 1.5))  # of the equal-aspect path panels
    out = {}

    def box(*arrays):
        """(lo, hi) over the finite points of ``arrays`` (each n x 2)."""
        pts = np.concatenate([np.asarray(a, float).reshape(-1, 2) for a in arrays])
        pts = pts[np.isfinite(pts).all(axis=1)]
        return pts.min(axis=0), pts.max(axis=0)

    # the predictors' panels compared side by side: one scale (shared axes); each 4.2 in column holds an equal-aspect
    # panel about 3.75 in wide (its tick labels beside it), so 3.75 x aspect in high (4.2 x aspect left 0.5-0.7 in blank
    # above and below the panels)
    fig, axes = plt.subplots(1, len(preds), figsize=(4.2 * len(preds), 3.75 * aspect + 1.2), squeeze=False, sharex=True,
                             sharey=True, layout="constrained")
    for ax, (name, P) in zip(axes[0], preds.items()):
        ok = np.isfinite(P[:, 0, 0])
        ax.plot(*xy.T, color="0.6", lw=2.5, label="recorded", zorder=1)
        ax.add_collection(LineCollection(P[ok, :, :2], colors=colours[name], linewidths=0.5, alpha=0.4, zorder=2,
                                         label=f"{name}: prediction from each k"))
        ax.set_title(f"{name}: all {ok.sum()} predictions")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="best", fontsize=7)
    # one window of the figure's aspect (a path much longer than wide fills its panels, not a strip), shared
    window_limits(axes[0], *box(xy, *(P[..., :2] for P in preds.values())), aspect=aspect)
    step = f"OC nodes of {conv.prediction.node_dt:g} s" if conv.prediction.node_dt else f"T_OC = {traj.dt * 1000:.1f} ms"
    fig.suptitle(f"{traj.label}, N0 = {n0}, N_OC = {n_oc}, {step}, {conv.name} convention")
    out["prediction_overlay"] = fig

    # six windows from the first (k = N0 - 1), the last half a horizon before the end, or the first alone when a
    # recording holds less than that after N0
    ks = np.unique(np.linspace(n0 - 1, max(n0 - 1, len(xy) - 1 - (n_oc - n0) // 2), 6).astype(int))
    fig, axes = plt.subplots(2, 3, figsize=(12, 9.0), squeeze=False, layout="constrained")
    for ax in axes.ravel()[len(ks):]:
        ax.set_visible(False)
    for ax, k in zip(axes.ravel(), ks):
        past, future = xy[k - n0 + 1: k + 1], xy[k: k + n_oc - n0 + 1]
        ax.plot(*xy.T, color="0.8", lw=1, label="recorded path")
        ax.plot(*past.T, color="k", lw=2.5, label="measured past (N0 samples)")
        ax.plot(*future.T, color="k", ls="--", lw=1, label="recorded future (N_OC - N0 samples)")
        for name, P in reversed(preds.items()):  # the first predictor (oc) drawn on top
            ax.plot(*P[k - n0 + 1][:, :2].T, color=colours[name], lw=1.5, label=f"{name} prediction")
        ax.set_title(f"k = {k} ({100 * k / (len(xy) - 1):.0f} %)")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        # zoomed on the window (its past, recorded future and predictions), square: the predictions told apart
        window_limits([ax], *box(past, future, *(P[k - n0 + 1][:, :2] for P in preds.values())))
    handles, labels = axes[0, 0].get_legend_handles_labels()
    order = [*range(3), *reversed(range(3, len(labels)))]  # the predictors in the order given
    fig.legend([handles[i] for i in order], [labels[i] for i in order], loc="outside lower center", ncol=3 + len(preds),
               fontsize=8)
    fig.suptitle(f"Prediction at k: {traj.label}, N0 = {n0}, N_OC = {n_oc}, {conv.name} convention")
    out["prediction_at_k"] = fig

    m = metrics[(metrics["n0"] == n0) & (metrics["n_oc"] == n_oc)]
    orientations = sorted(m["start_orientation"].replace("", "all").unique())
    fig, axes = plt.subplots(1, len(preds), figsize=(4.2 * len(preds), 4.2), squeeze=False, sharey=True, layout="constrained")
    series = {}
    for ax, name in zip(axes[0], preds):
        mp = m[m["predictor"] == name]
        for i, (orient, g) in enumerate(mp.groupby(mp["start_orientation"].replace("", "all"), sort=True)):
            c = g.groupby("condition").agg(d=("global_distance", "mean"), mean=("delta_xy", "mean"),
                                           lo=("delta_xy", "min"), hi=("delta_xy", "max")).sort_values("d")
            colour = f"C{orientations.index(orient)}"
            line, = ax.plot(c["d"], c["mean"], marker="o", ms=3, color=colour, label=orient)
            band = ax.fill_between(c["d"], c["lo"], c["hi"], color=colour, alpha=0.15, label=orient)
            series.setdefault(orient, (line, band))
        ax.set_title(name)
        ax.set_xlabel("global distance (m)")
    axes[0, 0].set_ylabel("delta_xy per condition, mean and min-max (m)")
    fig.legend(list(series.values()), list(series), handler_map={tuple: HandlerTuple(ndivide=1)}, title="start orientation",
               loc="outside right center", fontsize=8)
    fig.suptitle(f"Prediction error vs global distance, N0 = {n0}, N_OC = {n_oc}, {conv.name} convention")
    out["prediction_error_vs_distance"] = fig
    return out


def _fmt(v, digits=3) -> str:
    import math

    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"


def _p(v) -> str:
    import math

    return "n/a" if math.isnan(v) else ("< 0.001" if v < 1e-3 else f"{v:.3f}")


def travel_angle(trajectories) -> dict[str, float]:
    """Per entity, the median over its trajectories (orientation tracked) of their median |gamma|, gamma = wrap(theta -
    direction of travel), the direction of travel atan2 of the positions' central differences (rad): 0 for a walker
    facing where it goes, pi / 2 for a table carried sideways."""
    import numpy as np

    from cobot_analysis.angles import wrap

    per = {}
    for t in trajectories:
        if not t.track_theta or not np.isfinite(t.poses[:, 2]).any():
            continue
        dx, dy = (np.gradient(t.poses[:, i]) for i in (0, 1))
        moving = np.hypot(dx, dy) > 0
        gamma = np.abs(wrap(t.poses[moving, 2] - np.arctan2(dy[moving], dx[moving])))
        if np.isfinite(gamma).any():
            per.setdefault(t.entity, []).append(float(np.nanmedian(gamma)))
    return {e: float(np.median(v)) for e, v in sorted(per.items())}


def horizon_cut_lines(first: pd.DataFrame) -> list[str]:
    """Where a setting's horizon is longer than most recordings hold after N0 (``first``: one metrics row per
    trajectory and setting): a line saying how few windows have their whole horizon inside the recording, since
    delta_xy and delta_theta then compare only the samples that remain (docs/methods.md sec. 7)."""
    out = []
    for (n0, n_oc), g in first.groupby(["n0", "n_oc"], sort=True):
        used, full = int(g["n_used"].sum()), int(g["n_full"].sum())
        if used and full < used / 2:
            after = g["n_samples"] - n0
            out.append(f"(N0, N_OC) = ({n0}, {n_oc}): {full} of {used} windows have their whole horizon ({n_oc - n0} samples) "
                       f"inside the recording, which holds {after.min()}-{after.max()} samples after N0: delta_xy and "
                       "delta_theta compare the samples that remain (fewer the later the window), ADE and FDE only the "
                       "whole horizons. Shorten N_OC (--settings) to compare the horizon itself.")
    return [""] + out if out else []


def results_fragment(metrics, summary, comparison, config, example, unpredictable=(), stage_name: str = "predict",
                     trajectories=()) -> str:
    """Markdown fragment of the stage (assembled into docs/results.md); ``trajectories`` (those predicted) give the
    angle between heading and direction of travel that the goal predictors' delta_theta holds (``travel_angle``)."""

    traj = metrics.drop_duplicates(["study", "trial", "entity"])
    studies = ", ".join(f"{s} ({n})" for s, n in traj.groupby("study").size().items())
    no_theta = int((~traj["orientation"]).sum())
    untracked = int((traj["orientation"] & ~traj["theta_tracked"]).sum())
    assumed = traj[traj["duration_source"] == "nominal_speed"]
    conv = config.convention
    period = traj["sample_period"]
    sampled = (f"{'resampled every %g s' % config.t_oc if config.t_oc else 'the sample period of each trajectory'}, "
               f"median {1000 * period.median():.1f} ms (range {1000 * period.min():.1f}-{1000 * period.max():.1f} ms)")
    lines = [
        "## Trajectory prediction (docs/methods.md sec. 7)" + ("" if stage_name == "predict" else f", stage {stage_name}"), "",
        f"Convention: **{conv.name}** (docs/methods.md sec. 11): {conv.summary}.",
        f"{len(traj)} trajectories: {studies}; entities " + ", ".join(f"{e} ({n})" for e, n in traj.groupby("entity").size().items()) + ".",
        f"Predictors: {', '.join(config.predictors)}; settings (N0, N_OC): {', '.join(f'({a}, {b})' for a, b in config.settings)}; "
        f"OC weights {config.weights or f'walking-2021 (walkers) / {conv.prediction.table_weights} (tables)'}, g0 = {config.g0}, g1 = {config.g1}."
        + (f" Goal plans: a3 = {config.turn_weight:.3g}, identified on the continuations of the study's mean paths (the weights leave a3 "
           "undetermined; docs/methods.md sec. 7.1)." if getattr(config, "turn_weight", None) is not None else ""),
        (f"T_OC: {sampled}. " if conv.prediction.node_dt is None else
         f"OC nodes: one of {conv.prediction.node_dt:g} s per sample whatever the sample period ({sampled}). ")
        + (f"{len(assumed)} trajectories have no recorded duration: assumed duration = path length / {config.nominal_speed:g} m/s "
           f"(median {assumed['duration'].median():.2f} s). " if len(assumed) else "Durations: recorded travel times. ")
        + (f"{no_theta} trajectories have no orientation" if no_theta else "")
        + (f"; {untracked} have one that was not used (orientation mode {config.orientation}: flagged "
           "implausible or ignored)" if untracked else "")
        + (": predicted from positions only (the OC tracks the direction of travel as theta, gamma = 0 assumed), no delta_theta."
           if no_theta or untracked else ""),
    ]
    first = metrics.drop_duplicates(["study", "trial", "entity", "n0", "n_oc"])
    skipped = int(first["n_skipped"].sum())
    solved = [p for p in ("oc", "goal", "goal-inferred") if p in config.predictors]  # the OC-based ones: solves can fail
    failed = ", ".join(f"{int(metrics.loc[metrics['predictor'] == p, 'n_failed'].sum())} {p}" for p in solved) or "0"
    lines.append(f"Windows: {int(first['n_windows'].sum())} per predictor, {skipped} skipped (NaN positions), "
                 f"failed OC solves: {failed} (goal-inferred: every candidate's plan failed or hit its CPU limit); "
                 "metrics use the windows every predictor predicted."
                 + (f" {len(unpredictable)} trajectories left out (no N0 consecutive finite positions)." if unpredictable else ""))
    lines += ["", "### Errors per setting (mean +- sd over trajectories; r = Pearson correlation with the global distance)", "",
              "| N0 | N_OC | predictor | delta_xy (m) | delta_theta (rad) | d_pred (m) | ADE (m) | FDE (m) | r(delta_xy, D) |",
              "|---|---|---|---|---|---|---|---|---|"]
    for (n0, n_oc, pred), g in summary.groupby(["n0", "n_oc", "predictor"], sort=True):
        cell = {r["metric"]: r for _, r in g.iterrows()}
        vals = [f"{_fmt(cell[k]['mean'])} +- {_fmt(cell[k]['sd'])}" for k in ("delta_xy", "delta_theta", "d_pred", "ade", "fde")]
        r = cell["delta_xy"]
        lines.append(f"| {n0} | {n_oc} | {pred} | " + " | ".join(vals) + f" | {_fmt(r['pearson_r'], 2)} (p {_p(r['pearson_p'])}) |")
    lines += horizon_cut_lines(first)
    goal_preds = [p for p in ("goal", "goal-inferred") if p in config.predictors]
    gamma = travel_angle(trajectories) if goal_preds else {}
    if gamma:
        lines += ["", f"{' and '.join(goal_preds)} predict the heading as the direction of travel (the walker facing where "
                  "it goes, docs/methods.md sec. 7.1), so their delta_theta holds the trajectories' own angle between "
                  "heading and direction of travel, |gamma|: median " + ", ".join(f"{e} {v:.2f} rad" for e, v in gamma.items())
                  + " (per trajectory its median, then the median over trajectories). Where it is large (a table carried "
                  "sideways or backwards: its theta is its orientation) that delta_theta is no error of a predicted heading."]
    if len(comparison):
        lines += ["", "### OC predictor vs baselines on the same windows (delta_xy; Wilcoxon signed-rank over trajectories)", "",
                  "| N0 | N_OC | baseline | group | n | OC median (m) | baseline median (m) | median OC - baseline (m) | OC better (trajectories) | OC better (windows) | W | p | r |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for _, c in comparison.iterrows():
            if c["baseline"] != "cv" and c["group"] != "all":
                continue  # the other baselines: overall only (every group is in prediction_comparison.parquet)
            lines.append(f"| {c['n0']} | {c['n_oc']} | {c['baseline']} | {c['group']} | {c['n']} | {_fmt(c['oc_median'])} | "
                         f"{_fmt(c['baseline_median'])} | {_fmt(c['median_difference'])} | {100 * c['oc_wins']:.0f} % | "
                         f"{100 * c['oc_wins_windows']:.0f} % | {_fmt(c['wilcoxon_w'], 0)} | {_p(c['wilcoxon_p'])} | {_fmt(c['effect_r'], 2)} |")
        lines += ["", "r: matched-pairs rank-biserial correlation, > 0 when the OC predictor has the smaller error."]
    if "oc" in config.predictors:
        paper = paper_rows(metrics, conv)
        start = ("started from rest at the window's first sample (published convention)" if conv.prediction.start == "rest"
                 else "started from the velocity estimated at the window's first sample")
        lines += ([""] + paper if paper else []) + [
                  "", "What the OC prediction is (the reading of the tables above): beyond the measured past the window "
                  "carries only control costs, so the predicted path is the walker coasting from its state at sample k "
                  "with constant body-frame velocities (v_forw, v_orth) and yaw rate omega, an arc of curvature "
                  "omega / speed (`OCPredictor`). The state at k is a smoothed fit of the past (tracking g0, g1 against "
                  f"the control weights a1-a3) {start}"
                  + ("" if conv.prediction.start == "rest" else "; the arc is moved onto the state estimate at k, so it "
                     "starts on the walker's current pose") + ". Where the "
                  "orientation is tracked (without it, the direction of travel in its place), its gait oscillation and any "
                  "turn on the spot enter omega (a3 is nearly zero "
                  "with the walking weights), and the arc curls away from the path: compare the 'theta tracked' and "
                  "'positions only' rows. The constant-velocity baseline extrapolates the last measured displacement "
                  "and has no such lag."]
    lines += ["", f"Figures: `prediction_overlay.png` (all predictions of {example.label}), `prediction_at_k.png`, "
              "`prediction_error_vs_distance.png` (per start orientation, min-max bands over trajectories of a condition)."]
    return "\n".join(lines) + "\n"
