"""Mean trajectories per condition (docs/methods.md sec. 2.9) with their sample-wise spread.

Positions: arithmetic mean over the trajectories of a group, sample by sample. Angles (theta,
gamma): circular mean ``atan2(sum sin a, sum cos a)``; theta is then unwrapped along the path so
the mean is a continuous curve. Trajectories without orientation are left out of the orientation
mean only (``n_theta`` counts those that contributed). Spread: standard deviation (circular
standard deviation ``sqrt(-2 ln R)`` for angles) and a 95 % band ``mean +- 1.96 sd``, the range
expected to hold 95 % of individual trajectories under a normal model (documented choice; the
band of the mean itself would be ``+- 1.96 sd / sqrt(n)``).

Groups must be real conditions (``check_groups``): a grouping column that is empty for some trials
(a trials table without ``condition``) would average unrelated trials into one mean, so it is
refused with the trials concerned, and so are two labels that differ only by case or spaces (two
spellings of one condition, which would make two means; docs/methods.md sec. 2.9).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from cobot_analysis.compare import TrajectorySet, default_groups, group_keys
from cobot_analysis.errors import InputError
from cobot_analysis.schema import NONNEGATIVE, POSITION, TRIAL_COLUMNS, UNWRAPPED, WRAPPED, Column, TableSchema

Z95 = 1.959963984540054
#: largest spread (m) of the members' start or end points around the group's median start or end:
#: beyond it the trials were not recorded in one frame (e.g. three labs), or are not one condition,
#: and their mean is no path anyone walked (flag ``frames_differ``, left out of the comparisons).
MAX_FRAME_SPREAD = 1.0

MEANS = TableSchema(
    name="means",
    version=1,
    description=("Mean trajectories per condition, long format like trajectories (kind = 'mean'), with the "
                 "number of trajectories averaged and the sample-wise spread."),
    columns={
        **TRIAL_COLUMNS,
        "entity": Column("string", "", "walker, subject1, subject2 or table"),
        "sample": Column("int", "-", "sample index 0..N-1"),
        "phase": Column("float", "%", "100 * sample / (N - 1)"),
        "time": Column("float", "s", "phase * mean travel time / 100 (NaN if unknown)"),
        "x": Column("float", "m", "mean position", limits=POSITION),
        "y": Column("float", "m", "mean position", limits=POSITION),
        "theta": Column("float", "rad", "circular mean of the global orientation, unwrapped along the path", limits=UNWRAPPED),
        "gamma": Column("float", "rad", "circular mean of the local orientation, wrapped", limits=WRAPPED),
        "n_theta": Column("int", "-", "trajectories with orientation that entered the angle means"),
        "x_sd": Column("float", "m", "sample-wise standard deviation of x"),
        "y_sd": Column("float", "m", "sample-wise standard deviation of y"),
        "theta_sd": Column("float", "rad", "sample-wise circular standard deviation of theta"),
        "gamma_sd": Column("float", "rad", "sample-wise circular standard deviation of gamma"),
        "x_lo": Column("float", "m", "x - 1.96 x_sd (95 % band of individual paths)"),
        "x_hi": Column("float", "m", "x + 1.96 x_sd"),
        "y_lo": Column("float", "m", "y - 1.96 y_sd"),
        "y_hi": Column("float", "m", "y + 1.96 y_sd"),
        "theta_lo": Column("float", "rad", "theta - 1.96 theta_sd"),
        "theta_hi": Column("float", "rad", "theta + 1.96 theta_sd"),
        "travel_time": Column("float", "s", "mean travel time of the group (NaN if unknown)", limits=NONNEGATIVE),
        "travelled_distance": Column("float", "m", "start-end distance of the mean path", limits=NONNEGATIVE),
        "quality": Column("string", "", "'ok' or 'orientation_missing' when no member had orientation"),
    },
)


def spread_warnings(ts: TrajectorySet, by: list[str], max_spread: float = MAX_FRAME_SPREAD) -> list[str]:
    """One line per group whose members do not share a frame (``frame_spread`` beyond ``max_spread``)."""
    sp = frame_spread(ts, by)
    far = sp[np.fmax(sp["start_spread"], sp["end_spread"]) > max_spread]
    return [f"mean {r.group} of {r.n} trajectories: starts spread {r.start_spread:.2f} m, ends {r.end_spread:.2f} m "
            f"(> {max_spread:g} m: not one frame or not one condition); flagged frames_differ, left out of the comparisons"
            for r in far.itertuples()]


def unequal_units(ts: TrajectorySet, by: list[str]) -> tuple[int, str, int, int]:
    """How unequally the subjects (walking) or pairs (pair study) weigh in the means: (means whose units contribute
    unequal numbers of trajectories, the unit column, the fewest and the most trajectories of a unit in one mean). Each
    mean weighs its trajectories alike, so a subject with more trials in a condition weighs more in its mean (the
    published means had one trajectory per subject). (0, "", 0, 0) without a unit column or when every unit is alike."""
    unit = next((c for c in ("subject", "pair") if c in ts.meta and ts.meta[c].notna().any()), None)
    if unit is None or unit in by:
        return 0, "", 0, 0
    counts = ts.meta.assign(_group=group_keys(ts.meta, by)).groupby(["_group", unit], observed=True).size()
    spread = counts.groupby(level=0).agg(["min", "max"])
    unequal = spread[spread["min"] < spread["max"]]
    if unequal.empty:
        return 0, unit, 0, 0
    return len(unequal), unit, int(unequal["min"].min()), int(unequal["max"].max())


def check_groups(meta: pd.DataFrame, by: list[str], path=None) -> None:
    """Refuse a grouping under which trials without a value would be averaged together.

    Every column of ``by`` (``entity`` is always set) must be given for every trial: one empty
    for all trials would make one mean of the whole study, one empty for some would pool those
    trials, whatever their conditions, into a group of their own. Nor may two labels of a column differ
    only by case or spaces (``_check_spellings``).
    """
    per = meta.drop_duplicates(["trial", "entity"]) if {"trial", "entity"} <= set(meta.columns) else meta
    for c in by:
        _check_spellings(per[c], c, path)
        empty = per[c].isna() | per[c].astype(str).str.strip().eq("")
        if not empty.any():
            continue
        n = len(per)
        if empty.all():
            what = f"no trial has a {c!r} value: the means would average all {n} trajectories into one"
        else:
            ids = ", ".join(per.loc[empty, "trial"].astype(str).unique()[:5]) if "trial" in per.columns else ""
            what = f"{int(empty.sum())} of {n} trajectories have no {c!r} value ({ids}...): they would be averaged together as one group"
        raise InputError(what, path=path,
                         remedy=f"give every trial its {c} in the protocol's trials table and re-run import and preprocess, "
                                f"or choose the grouping with --by (e.g. --by {','.join(b for b in by if b != c)} for one mean "
                                f"over all {c}s)")


def _check_spellings(values: pd.Series, column: str, path=None) -> None:
    """Refuse two labels of ``column`` that differ only by case or spaces ("d1_p4" and "D1_P4 "): two trials
    tables' spellings of one condition, which would be averaged as two."""
    labels = pd.Series(values.dropna().astype(str).unique())
    if labels.empty:
        return
    key = labels.str.split().str.join(" ").str.casefold()
    clash = labels[key.duplicated(keep=False)]
    if clash.empty:
        return
    first = sorted(clash[key[clash.index] == key[clash.index[0]]])
    raise InputError(f"{column} labels {' and '.join(repr(v) for v in first)} differ only by case or spaces: they "
                     "would be averaged as two conditions", path=path,
                     remedy=f"write each {column} alike in the protocol's trials table and re-run import and preprocess")


def frame_spread(ts: TrajectorySet, by: list[str]) -> pd.DataFrame:
    """Per group of ``by``: trajectories, start spread and end spread (m): the largest distance of a
    member's first (last) point from the median first (last) point of the group."""
    keys = group_keys(ts.meta, by).to_numpy()
    rows = []
    for key in pd.unique(keys):
        idx = np.flatnonzero(keys == key)
        spread = []
        for k in (0, -1):
            p = np.column_stack([ts.x[idx, k], ts.y[idx, k]])
            p = p[np.isfinite(p).all(axis=1)]
            spread.append(float(np.max(np.hypot(*(p - np.median(p, axis=0)).T))) if len(p) else 0.0)
        rows.append({"group": key, "n": len(idx), "start_spread": spread[0], "end_spread": spread[1]})
    return pd.DataFrame(rows, columns=["group", "n", "start_spread", "end_spread"])


def _group_sums(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Sums of consecutive row blocks starting at ``starts`` (rows sorted by group), NaN as 0."""
    return np.add.reduceat(np.where(np.isfinite(values), values, 0.0), starts, axis=0)


def mean_trajectories(ts: TrajectorySet, by: list[str] | None = None, max_spread: float = MAX_FRAME_SPREAD) -> pd.DataFrame:
    """Mean trajectory of every group of ``ts`` defined by the ``by`` columns -> MEANS long table.

    Vectorised over groups, trajectories and samples: trajectories are sorted by group and summed
    block-wise (``np.add.reduceat``). Means: ``sum x / n``; sd with ddof = 1 (0 for a single
    trajectory); circular mean ``atan2(S, C)`` and circular sd ``sqrt(-2 ln R)``, R = |(C, S)| / n_theta,
    over the trajectories whose orientation is complete. A group whose start or end points spread
    beyond ``max_spread`` (``frame_spread``) is flagged ``frames_differ`` in ``quality``.
    """
    by = by or default_groups(ts.meta)
    keys = group_keys(ts.meta, by).to_numpy()
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    starts = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
    counts = np.diff(np.r_[starts, len(order)])
    n_groups, n = len(starts), ts.n_samples
    x, y = ts.x[order], ts.y[order]
    cnt = counts[:, None].astype(float)
    out: dict[str, np.ndarray] = {}
    for k, v in (("x", x), ("y", y)):
        mean = _group_sums(v, starts) / cnt
        sq = _group_sums(v ** 2, starts) - cnt * mean ** 2
        out[k], out[f"{k}_sd"] = mean, np.sqrt(np.clip(sq, 0, None) / np.maximum(cnt - 1, 1))
    for k in ("theta", "gamma"):
        a = getattr(ts, k)[order]
        ok = np.isfinite(a).all(axis=1)
        w = ok[:, None].astype(float)
        s_ = np.add.reduceat(np.where(ok[:, None], np.sin(np.where(ok[:, None], a, 0)), 0) * w, starts, axis=0)
        c_ = np.add.reduceat(np.where(ok[:, None], np.cos(np.where(ok[:, None], a, 0)), 0) * w, starts, axis=0)
        n_ok = np.add.reduceat(ok.astype(float), starts)[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(n_ok > 0, np.arctan2(s_, c_), np.nan)
            r = np.hypot(s_, c_) / n_ok
            out[f"{k}_sd"] = np.where(n_ok > 0, np.sqrt(-2 * np.log(np.clip(r, 1e-300, 1.0))), np.nan)
        if k == "theta":
            mean = np.unwrap(np.where(np.isnan(mean), 0, mean), axis=1)
            # same turn as the members at the start (e.g. +pi/2, not -3 pi/2)
            first = np.add.reduceat(np.where(ok, a[:, 0], 0), starts) / np.maximum(n_ok[:, 0], 1)
            mean += 2 * np.pi * np.round((first[:, None] - mean[:, :1]) / (2 * np.pi))
            mean = np.where(n_ok > 0, mean, np.nan)
            out["n_theta"] = np.repeat(n_ok.astype(int), n, axis=1)
        out[k] = mean
    for k in ("x", "y", "theta"):
        out[f"{k}_lo"] = out[k] - Z95 * out[f"{k}_sd"]
        out[f"{k}_hi"] = out[k] + Z95 * out[f"{k}_sd"]

    first_rows = ts.meta.iloc[order[starts]].reset_index(drop=True)
    meta = pd.DataFrame({c: first_rows[c] if c in by else None for c in TRIAL_COLUMNS})
    meta["trial"] = ["mean:" + k for k in sorted_keys[starts]]
    meta["kind"] = "mean"
    meta["n_trials"] = counts
    meta["entity"] = first_rows["entity"]
    if "travel_time" in ts.meta.columns:
        tt = ts.meta["travel_time"].to_numpy(dtype=float)[order]
        meta["travel_time"] = np.add.reduceat(np.nan_to_num(tt), starts) / np.maximum(np.add.reduceat(np.isfinite(tt).astype(float), starts), 1)
        meta.loc[np.add.reduceat(np.isfinite(tt).astype(float), starts) == 0, "travel_time"] = np.nan
    else:
        meta["travel_time"] = np.nan
    meta["travelled_distance"] = np.hypot(out["x"][:, -1] - out["x"][:, 0], out["y"][:, -1] - out["y"][:, 0])
    meta["quality"] = np.where(out["n_theta"][:, 0] > 0, "ok", "orientation_missing")
    spread = frame_spread(ts, by).set_index("group").reindex(sorted_keys[starts])
    far = (np.fmax(spread["start_spread"], spread["end_spread"]) > max_spread).to_numpy()
    meta.loc[far, "quality"] = meta.loc[far, "quality"].where(meta.loc[far, "quality"].ne("ok"), "") + ";frames_differ"
    meta["quality"] = meta["quality"].str.lstrip(";")
    long = meta.loc[np.repeat(np.arange(n_groups), n)].reset_index(drop=True)
    phase = 100.0 * np.arange(n) / max(n - 1, 1)
    long["sample"] = np.tile(np.arange(n), n_groups)
    long["phase"] = np.tile(phase, n_groups)
    long["time"] = long["phase"] * long["travel_time"] / 100.0
    for k, v in out.items():
        long[k] = v.reshape(-1)
    return long[list(MEANS.columns)]
