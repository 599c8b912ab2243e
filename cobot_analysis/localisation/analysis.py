"""One run end to end: read the streams from the bag, compare, goal accuracy (one task per bag)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cobot_analysis.console import warn
from cobot_analysis.localisation.bags import PoseSpec, read_streams
from cobot_analysis.localisation.compare import compare
from cobot_analysis.localisation.goals import StopRule, goal_accuracy, goal_summary, goals_from_stream


@dataclass(frozen=True)
class Options:
    truth: str = "/mocap/pose"
    icp: str = "/icp/pose"
    time: str = "header"
    delay: float | None = None
    window: tuple[float, float] = (0.0, 1.5)
    weights: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    alignment: str = "mean"
    association: str = "interpolate"
    max_gap: float = 0.05
    max_diff: float = 0.01
    distance_window: float = 2.0
    min_samples: int = 20
    goal_topic: str | None = "/goal"
    goals: tuple[tuple[float, float, float], ...] | None = None  # from --goals CSV, for every run
    rule: StopRule = field(default_factory=StopRule)


def analyse_run(task: tuple[str, str, str, Options]) -> dict:
    """``(path, run label, map label, options)`` -> poses, comparison, goals and the per-run row."""
    path, run, map_label, o = task
    path = Path(path)
    specs = {"truth": PoseSpec.parse(o.truth), "icp": PoseSpec.parse(o.icp)}
    if o.goals is None and o.goal_topic:
        specs["goals"] = PoseSpec.parse(o.goal_topic)
    streams = read_streams(path, specs, o.time, optional=("goals",))
    goal_from_bag = "goals" in streams
    truth, icp = streams["truth"], streams["icp"]
    cmp = compare(truth, icp, delay=o.delay, window=o.window, weights=o.weights, alignment=o.alignment,
                  association=o.association, max_gap=o.max_gap, max_diff=o.max_diff,
                  distance_window=o.distance_window, min_samples=o.min_samples, path=path)
    row = {"run": run, "file": str(path), "map": map_label, "truth": o.truth, "icp": o.icp, "time_base": o.time,
           **{k: v for k, v in cmp.summary.items()}}
    goals_df = None
    goals = np.asarray(o.goals, dtype=float) if o.goals is not None else goals_from_stream(streams["goals"]) if goal_from_bag else None
    if goals is not None:
        goal_times = streams["goals"].t if goal_from_bag else None
        goals_df = goal_accuracy(truth, icp, goals, cmp.alignment, cmp.delay.value, o.rule, goal_times)
        row.update(goal_summary(goals_df))
        if not goals_df["found"].all():
            warn(f"{path}: {int((~goals_df['found']).sum())} of {len(goals_df)} goals without a matching stop "
                 f"({goals_df.attrs['n_stops']} stops detected); see --speed-threshold and --min-stop")
        goals_df.insert(0, "run", run)
    samples = cmp.samples.copy()
    samples.insert(0, "run", run)
    poses = [truth.to_frame(run, "truth"), icp.to_frame(run, "icp")]
    return {"run": run, "row": row, "samples": samples, "goals": goals_df, "comparison": cmp, "poses": poses}
