"""The horizon sweep (docs/methods.md sec. 7.2): how each predictor's error grows with how far ahead it
predicts, from a few samples to the whole remaining path, at one N0.

Every predictor predicts once per window as far as the recording goes (H_max = N - N0 samples; the
OC predictors' windows separate, so a longer horizon does not change the nearer predictions), and each
horizon h takes the first h + 1 samples of those predictions. Per trajectory, predictor and h, over
the windows every predictor predicted:

- ``delta_xy(h)``: docs/methods.md sec. 7's delta_xy with N_OC - N0 = h (the window's samples k .. k + h,
  cut at the end of the recording);
- ``fde(h)``: the error at sample k + h, over the windows with k + h inside the recording.

The horizon ``whole`` (h = -1 in the tables) is the whole remaining path of each window: delta_xy over
k .. N - 1 and the final displacement error at the last sample N - 1.

Candidate goals: the goal-inferred predictor's p(true goal | past) and whether its most probable goal
is the true one (the candidate nearest the design goal), per window, against the fraction of the
path's length walked at sample k (``goal_inference`` table).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from cobot_analysis.errors import InputError
from cobot_analysis.models.prediction.metrics import truth_windows, window_errors
from cobot_analysis.models.prediction.predictor import make_predictor
from cobot_analysis.schema import Column, TableSchema

HORIZONS = (5, 10, 25, 50, 100, 200, -1)  # samples ahead; -1: the whole remaining path
WHOLE = -1
BASELINE = "cv"

HORIZON_ERRORS = TableSchema(
    name="horizon_errors",
    version=1,
    description="Prediction error against the horizon (docs/methods.md sec. 7.2): one row per trajectory x predictor x "
                "horizon, over the windows every predictor predicted.",
    columns={
        "convention": Column("string", "", "published or continuous (docs/methods.md sec. 11)"),
        "study": Column("string", "", "study name"),
        "trial": Column("string", "", "trial identifier"),
        "entity": Column("string", "", "walker, subject1, subject2 or table"),
        "n0": Column("int", "-", "N0: measured past samples"),
        "predictor": Column("string", "", "oc, goal, goal-inferred, cv or ctrv"),
        "horizon": Column("int", "-", "samples ahead h; -1 = the whole remaining path"),
        "delta_xy": Column("float", "m", "mean over windows of the mean position error over k .. min(k + h, N - 1)"),
        "fde": Column("float", "m", "mean over windows of the error at k + h (h = -1: at the last sample N - 1)"),
        "n_windows": Column("int", "-", "windows behind delta_xy"),
    },
)
HORIZON_SUMMARY = TableSchema(
    name="horizon_summary",
    version=1,
    description="Mean horizon errors over trajectories per study, predictor and horizon (docs/methods.md sec. 7.2).",
    columns={
        "study": Column("string", "", "study name"),
        "predictor": Column("string", "", "oc, goal, goal-inferred, cv or ctrv"),
        "horizon": Column("int", "-", "samples ahead h; -1 = the whole remaining path"),
        "n": Column("int", "-", "trajectories with a value"),
        "delta_xy": Column("float", "m", "mean over trajectories of delta_xy(h)"),
        "fde": Column("float", "m", "mean over trajectories of fde(h)"),
        "ratio_cv": Column("float", "-", "delta_xy over constant velocity's at the same horizon (< 1: better)", required=False),
        "ratio_cv_fde": Column("float", "-", "fde over constant velocity's at the same horizon", required=False),
    },
)
GOAL_INFERENCE = TableSchema(
    name="goal_inference",
    version=1,
    description="Goal inference of the goal-inferred predictor (docs/methods.md sec. 7.1), per trajectory and window.",
    columns={
        "study": Column("string", "", "study name"),
        "trial": Column("string", "", "trial identifier"),
        "entity": Column("string", "", "walker, subject1, subject2 or table"),
        "k": Column("int", "-", "sample of the window (0-based)"),
        "walked": Column("float", "-", "fraction of the path's length walked at sample k"),
        "p_true": Column("float", "-", "p(true goal | past)"),
        "correct": Column("bool", "", "the most probable candidate is the true goal"),
    },
)


def parse_horizons(text: str) -> tuple[int, ...]:
    """``"5,10,50,all"`` -> (5, 10, 50, -1)."""
    out = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        if part in ("all", "whole"):
            out.append(WHOLE)
            continue
        try:
            h = int(part)
        except ValueError:
            h = 0
        if h < 1:
            raise InputError(f"--horizons: bad horizon {part!r}", remedy="give positive sample counts and/or 'all', e.g. 5,50,200,all")
        out.append(h)
    if not out:
        raise InputError("--horizons: no horizon given", remedy="give e.g. 5,10,25,50,100,200,all")
    return tuple(dict.fromkeys(out))


def trajectory_horizons(traj, config, n0: int, horizons=HORIZONS) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Horizon errors of every predictor of ``config`` on one trajectory, and the goal inference rows."""
    from cobot_analysis.models.prediction.sweep import predictor_options

    n = len(traj.poses)
    h_max = n - n0
    preds, infer = {}, pd.DataFrame(columns=list(GOAL_INFERENCE.columns))
    for name in config.predictors:
        p = make_predictor(name, n0, n0 + h_max, traj.dt, convention=config.convention, **predictor_options(name, traj, config))
        preds[name] = p.predict_offline(traj.seen)
        if name == "goal-inferred" and traj.goal is not None:
            infer = inference_rows(traj, p)
    valid = np.logical_and.reduce([np.isfinite(P[:, 0, :2]).all(axis=1) for P in preds.values()])
    truth = truth_windows(traj.poses, n0, h_max)
    k = np.arange(n0 - 1, n)
    rows = []
    for name, P in preds.items():
        e = np.hypot(*(truth[..., :2] - P[..., :2]).transpose(2, 0, 1))  # (W, h_max + 1)
        for h in horizons:
            if h == WHOLE:
                dxy = window_errors(traj.poses, P, n0).error_xy
                fde = e[np.arange(len(k)), n - 1 - k]
            else:
                hh = min(h, h_max)
                dxy = window_errors(traj.poses, P[:, : hh + 1], n0).error_xy
                fde = np.where(k + h <= n - 1, e[:, hh], np.nan) if h <= h_max else np.full(len(k), np.nan)
            use = valid & np.isfinite(dxy)
            rows.append({"convention": config.convention.name, "study": traj.study, "trial": traj.trial, "entity": traj.entity,
                         "n0": n0, "predictor": name, "horizon": h,
                         "delta_xy": float(dxy[use].mean()) if use.any() else np.nan,
                         "fde": float(np.nanmean(fde[use])) if np.isfinite(fde[use]).any() else np.nan,
                         "n_windows": int(use.sum())})
    return pd.DataFrame(rows), infer


def inference_rows(traj, predictor) -> pd.DataFrame:
    """Per window: the walked fraction, p(true goal) and whether the most probable goal is the true one."""
    true = int(np.argmin(np.hypot(*(predictor.candidates - np.asarray(traj.goal[:2])).T)))
    xy = traj.poses[:, :2]
    step = np.hypot(*np.diff(xy, axis=0).T)
    s = np.concatenate([[0.0], np.nancumsum(step)])
    rows = [{"study": traj.study, "trial": traj.trial, "entity": traj.entity, "k": k, "walked": s[k] / s[-1] if s[-1] > 0 else np.nan,
             "p_true": float(post[true]), "correct": bool(np.argmax(post) == true)} for k, post in predictor.history]
    return pd.DataFrame(rows, columns=list(GOAL_INFERENCE.columns))


def _task(item):
    traj, config, n0, horizons = item
    return trajectory_horizons(traj, config, n0, horizons)


def horizon_sweep(trajectories, config, n0: int = 50, horizons=HORIZONS, *, jobs: int | None = None,
                  scheduler: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``trajectory_horizons`` over ``trajectories`` in parallel (``parallel.map_tasks``): (errors, inference)."""
    from cobot_analysis.models.prediction.predictor import check_setting
    from cobot_analysis.parallel import map_tasks

    check_setting(n0, n0 + 1)
    config = replace(config, settings=((n0, n0 + 1),))
    results = map_tasks(_task, [(t, config, n0, tuple(horizons)) for t in trajectories], jobs=jobs, scheduler=scheduler,
                        description="horizons")
    errors = pd.concat([r[0] for r in results], ignore_index=True)
    infer = [r[1] for r in results if len(r[1])]
    inference = pd.concat(infer, ignore_index=True) if infer else pd.DataFrame(columns=list(GOAL_INFERENCE.columns))
    return errors, inference


def horizon_summary(errors: pd.DataFrame) -> pd.DataFrame:
    """Mean over trajectories per study, predictor and horizon; ``ratio_cv``: the predictor's mean
    delta_xy over constant velocity's at the same horizon (< 1: better)."""
    g = errors.groupby(["study", "predictor", "horizon"], sort=True)
    out = g.agg(n=("delta_xy", "count"), delta_xy=("delta_xy", "mean"), fde=("fde", "mean")).reset_index()
    if BASELINE in set(out["predictor"]):
        base = out[out["predictor"] == BASELINE].set_index(["study", "horizon"])
        out["ratio_cv"] = out["delta_xy"].to_numpy() / base.loc[list(zip(out["study"], out["horizon"])), "delta_xy"].to_numpy()
        out["ratio_cv_fde"] = out["fde"].to_numpy() / base.loc[list(zip(out["study"], out["horizon"])), "fde"].to_numpy()
    return out


def wins_from(summary: pd.DataFrame, study: str, predictor: str, baseline: str = BASELINE) -> int | None:
    """The smallest finite horizon from which ``predictor``'s mean delta_xy is below ``baseline``'s at
    that and every longer horizon (the whole path included); None if never."""
    s = summary[summary["study"] == study].pivot(index="horizon", columns="predictor", values="delta_xy")
    order = sorted(s.index, key=lambda h: np.inf if h == WHOLE else h)
    better = [bool(s.loc[h, predictor] < s.loc[h, baseline]) for h in order]
    start = None
    for h, b in zip(order, better):
        if b and start is None:
            start = h
        elif not b:
            start = None
    return start


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
                lines.append(f"- {p}: " + (f"beats cv from {fmt(w)} samples ahead on" if w is not None else "never beats cv at every longer horizon")
                             + ratio)
            lines.append("")
    if len(inference):
        bins = np.linspace(0, 1, 6)
        inference = inference.assign(part=pd.cut(inference["walked"], bins, include_lowest=True))
        t = inference.groupby("part", observed=True).agg(p_true=("p_true", "mean"), correct=("correct", "mean"), n=("k", "size"))
        lines += ["Goal inference (goal-inferred, candidate goals of the study), by fraction of the path walked:", "",
                  "| walked | mean p(true goal) | most probable = true | windows |", "|---|---|---|---|"]
        lines += [f"| {iv.left:.0%}-{iv.right:.0%} | {r.p_true:.2f} | {r.correct:.0%} | {r.n} |" for iv, r in t.iterrows()]
        lines.append("")
    return lines


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
                ax.plot(gp["x"], gp[metric], "o-", label=p)
            ax.set_xscale("log")
            ax.set_xticks(hs + [x_whole], [str(h) for h in hs] + ["whole"])
            ax.set_xlabel("horizon (samples ahead)")
            ax.set_ylabel(f"{metric} (m)")
            ax.set_title(f"{study}: {metric}")
            ax.grid(alpha=0.3)
        axes[0, j].legend()
    fig.tight_layout()
    return fig


def write_horizons(stage, trajectories, config, horizons, *, jobs: int | None = None, scheduler: str | None = None) -> list[str]:
    """The horizon sweep at the first setting's N0 written into ``stage`` (``horizon_errors.parquet``,
    ``horizon_summary.parquet``, ``goal_inference.parquet``, figure ``horizons``); returns the results fragment."""
    from cobot_analysis.schema import write_table

    n0 = config.settings[0][0]
    errors, inference = horizon_sweep(trajectories, config, n0, horizons, jobs=jobs, scheduler=scheduler)
    summary = horizon_summary(errors)
    write_table(errors, stage.path("horizon_errors.parquet"), HORIZON_ERRORS, convention=config.convention.name)
    write_table(summary, stage.path("horizon_summary.parquet"), HORIZON_SUMMARY, convention=config.convention.name)
    write_table(inference, stage.path("goal_inference.parquet"), GOAL_INFERENCE, convention=config.convention.name)
    stage.savefig(horizon_figure(summary), "horizons")
    return horizon_markdown(summary, inference)
