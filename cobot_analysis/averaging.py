"""Mean trajectories per condition (docs/methods.md sec. 2.9) with their sample-wise spread.

Positions: arithmetic mean over the trajectories of a group, sample by sample. Angles (theta,
gamma): circular mean ``atan2(sum sin a, sum cos a)``; theta is then unwrapped along the path so
the mean is a continuous curve. Trajectories without orientation are left out of the orientation
mean only (``n_theta`` counts those that contributed). Spread: standard deviation (circular
standard deviation ``sqrt(-2 ln R)`` for angles) and a 95 % band ``mean +- 1.96 sd``, the range
expected to hold 95 % of individual trajectories under a normal model (documented choice; the
band of the mean itself would be ``+- 1.96 sd / sqrt(n)``).

Weighting (``average --weigh``): ``trials`` (default, the published method) weighs every trajectory alike;
``subjects`` takes the mean of each unit's mean (the unit: the subject, or the pair in the pair study), so a unit
with more trials in a condition weighs as much as one with a single trial, and the spread is between the units'
means (the repeated-measures grand mean: statsmodels' ``AnovaRM(aggregate_func="mean")`` aggregates so first).

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


#: how a mean weighs its trajectories (``average --weigh``): every trajectory alike, or every unit (subject, pair) alike
WEIGHTS = ("trials", "subjects")


def unit_column(meta: pd.DataFrame) -> str | None:
    """The column of the study's units: ``pair`` in the pair study, else ``subject`` (the first with a value)."""
    return next((c for c in ("pair", "subject") if c in meta.columns and meta[c].notna().any()), None)


def check_units(meta: pd.DataFrame, by: list[str], path=None) -> str:
    """The unit column ``--weigh subjects`` averages over, refused when there is none, when some trials have no
    unit (they would make one unit of their own) or when it is a grouping column (each mean is then one unit's,
    with no spread between units)."""
    unit = unit_column(meta)
    if unit is None:
        raise InputError("--weigh subjects needs each trial's subject (or pair), and no trial has one", path=path,
                         remedy="give every trial its subject in the protocol's trials table and re-run import and "
                                "preprocess, or use --weigh trials")
    per = meta.drop_duplicates(["trial", "entity"]) if {"trial", "entity"} <= set(meta.columns) else meta
    empty = per[unit].isna() | per[unit].astype(str).str.strip().eq("")
    if empty.any():
        ids = ", ".join(per.loc[empty, "trial"].astype(str).unique()[:5]) if "trial" in per.columns else ""
        raise InputError(f"--weigh subjects: {int(empty.sum())} of {len(per)} trajectories have no {unit!r} value ({ids}...): "
                         f"they would be weighed as one {unit}", path=path,
                         remedy=f"give every trial its {unit} in the protocol's trials table and re-run import and preprocess, "
                                "or use --weigh trials")
    if unit in by:
        raise InputError(f"--weigh subjects with {unit!r} in --by: each mean is one {unit}'s, with no spread between {unit}s",
                         path=path, remedy=f"use --weigh trials for the mean of each {unit}'s trials, or leave {unit} out of --by")
    return unit


def _unit_sizes(ts: TrajectorySet, by: list[str], unit: str) -> pd.Series:
    """Trajectories of each unit in each mean, indexed by (group, unit)."""
    return ts.meta.assign(_group=group_keys(ts.meta, by)).groupby(["_group", unit], observed=True).size()


def unequal_units(ts: TrajectorySet, by: list[str]) -> tuple[int, str, int, int]:
    """How unequally the subjects (walking) or pairs (pair study) weigh in the means: (means whose units contribute
    unequal numbers of trajectories, the unit column, the fewest and the most trajectories of a unit in one mean). Each
    mean weighs its trajectories alike, so a subject with more trials in a condition weighs more in its mean (the
    published means had one trajectory per subject). (0, "", 0, 0) without a unit column or when every unit is alike."""
    unit = unit_column(ts.meta)
    if unit is None or unit in by:
        return 0, "", 0, 0
    spread = _unit_sizes(ts, by, unit).groupby(level=0).agg(["min", "max"])
    unequal = spread[spread["min"] < spread["max"]]
    if unequal.empty:
        return 0, unit, 0, 0
    return len(unequal), unit, int(unequal["min"].min()), int(unequal["max"].max())


def unit_counts(ts: TrajectorySet, by: list[str], unit: str) -> tuple[str, int, int, int, int]:
    """What the means of ``weigh="subjects"`` are made of: (the unit column, the fewest and the most units in a mean,
    the fewest and the most trajectories of a unit in a mean)."""
    sizes = _unit_sizes(ts, by, unit)
    per_mean = sizes.groupby(level=0).size()
    return unit, int(per_mean.min()), int(per_mean.max()), int(sizes.min()), int(sizes.max())


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


def mean_trajectories(ts: TrajectorySet, by: list[str] | None = None, max_spread: float = MAX_FRAME_SPREAD,
                      weigh: str = "trials") -> pd.DataFrame:
    """Mean trajectory of every group of ``ts`` defined by the ``by`` columns -> MEANS long table.

    Vectorised over groups, units and samples: trajectories are sorted by group and unit and summed
    block-wise (``np.add.reduceat``), first each unit's mean, then the mean of a group's k unit means.
    ``weigh="trials"``: every trajectory is a unit of its own; ``"subjects"``: the unit is the subject, or
    the pair (``check_units``). Positions: ``x = (1/k) sum_u x_u``, sd between the unit means with ddof = 1
    (0 for a single unit); angles: the mean of the units' mean resultant vectors
    ``m_u = (1/n_u) sum (cos a, sin a)`` over their trajectories with complete orientation, ``atan2(S, C)`` of
    ``(C, S) = sum_u m_u``, circular sd ``sqrt(-2 ln R)``, ``R = |(C, S)| / k`` (Zar's second-order mean angle);
    travel time: the mean of the unit means. A group whose start or end points spread beyond ``max_spread``
    (``frame_spread``) is flagged ``frames_differ`` in ``quality``.
    """
    by = by or default_groups(ts.meta)
    keys = group_keys(ts.meta, by).to_numpy()
    unit = np.arange(len(keys)) if weigh == "trials" else pd.factorize(ts.meta[check_units(ts.meta, by)].astype(str))[0]
    order = np.lexsort((unit, pd.factorize(keys, sort=True)[0]))
    sorted_keys, sorted_units = keys[order], unit[order]
    ustarts = np.flatnonzero(np.r_[True, (sorted_keys[1:] != sorted_keys[:-1]) | (sorted_units[1:] != sorted_units[:-1])])
    gstarts = np.flatnonzero(np.r_[True, sorted_keys[ustarts][1:] != sorted_keys[ustarts][:-1]])  # first unit of each group
    starts = ustarts[gstarts]  # first trajectory of each group
    counts = np.diff(np.r_[starts, len(order)])
    n_u = np.diff(np.r_[ustarts, len(order)])[:, None].astype(float)  # trajectories per unit
    units = np.diff(np.r_[gstarts, len(ustarts)])[:, None].astype(float)  # units per group
    n_groups, n = len(starts), ts.n_samples
    out: dict[str, np.ndarray] = {}
    for key, v in (("x", ts.x[order]), ("y", ts.y[order])):
        u = _group_sums(v, ustarts) / n_u
        mean = _group_sums(u, gstarts) / units
        sq = _group_sums(u ** 2, gstarts) - units * mean ** 2
        out[key], out[f"{key}_sd"] = mean, np.sqrt(np.clip(sq, 0, None) / np.maximum(units - 1, 1))
    for key in ("theta", "gamma"):
        a = getattr(ts, key)[order]
        ok = np.isfinite(a).all(axis=1)
        n_ok = np.add.reduceat(ok.astype(float), ustarts)[:, None]
        s_, c_ = (_group_sums(_group_sums(np.where(ok[:, None], f(np.where(ok[:, None], a, 0)), 0), ustarts) / np.maximum(n_ok, 1),
                              gstarts) for f in (np.sin, np.cos))
        k_ok = np.add.reduceat((n_ok > 0).astype(float), gstarts)  # units with orientation
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(k_ok > 0, np.arctan2(s_, c_), np.nan)
            r = np.hypot(s_, c_) / k_ok
            out[f"{key}_sd"] = np.where(k_ok > 0, np.sqrt(-2 * np.log(np.clip(r, 1e-300, 1.0))), np.nan)
        if key == "theta":
            n_theta = np.add.reduceat(ok.astype(float), starts)[:, None]
            mean = np.unwrap(np.where(np.isnan(mean), 0, mean), axis=1)
            # same turn as the members at the start (e.g. +pi/2, not -3 pi/2)
            first = np.add.reduceat(np.where(ok, a[:, 0], 0), starts) / np.maximum(n_theta[:, 0], 1)
            mean += 2 * np.pi * np.round((first[:, None] - mean[:, :1]) / (2 * np.pi))
            mean = np.where(k_ok > 0, mean, np.nan)
            out["n_theta"] = np.repeat(n_theta.astype(int), n, axis=1)
        out[key] = mean
    for key in ("x", "y", "theta"):
        out[f"{key}_lo"] = out[key] - Z95 * out[f"{key}_sd"]
        out[f"{key}_hi"] = out[key] + Z95 * out[f"{key}_sd"]

    first_rows = ts.meta.iloc[order[starts]].reset_index(drop=True)
    meta = pd.DataFrame({c: first_rows[c] if c in by else None for c in TRIAL_COLUMNS})
    meta["trial"] = ["mean:" + k for k in sorted_keys[starts]]
    meta["kind"] = "mean"
    meta["n_trials"] = counts
    meta["entity"] = first_rows["entity"]
    if "travel_time" in ts.meta.columns:
        tt = ts.meta["travel_time"].to_numpy(dtype=float)[order]
        n_tt = np.add.reduceat(np.isfinite(tt).astype(float), ustarts)
        k_tt = np.add.reduceat((n_tt > 0).astype(float), gstarts)  # units with a travel time
        u_tt = np.add.reduceat(np.nan_to_num(tt), ustarts) / np.maximum(n_tt, 1)
        meta["travel_time"] = np.where(k_tt > 0, np.add.reduceat(u_tt, gstarts) / np.maximum(k_tt, 1), np.nan)
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
