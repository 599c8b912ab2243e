"""Headline numbers of the model stages: fit-ioc (-subjects, -coupled), generate, velocity-commands
(docs/methods.md sec. 5, 6, 10). Each function adds its records to a ``records.Collector``."""

from __future__ import annotations

import json
from typing import Any

from cobot_analysis.metrics.records import Collector, groups
from cobot_analysis.models.ioc.uncertainty import verdict_category


def fit_ioc(out: Collector, weights: dict[str, Any], distances) -> None:
    """fit-ioc: D at the start and fitted, evaluations, fitted weights per fit (``weights``: the document of
    ``weights.json``, as written), each fitted weight's identifiability verdict (``models.ioc.uncertainty.verdict_category``) and,
    when determined, its bootstrap interval (``weights.<w>.lo`` / ``.hi``); per subject, the test of whether
    the subjects' weights differ (``subjects_differ.<w>``: subjects, Q, p, p_holm, differ); distances of each
    compared model to the means, per fit in ``fit-ioc-subjects``; a single-level fit's cross-check of the
    bi-level weights (``D.bilevel_cross_checked``) and its steps from them (``D.single_level_from_bilevel``,
    docs/methods.md sec. 6, 6.1, 6.3)."""
    w = json.loads(json.dumps(weights, default=float))  # as Stage.write_json writes it
    for fit, r in (w.get("fits") or {}).items():
        per = r.get("per_target") or []
        out.count((fit, "paths"), len(per))
        out.add((fit, "D", "start"), r.get("start_objective"))
        out.add((fit, "D", "fitted"), r.get("objective"))
        if "against_D" in r:  # single-level: the bi-level weights' D, re-solved also from the single-level paths
            out.add((fit, "D", "bilevel_cross_checked"), r["against_D"])
        if "from_bilevel" in r:  # single-level: its steps from the bi-level fit's end
            out.add((fit, "D", "single_level_from_bilevel"), r["from_bilevel"]["objective"])
        out.count((fit, "evaluations"), r.get("evaluations"))
        out.count((fit, "not_converged"), r.get("failed"))
        out.count((fit, "T_at_bound"), sum(1 for p in per if p.get("T_at_bound")))
        u = r.get("uncertainty") or {}
        for name in (r.get("spec") or {}).get("fitted", []):
            out.add((fit, "weights", name), (r.get("weights") or {}).get(name))
            verdict = (u.get("verdicts") or {}).get(name)
            if verdict is None:
                continue
            out.add((fit, "verdict", name), verdict_category(verdict))
            if verdict.startswith("determined"):  # the report gives no interval to a weight the data do not determine
                lo, hi = u["intervals"][name]
                out.add((fit, "weights", name, "lo"), lo)
                out.add((fit, "weights", name, "hi"), hi)
    for row in w.get("subjects_differ") or []:
        key = ("subjects_differ", row["weight"])
        out.count((*key, "subjects"), row.get("subjects"))
        for stat in ("Q", "p", "p_holm"):
            out.add((*key, stat), row.get(stat))
        out.add((*key, "differ"), row.get("differ"))
    if distances is not None:
        keys = ["model", *(["fit"] if out.prefix.startswith("fit-ioc-subjects") else []), "carrier"]  # -single too
        for key, g in groups(distances, keys, {"carrier": "carrier{}"}):
            out.count(("distances", *key, "n"), len(g))
            out.mean_sd(("distances", *key, "d_xy"), g["d_xy"], "m")
            for c in ("d_theta", "d_gamma"):
                out.mean_sd(("distances", *key, c), g[c], "rad")
            out.add(("distances", *key, "D", "mean"), g["D"].mean() if "D" in g else None)


def generate(out: Collector, generated, models: list[str], cases: list) -> None:
    """generate: per model, paths, duration T, optimal cost and end error to the goal of each case
    (``cases``: [condition, start, goal]; a path's trial is ``model_condition``, or ``model``); where the
    table has them, the paths at their goal and the time law (mean speed = path length / T)."""
    import numpy as np

    ends = generated.sort_values("sample").groupby("trial").tail(1)
    goals = {f"{m}_{c}" if c else m: goal for m in models for c, _, goal in cases}
    for key, e in groups(ends, ["model"]):
        out.count((*key, "paths"), len(e))
        out.mean_sd((*key, "T"), e["travel_time"], "s")
        out.mean_sd((*key, "cost"), e["cost"], "")
        known = e[e["trial"].isin(list(goals))]
        if len(known):
            err = [np.hypot(r.x - goals[r.trial][0], r.y - goals[r.trial][1]) for r in known.itertuples()]
            out.add((*key, "end_error", "max"), float(max(err)), "m")
        if "goal_reached" in e:
            out.count((*key, "goal_reached"), int(e["goal_reached"].fillna(False).astype(bool).sum()))
        if "mean_speed" in e:
            out.mean_sd((*key, "mean_speed"), e["mean_speed"], "m/s")
            out.add((*key, "mean_speed", "min"), float(e["mean_speed"].min()), "m/s")


def velocity_commands(out: Collector, commands) -> None:
    """velocity-commands: commands written and the share saturated."""
    out.count("commands", len(commands))
    out.add(("saturated", "share"), commands["saturated"].astype(float).mean())
