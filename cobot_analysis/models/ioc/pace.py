"""The time law of fitted weights (docs/methods.md sec. 5.5, 6.4): the time gauge fitted to measured durations.

Under the continuous convention the goal at rest is a constraint and the cost of a path X(t), t in
[0, T], is J = A + B with A = int (a0 + a4 psi^2) dt (time and path terms) and B = int (a1 u1^2 +
a2 u2^2 + a3 u3^2) dt (accelerations). The same path walked c times slower, X(t / c), costs
c A + c^-3 B. So the weights with a1, a2, a3 multiplied by c^4 (a0, a4 held) have the optimal path
X(t / c): the same time-normalised path, the duration c T (``scale_time``; the exact gauge tested in
tests/test_models_goal.py). D compares time-normalised paths and cannot see c: the pace is fitted
to measured durations instead, in closed form (``time_gauge``):

    c = argmin_c sum_n (c T_n - T^_n)^2 = sum_n T_n T^_n / sum_n T_n^2,

T_n the model's durations at the weights, T^_n the subjects' (``subject_durations``). The gauge
holds only where no duration sits on a bound of the duration search, which the continuous rule
keeps wide (``conventions.OCRule.T_bounds``); ``calibrate`` re-solves at the scaled weights and
reports the durations, D before and after, and how many durations sit on a bound (flagged, not
hidden).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

ACCELERATION_WEIGHTS = ("a1", "a2", "a3")  # the walker's weights scaled by c^4


def time_gauge(model_T, measured_T) -> float:
    """Least-squares time scale c = sum T_n T^_n / sum T_n^2 over the pairs where both are finite (nan if none)."""
    T, M = np.asarray(model_T, float), np.asarray(measured_T, float)
    ok = np.isfinite(T) & np.isfinite(M) & (T > 0) & (M > 0)
    return float(np.sum(T[ok] * M[ok]) / np.sum(T[ok] ** 2)) if ok.any() else float("nan")


def scale_time(weights: dict[str, float], c: float) -> dict[str, float]:
    """The weights whose optimal paths are those of ``weights`` walked in c times the duration: a1..a3 x c^4."""
    return {k: v * c ** 4 if k in ACCELERATION_WEIGHTS else v for k, v in weights.items()}


def subject_durations(trials: pd.DataFrame) -> pd.DataFrame:
    """Per trial: ``duration`` (s) and ``mean_speed`` (m/s) of the subjects' own walk.

    The trial's ``travel_time`` where the data hold it; else, from the recorded velocity rows (the
    published walking-2020 files hold vx, vy in m/s on the time-normalised samples, no duration):
    mean speed = mean |v| over the samples (equally spaced in time), duration = path length / mean
    speed. Rows: trial, condition, duration, mean_speed, source."""
    rows = []
    for trial, g in trials.groupby("trial", sort=False):
        g = g.sort_values("sample") if "sample" in g else g
        x, y = g["x"].to_numpy(float), g["y"].to_numpy(float)
        length = float(np.hypot(np.diff(x), np.diff(y)).sum())
        T = float(g["travel_time"].iloc[0]) if "travel_time" in g else float("nan")
        source = "travel_time"
        v = np.hypot(g["vx"].to_numpy(float), g["vy"].to_numpy(float)) if {"vx", "vy"} <= set(g.columns) else np.array([])
        if not (np.isfinite(T) and T > 0) and np.isfinite(v).any():
            speed = float(np.nanmean(v))
            T, source = (length / speed if speed > 0 else float("nan")), "velocity"
        if np.isfinite(T) and T > 0:
            rows.append({"trial": str(trial), "condition": str(g["condition"].iloc[0]), "duration": T,
                         "mean_speed": length / T, "source": source})
    return pd.DataFrame(rows, columns=["trial", "condition", "duration", "mean_speed", "source"])


def measured_by_condition(trials: pd.DataFrame) -> dict[str, tuple[float, float]]:
    """condition -> the subjects' (mean duration, mean of the trials' mean speeds) (``subject_durations``)."""
    d = subject_durations(trials)
    return {c: (float(g["duration"].mean()), float(g["mean_speed"].mean())) for c, g in d.groupby("condition")}


@dataclass
class PaceResult:
    """The time-gauge calibration of one fit (``calibrate``)."""

    c: float  # the fitted time scale: durations multiplied by c, a1..a3 by c^4
    weights: dict[str, float]  # the calibrated weights
    measured_T: list[float]  # the subjects' durations per target (nan: none)
    model_T: list[float]  # the model's durations before the calibration
    calibrated_T: list[float]  # ... and after it (re-solved)
    length: list[float]  # path length of each calibrated path (m)
    D_before: float
    D_after: float
    at_bound: int  # calibrated durations on a bound of the duration search
    n_measured: int
    failed: int = 0
    notes: list[str] = field(default_factory=list)
    terms: list[dict] = field(default_factory=list, repr=False)  # the lower level's terms at the calibrated weights


def calibrate(solve, weights: dict[str, float], per_target: list[dict], measured_T) -> PaceResult:
    """Fit the time gauge c of ``weights`` to ``measured_T`` (one per target, nan: none) from the model's
    durations ``per_target`` (the lower level's terms at ``weights``: T, D, success), then re-solve every
    target at the scaled weights with ``solve(weights) -> list of terms`` to check the gauge: every
    duration c T, D unchanged."""
    T = np.array([d["T"] if d.get("success") else np.nan for d in per_target], float)
    M = np.asarray(measured_T, float)
    c = time_gauge(T, M)
    if not np.isfinite(c):
        raise ValueError("no target with both a model and a measured duration")
    scaled = scale_time(weights, c)
    after = solve(scaled)
    Tc = [d["T"] if d.get("success") else float("nan") for d in after]
    notes = []
    bound = sum(d.get("T_at_bound", 0) != 0 for d in after if d.get("success"))
    if bound:
        notes.append(f"{bound} calibrated durations on a bound of the duration search: the gauge does not hold there")
    ok = [d for d in after if d.get("success")]
    return PaceResult(c=c, weights=scaled, measured_T=[float(v) for v in M], model_T=[float(v) for v in T], calibrated_T=Tc,
                      length=[d.get("length", float("nan")) if d.get("success") else float("nan") for d in after],
                      D_before=float(np.mean([d["D"] for d in per_target])), D_after=float(np.mean([d["D"] for d in after])),
                      at_bound=bound, n_measured=int(np.sum(np.isfinite(M) & np.isfinite(T))), failed=len(after) - len(ok),
                      notes=notes, terms=after)


def target_durations(targets, *, means: pd.DataFrame | None = None, trials: pd.DataFrame | None = None,
                     durations: pd.DataFrame | None = None, mean_keys: pd.DataFrame | None = None) -> np.ndarray | None:
    """The subjects' duration of each target (nan where none), or None when the data hold none: the
    target's own travel time in ``means`` (its trial's rows) where it holds one; else from ``durations``
    (the pair study's durations.parquet: mean over the trials of the same scenario, condition and
    direction as the mean, ``mean_keys`` those columns per mean trial); else from the ``trials`` of the
    target's condition (``subject_durations``: travel times or velocity rows)."""
    keys = ["scenario", "condition", "direction"]
    out = np.full(len(targets), np.nan)
    if means is not None and "travel_time" in means:
        own = means.groupby("trial")["travel_time"].first()
        out[:] = [float(own.get(t.trial, np.nan)) for t in targets]
        out[~(out > 0)] = np.nan
        if np.isfinite(out).all():
            return out
    if durations is not None and mean_keys is not None and set(keys + ["duration"]) <= set(durations.columns) \
            and set(keys) <= set(mean_keys.columns):
        measured = durations.groupby(keys)["duration"].mean()
        for i, t in enumerate(targets):
            if t.trial in mean_keys.index:
                k = tuple(mean_keys.loc[t.trial, keys])
                if k in measured.index and not np.isfinite(out[i]):
                    out[i] = float(measured.loc[k])
    elif trials is not None and not trials.empty and "condition" in trials:
        by_condition = measured_by_condition(trials[trials["condition"].fillna("").astype(str) != ""])
        for i, t in enumerate(targets):
            if t.condition and t.condition in by_condition and not np.isfinite(out[i]):
                out[i] = by_condition[t.condition][0]
    return out if np.isfinite(out).any() else None
