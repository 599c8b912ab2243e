"""Headline numbers of the model stages: fit-ioc (-subjects, -coupled), generate, velocity-commands
(docs/methods.md sec. 5, 6, 10). Each function adds its records to a ``records.Collector``."""

from __future__ import annotations

import json
from typing import Any

from cobot_analysis.metrics.records import Collector, groups


def fit_ioc(out: Collector, weights: dict[str, Any], distances) -> None:
    """fit-ioc: D at the start and fitted, evaluations, fitted weights per fit (``weights``: the document of
    ``weights.json``, as written); distances of each compared model to the means, per fit in
    ``fit-ioc-subjects`` (docs/methods.md sec. 6)."""
    w = json.loads(json.dumps(weights, default=float))  # as Stage.write_json writes it
    for fit, r in (w.get("fits") or {}).items():
        per = r.get("per_target") or []
        out.count((fit, "paths"), len(per))
        out.add((fit, "D", "start"), r.get("start_objective"))
        out.add((fit, "D", "fitted"), r.get("objective"))
        out.count((fit, "evaluations"), r.get("evaluations"))
        out.count((fit, "not_converged"), r.get("failed"))
        out.count((fit, "T_at_bound"), sum(1 for p in per if p.get("T_at_bound")))
        for name in (r.get("spec") or {}).get("fitted", []):
            out.add((fit, "weights", name), (r.get("weights") or {}).get(name))
    if distances is not None:
        keys = ["model", *(["fit"] if out.stage == "fit-ioc-subjects" else []), "carrier"]
        for key, g in groups(distances, keys, {"carrier": "carrier{}"}):
            out.count(("distances", *key, "n"), len(g))
            out.mean_sd(("distances", *key, "d_xy"), g["d_xy"], "m")
            for c in ("d_theta", "d_gamma"):
                out.mean_sd(("distances", *key, c), g[c], "rad")
            out.add(("distances", *key, "D", "mean"), g["D"].mean() if "D" in g else None)


def generate(out: Collector, generated, models: list[str], cases: list) -> None:
    """generate: per model, paths, duration T, optimal cost and end error to the goal of each case
    (``cases``: [condition, start, goal]; a path's trial is ``model_condition``, or ``model``)."""
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


def velocity_commands(out: Collector, commands) -> None:
    """velocity-commands: commands written and the share saturated."""
    out.count("commands", len(commands))
    out.add(("saturated", "share"), commands["saturated"].astype(float).mean())
