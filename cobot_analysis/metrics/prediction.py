"""Headline numbers of prediction (docs/methods.md sec. 7): per (N0, N_OC) and predictor, the error
metrics' mean and sd over trajectories and r with the global distance; the OC predictor vs each
baseline (Wilcoxon); windows used and failed."""

from __future__ import annotations

from cobot_analysis.metrics.records import Collector, study_of


def predict(out: Collector, predictions, summary, comparison) -> None:
    """predict, predict-*: ``predictions`` (per trajectory, setting and predictor), ``summary`` (per setting,
    predictor and error metric), ``comparison`` (OC vs each baseline; the ``all`` group is reported)."""
    p = predictions
    out.study = study_of(p)
    out.count("trajectories", p.drop_duplicates(["study", "trial", "entity"]).shape[0])
    for (n0, n_oc, pred), g in p.groupby(["n0", "n_oc", "predictor"], sort=True):
        setting = f"{n0}:{n_oc}"
        out.count((setting, pred, "windows_used"), g["n_used"].sum())
        out.count((setting, pred, "windows_failed"), g["n_failed"].sum())
    for _, r in summary.iterrows():
        key = (f"{r['n0']}:{r['n_oc']}", r["predictor"], r["metric"])
        out.add((*key, "mean"), r["mean"], r["unit"])
        out.add((*key, "sd"), r["sd"], r["unit"])
        out.add((*key, "pearson_r"), r["pearson_r"])
    for _, r in comparison[comparison["group"] == "all"].iterrows():
        key = (f"{r['n0']}:{r['n_oc']}", f"oc_vs_{r['baseline']}")
        out.add((*key, "median_difference"), r["median_difference"], "m")
        out.add((*key, "oc_wins"), r["oc_wins"])
        out.add((*key, "wilcoxon_p"), r["wilcoxon_p"])
