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

import warnings

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.errors import InputError
from cobot_analysis.models.prediction.errors import truth_windows
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


def horizon_rows(traj, config, n0: int, horizons, runs: dict) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``sweep.trajectory_horizons`` from predictions already made (``sweep.trajectory_runs`` with this N0 run
    over the whole path): the predict stage's sweep and its horizon sweep share one run per predictor."""
    n = len(traj.poses)
    h_max = n - n0
    preds, infer = {}, pd.DataFrame(columns=list(GOAL_INFERENCE.columns))
    for name in config.predictors:
        predictions, *_, p = runs[n0, name]
        preds[name] = predictions[:, : h_max + 1]
        if name == "goal-inferred" and traj.goal is not None:
            infer = inference_rows(traj, p)
    valid = np.logical_and.reduce([np.isfinite(P[:, 0, :2]).all(axis=1) for P in preds.values()])
    truth = truth_windows(traj.poses, n0, h_max)
    k = np.arange(n0 - 1, n)
    rows = []
    for name, P in preds.items():
        e = np.hypot(*(truth[..., :2] - P[..., :2]).transpose(2, 0, 1))  # (W, h_max + 1), NaN past the end
        has = np.where(np.isfinite(P[:, 0, :2]).all(axis=1), 1.0, np.nan)
        for h in horizons:
            hh = h_max if h == WHOLE else min(h, h_max)
            with warnings.catch_warnings():  # all-NaN rows give NaN on purpose ("mean of empty slice")
                warnings.simplefilter("ignore", RuntimeWarning)
                dxy = np.nanmean(e[:, : hh + 1], axis=1) * has  # errors.window_errors(...).error_xy of P[:, :hh + 1]
            if h == WHOLE:
                fde = e[np.arange(len(k)), n - 1 - k]
            else:
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
