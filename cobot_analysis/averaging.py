"""Mean trajectories per condition (METHODS.md sec. 2.9) with their sample-wise spread.

Positions: arithmetic mean over the trajectories of a group, sample by sample. Angles (theta,
gamma): circular mean ``atan2(sum sin a, sum cos a)``; theta is then unwrapped along the path so
the mean is a continuous curve. Trajectories without orientation are left out of the orientation
mean only (``n_theta`` counts those that contributed). Spread: standard deviation (circular
standard deviation ``sqrt(-2 ln R)`` for angles) and a 95 % band ``mean +- 1.96 sd``, the range
expected to hold 95 % of individual trajectories under a normal model (documented choice; the
band of the mean itself would be ``+- 1.96 sd / sqrt(n)``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from cobot_analysis.angles import circular_mean, circular_std
from cobot_analysis.compare import TrajectorySet, default_groups, group_keys
from cobot_analysis.schema import TRIAL_COLUMNS, Column, TableSchema

Z95 = 1.959963984540054

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
        "x": Column("float", "m", "mean position"),
        "y": Column("float", "m", "mean position"),
        "theta": Column("float", "rad", "circular mean of the global orientation, unwrapped along the path"),
        "gamma": Column("float", "rad", "circular mean of the local orientation, wrapped"),
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
        "travel_time": Column("float", "s", "mean travel time of the group (NaN if unknown)"),
        "travelled_distance": Column("float", "m", "start-end distance of the mean path"),
        "quality": Column("string", "", "'ok' or 'orientation_missing' when no member had orientation"),
    },
)


def mean_of(ts: TrajectorySet) -> dict[str, np.ndarray]:
    """Sample-wise mean and spread of all trajectories of ``ts`` (arrays of length N)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        has_theta = np.isfinite(ts.theta).all(axis=1)
        th = ts.theta[has_theta]
        ga = ts.gamma[np.isfinite(ts.gamma).all(axis=1)]
        n = len(ts)
        ddof = 1 if n > 1 else 0
        out = {
            "x": ts.x.mean(axis=0), "y": ts.y.mean(axis=0),
            "x_sd": ts.x.std(axis=0, ddof=ddof), "y_sd": ts.y.std(axis=0, ddof=ddof),
            "theta": np.unwrap(circular_mean(th, axis=0)) if len(th) else np.full(ts.n_samples, np.nan),
            "theta_sd": circular_std(th, axis=0) if len(th) else np.full(ts.n_samples, np.nan),
            "gamma": circular_mean(ga, axis=0) if len(ga) else np.full(ts.n_samples, np.nan),
            "gamma_sd": circular_std(ga, axis=0) if len(ga) else np.full(ts.n_samples, np.nan),
        }
    if len(th):  # put the unwrapped mean on the same turn as the members (e.g. start near +pi/2, not -3pi/2)
        out["theta"] += 2 * np.pi * np.round((np.nanmean(th[:, 0]) - out["theta"][0]) / (2 * np.pi))
    out["n_theta"] = np.full(ts.n_samples, len(th))
    for k in ("x", "y", "theta"):
        out[f"{k}_lo"] = out[k] - Z95 * out[f"{k}_sd"]
        out[f"{k}_hi"] = out[k] + Z95 * out[f"{k}_sd"]
    return out


def mean_trajectories(ts: TrajectorySet, by: list[str] | None = None, progress=None) -> pd.DataFrame:
    """Mean trajectory of every group of ``ts`` defined by the ``by`` columns -> MEANS long table.

    ``progress`` wraps the loop over groups (e.g. ``console.track``); the work inside each group
    is vectorised over samples and trajectories.
    """
    by = by or default_groups(ts.meta)
    keys = group_keys(ts.meta, by)
    groups = list(pd.Series(np.arange(len(ts))).groupby(keys.to_numpy(), sort=True))
    n = ts.n_samples
    phase = 100.0 * np.arange(n) / max(n - 1, 1)
    frames = []
    iterator = progress(groups, "average") if progress else groups
    for key, idx in iterator:
        member = ts.subset(np.isin(np.arange(len(ts)), idx.to_numpy()))
        m = mean_of(member)
        first = member.meta.iloc[0]
        tt = member.meta["travel_time"].mean() if "travel_time" in member.meta else np.nan
        row = {c: first[c] if c in by else None for c in TRIAL_COLUMNS}
        row.update({
            "trial": f"mean:{key}", "kind": "mean", "n_trials": len(member),
            "entity": first["entity"], "travel_time": tt,
            "travelled_distance": float(np.hypot(m["x"][-1] - m["x"][0], m["y"][-1] - m["y"][0])),
            "quality": "ok" if m["n_theta"][0] else "orientation_missing",
        })
        for c in by:
            row[c] = first[c]
        frame = pd.DataFrame({**m, "sample": np.arange(n), "phase": phase, "time": phase * tt / 100.0})
        for c, v in row.items():
            frame[c] = v
        frames.append(frame)
    out = pd.concat(frames, ignore_index=True)
    cols = list(MEANS.columns)
    return out[cols + [c for c in out.columns if c not in cols]]
