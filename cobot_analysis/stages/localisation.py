"""Localisation stages into a workspace: ``synth localisation`` (synthetic robot runs as ROS1 / ROS2 /
MCAP bags with their truth) and ``localisation`` (docs/methods.md sec. 9)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from cobot_analysis.errors import InputError
from cobot_analysis.stages import Outcome
from cobot_analysis.workspace import Stage

SYNTH_STAGE = "synth-localisation"
SYNTH_FILES = ("run.bag", "run_ros2", "run.mcap")
STAGE = "localisation"


def synth_localisation(out: str | os.PathLike, *, force: bool = False, **options: Any) -> Outcome:
    """``synth-localisation``: a synthetic robot run written in each format (ros1 -> run.bag, ros2 -> run_ros2/,
    mcap -> run.mcap), with truth.json and goals.csv (``options``: those of ``api.synth_localisation``)."""
    from cobot_analysis import api
    from cobot_analysis.console import track

    o = api.synth_options("localisation", **options)
    with Stage(out, SYNTH_STAGE, params=o, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = api.synth_localisation(stage.dir, **o, progress=track)
    return Outcome(stage.final_dir, result)


def localisation(out: str | os.PathLike, bags: list[str | os.PathLike] | None = None, *, figures: bool = True,
                 jobs: int | None = None, scheduler: str | None = None, force: bool = False, **options: Any) -> Outcome:
    """``localisation``: localisation.parquet (one row per bag), errors.parquet, goals.parquet, poses.parquet,
    figures and results.md; the bags default to the synthetic runs of ``synth localisation`` in ``out``."""
    if not bags:
        base = Path(out) / SYNTH_STAGE
        bags = [base / f for f in SYNTH_FILES if (base / f).exists()]
        if not bags:
            raise InputError("no bag given and no synthetic runs in the workspace", path=base,
                             remedy="pass bag files, or run `cobot-analysis synth localisation` first with the same --out")
    bags = [Path(b) for b in bags]
    for b in bags:
        if not b.exists():
            raise InputError("no such file or directory", path=b, remedy="check the path")
    # a missing bag is refused above, before the heavy imports (pandas, pyarrow)
    from cobot_analysis.api.localisation import analyse, localisation_options
    from cobot_analysis.localisation.poses import POSES
    from cobot_analysis.localisation.tables import ERRORS, GOALS, RUNS
    from cobot_analysis.reports import localisation as report

    opts, runs, labels, maps = localisation_options(bags, **options)
    goals = options.get("goals_csv")
    params = {"options": opts, "labels": labels, "maps": maps, "figures": figures}
    inputs = [*bags, *([Path(goals)] if goals else [])]
    with Stage(out, STAGE, inputs=inputs, params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = analyse(runs, opts, labels, maps, jobs=jobs, scheduler=scheduler)
        stage.result = result  # its own numbers are the stage's metrics.json
        stage.write_table("poses.parquet", result.poses, POSES, time_base=opts.time)
        stage.write_table("localisation.parquet", result.runs, RUNS)
        stage.write_table("errors.parquet", result.errors, ERRORS)
        if result.goals is not None:
            stage.write_table("goals.parquet", result.goals, GOALS, tol_xy=opts.rule.tol_xy, tol_yaw=opts.rule.tol_yaw)
        names = []
        if figures:
            for stem, fig in result.figures().items():
                stage.savefig(fig, stem)
                names.append(f"{stem}.png")
        stage.path("results.md").write_text(report.results_markdown(result.runs, names, opts.rule.tol_xy, opts.rule.tol_yaw))
    return Outcome(stage.final_dir, result)
