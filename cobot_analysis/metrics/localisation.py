"""Headline numbers of localisation (docs/methods.md sec. 9): per run, delay, structural offset, per-axis
errors, APE, drift and goal accuracy."""

from __future__ import annotations

from cobot_analysis.metrics.data import LOCALISATION_STUDY
from cobot_analysis.metrics.records import Collector

#: the columns of a run (``localisation.tables.RUNS``) reported, with their units; then the counts
RUN_COLUMNS = {
    "distance": "m", "delay": "s", "delay_sd": "s", "offset_x": "m", "offset_y": "m", "offset_z": "m", "offset_yaw": "rad",
    **{f"err_{a}_{s}": ("rad" if a == "yaw" else "m") for a in ("x", "y", "z", "yaw") for s in ("mean", "sd", "max")},
    "ape_rmse": "m", "ape_max": "m", "drift": "m/m", "drift_sd": "m/m",
    "goal_err_xy_mean": "m", "goal_err_xy_sd": "m", "goal_err_yaw_mean": "rad", "goal_err_yaw_sd": "rad",
}
RUN_COUNTS = ("n_truth", "n_icp", "n", "goals_commanded", "goals_found", "goals_within_tolerance")


def localisation(out: Collector, runs) -> None:
    """localisation: ``runs``, one row per bag (``n``, the associated samples, is named ``associated``)."""
    out.study = LOCALISATION_STUDY
    out.count("runs", len(runs))
    for _, r in runs.iterrows():
        for c in RUN_COUNTS:
            if c in r:
                out.count((r["run"], "associated" if c == "n" else c), r[c])
        for c, unit in RUN_COLUMNS.items():
            if c in r:
                out.add((r["run"], c), r[c], unit)
