"""Headline numbers of the analyses: average, compare, stats, reconstruct (docs/methods.md sec. 2.9, 3,
4, 8). Each function adds its records to a ``records.Collector``."""

from __future__ import annotations

from cobot_analysis.metrics.records import Collector, groups, study_of


def average(out: Collector, means) -> None:
    """average: mean trajectories per entity, trials behind them, spread of the individual paths."""
    out.study = study_of(means)
    first = means[means["sample"] == 0]
    out.count("means", len(first))
    for key, g in groups(means, ["entity"]):
        f = g[g["sample"] == 0]
        out.count((*key, "means"), len(f))
        out.count((*key, "trials"), f["n_trials"].sum())
        out.count((*key, "without_orientation"), (f["n_theta"] == 0).sum())
        out.add((*key, "x_sd", "mean"), g["x_sd"].mean(), "m")
        out.add((*key, "y_sd", "mean"), g["y_sd"].mean(), "m")
        out.add((*key, "travelled_distance", "mean"), f["travelled_distance"].mean(), "m")
        out.add((*key, "travel_time", "mean"), f["travel_time"].mean(), "s")


def compare(out: Collector, distances) -> None:
    """compare: d_xy, d_theta, d_gamma mean and sd per comparison and entity (docs/methods.md sec. 3)."""
    out.study = study_of(distances)
    for key, g in groups(distances, ["comparison", "entity"]):
        out.count((*key, "n"), len(g))
        out.mean_sd((*key, "d_xy"), g["d_xy"], "m")
        for c in ("d_theta", "d_gamma"):
            out.mean_sd((*key, c), g[c], "rad", n=True)


def statistics(out: Collector, stats) -> None:
    """stats: per question, the test run, n, statistic, p, Holm p, effect size; or why it was skipped."""
    out.study = study_of(stats)
    ok = stats["status"].eq("ok")
    out.count("tests_run", ok.sum())
    out.count("significant", stats["significant"].fillna(False).astype(bool).sum())
    for _, r in stats.iterrows():
        key = str(r["id"])
        if r["status"] != "ok":
            out.add((key, "status"), r["status"])
            continue
        out.add((key, "test"), r["test"])
        out.count((key, "n"), r["n"])
        for c in ("statistic", "p", "p_holm", "effect_size"):
            out.add((key, c), r[c])
        if r["test"] not in ("describe", "largest_subset"):
            out.add((key, "significant"), bool(r["significant"]))


def reconstruct(out: Collector, reconstruction) -> None:
    """reconstruct: accuracy of the subjects rebuilt from the table (docs/methods.md sec. 8)."""
    out.study = study_of(reconstruction)
    for key, g in groups(reconstruction, ["relative_pose", "kind", "direction", "entity"]):
        out.count((*key, "n"), len(g))
        out.mean_sd((*key, "d_xy"), g["d_xy"], "m")
        out.mean_sd((*key, "d_theta"), g["d_theta"], "rad")
