"""Headline numbers of the data stages: the synthetic studies, import, import-published, preprocess
(docs/methods.md sec. 1-2). Each function adds its records to a ``records.Collector``."""

from __future__ import annotations

import json
from typing import Any

from cobot_analysis.metrics.records import Collector, flatten, groups, study_of

LOCALISATION_STUDY = "localisation"


def synth_study(out: Collector, study: str | None, recordings: int, entities: dict[str, int], truth) -> None:
    """synth-walking / synth-pairs: design counts (``entities``: subjects or pairs -> how many), true
    travel times and paths, planted losses (``truth``: the ``truth_trials`` table)."""
    out.study = study
    out.count("recordings", recordings)
    for name, n in entities.items():
        out.count(name, n)
    for key, g in groups(truth, ["entity", "segment", "scenario"], {"scenario": "s{}"}):
        out.count((*key, "n"), len(g))
        out.mean_sd((*key, "travel_time"), g["travel_time"], "s")
        out.add((*key, "path_length", "mean"), g["path_length"].mean(), "m")
        out.add((*key, "peak_speed", "mean"), g["peak_speed"].mean(), "m/s")
        out.count((*key, "orientation_lost"), g["orientation_lost"].sum())
        if "optimal" in g and g["optimal"].notna().any():
            out.add((*key, "optimal", "share"), g["optimal"].astype(float).mean())


def synth_localisation(out: Collector, truth: dict[str, Any], bags: int) -> None:
    """synth-localisation: length of the run, poses, goals and the realised ICP noise (``truth``: truth.json)."""
    out.study = LOCALISATION_STUDY
    out.add("distance", truth.get("distance"), "m")
    out.add("duration", truth.get("duration"), "s")
    out.count("mocap_poses", truth.get("n_mocap"))
    out.count("icp_poses", truth.get("n_icp"))
    out.count("goals", len(truth.get("goals", [])))
    out.add("delay", truth.get("delay"), "s")
    for axis, r in (truth.get("noise_realised") or {}).items():
        out.add(("noise", axis, "rmse"), r.get("rmse"), "rad" if axis == "yaw" else "m")
    out.count("bags", bags)


def import_markers(out: Collector, trials, marker_samples: int) -> None:
    """import: recordings, frames, marker samples, sampling rate."""
    out.study = study_of(trials)
    out.count("recordings", len(trials))
    out.count("frames", trials["n_frames"].sum())
    out.add(("rate", "median"), trials["rate"].median(), "Hz")
    out.count("marker_samples", marker_samples)


def import_published(out: Collector, trajectories, facts: dict[str, Any]) -> None:
    """import-published: every fact the stage checked against the dataset README, as ``facts.json`` holds
    them (JSON values; what JSON lacks as text)."""
    out.study = study_of(trajectories)
    for k, v in json.loads(json.dumps(facts, default=str)).items():
        flatten(out, ("facts", k), v)


def preprocess(out: Collector, trajectories, gaps) -> None:
    """preprocess: trajectories per entity, travel times, distances, quality flags and marker gaps (``gaps``:
    None when the stage wrote none)."""
    t = trajectories[trajectories["sample"] == 0]
    out.study = study_of(t)
    out.count("trajectories", len(t))
    for key, g in groups(t, ["entity", "direction"]):
        out.count((*key, "trajectories"), len(g))
        out.mean_sd((*key, "travel_time"), g["travel_time"], "s")
        out.mean_sd((*key, "travelled_distance"), g["travelled_distance"], "m")
    flags: dict[str, int] = {}
    for q in t["quality"].fillna(""):
        for f in filter(None, str(q).split(";")):
            flags[f] = flags.get(f, 0) + 1
    for f, n in sorted(flags.items()):
        out.count(("quality", f), n)
    if gaps is not None:
        filled = gaps["filled"].astype(bool)
        out.count(("gaps", "total"), len(gaps))
        out.count(("gaps", "filled"), filled.sum())
        out.count(("gaps", "open"), (~filled).sum())
        out.count(("gaps", "open_frames"), gaps.loc[~filled, "n_frames"].sum())
