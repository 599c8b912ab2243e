"""The ``predict`` stage into a workspace (docs/methods.md sec. 7): ``STAGE/`` (``predict`` or
``predict-<label>``, ``-published`` under the published convention) with the predictions, their
summaries, figures and results fragment. Finished (trajectory, setting) results are kept in
``OUT/.predict-work``, shared by every sweep, so an interrupted or extended run resumes."""

from __future__ import annotations

import os
from pathlib import Path

from cobot_analysis import registry
from cobot_analysis.api.prediction import DEFAULT_SETTINGS, assess, prediction_config, select, with_turn_weight
from cobot_analysis.console import info, warn
from cobot_analysis.errors import InputError
from cobot_analysis.stages import Outcome
from cobot_analysis.workspace import Stage, find_input

WORK = ".predict-work"


def predict(out: str | os.PathLike, *, trajectories: str | os.PathLike | None = None, settings: str = DEFAULT_SETTINGS,
            predictors: str = "oc,cv,ctrv", weights: str | None = None, convention: str | None = None, g0: float = 10.0,
            g1: float = 10.0, t_oc: float | None = None, orientation: str = "auto", v_nominal: float = 1.0,
            studies: list[str] | None = None, entities: list[str] | None = None, kind: str = "all", limit: int | None = None,
            every: int = 1, per_condition: int | None = None, stage_name: str = "predict", jobs: int | None = None, scheduler: str | None = None,
            force: bool = False, goal=None, candidates: str | None = None, horizons: str | None = None) -> Outcome:
    """``predict``: predictions.parquet, prediction_windows.parquet, prediction_summary.parquet,
    prediction_comparison.parquet, figures and results.md; with ``horizons`` also the horizon sweep
    (``models.prediction.horizons.write_horizons``)."""
    from cobot_analysis.models.prediction.horizons import parse_horizons

    from cobot_analysis import conventions
    from cobot_analysis.models.presets import weights_convention
    from cobot_analysis.models.prediction.sweep import (PREDICTION_COMPARISON, PREDICTION_SUMMARY, PREDICTION_WINDOWS, PREDICTIONS,
                                                        WorkDir)
    from cobot_analysis.reports import prediction as report
    from cobot_analysis.schema import TRAJECTORIES, read_table

    of_weights = weights_convention(weights) or "continuous"
    config = prediction_config(settings=settings, predictors=predictors, weights=weights, convention=convention,
                                              g0=g0, g1=g1, t_oc=t_oc, orientation=orientation, v_nominal=v_nominal,
                                              goal=goal, candidates=candidates)
    horizon_list = None if horizons is None else parse_horizons(horizons)
    conv = config.convention
    if not registry.PREDICT_LABEL.fullmatch(stage_name):
        raise InputError(f"--stage-name {stage_name!r} is not a predict stage name", remedy="use predict or predict-<label>, e.g. predict-fitted")
    if convention is not None and weights and Path(weights).is_file() and conv.name != of_weights:
        warn(f"predict: the weights {weights} are {of_weights}-convention weights, predicting under --convention {conv.name}")
    directory = registry.directory(stage_name, conv.name)
    inputs = [Path(weights)] if "oc" in config.predictors and weights and Path(weights).is_file() else []
    path = Path(trajectories) if trajectories is not None else find_input(out, "trajectories.parquet", ["preprocess", "import-published"], "--trajectories")
    df = read_table(path, TRAJECTORIES)
    trajs, unpredictable = select(df, config, studies=studies, entities=entities, kind=kind, limit=limit, every=every, path=path,
                                  per_condition=per_condition)
    if unpredictable:
        n0_min = min(n0 for n0, _ in config.settings)
        warn(f"predict: {len(unpredictable)} trajectories left out, fewer than N0 = {n0_min} consecutive finite positions: "
             + ", ".join(unpredictable[:5]) + (" ..." if len(unpredictable) > 5 else ""))
    config = with_turn_weight(config, df, studies=studies, entities=entities)
    if config.goal is not None and "goal" in config.predictors:
        from cobot_analysis.models.prediction.goal import check_reachable

        check_reachable(trajs, config.goal, min(n0 for n0, _ in config.settings), config.weights_for)
    params = {"convention": conv.name, "config": config.params(), "study": studies, "entity": entities, "kind": kind,
              "limit": limit, "every": every, "horizons": horizon_list,
              **({"per_condition": per_condition} if per_condition else {})}  # absent when unused: earlier stages stay current
    work = WorkDir(Path(out) / WORK)  # shared by every sweep: its results are keyed by trajectory, setting and options
    with Stage(out, directory, inputs=[path, *inputs], params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        if force:
            work.clear()  # --force recomputes everything
        n_set, n_pred = len(config.settings), len(config.predictors)
        info(f"predict ({conv.name} convention): {len(trajs)} trajectories x {n_set} setting{'s' * (n_set != 1)} x "
             f"{n_pred} predictor{'s' * (n_pred != 1)}")
        sweep = None if horizon_list is None else (config.settings[0][0], horizon_list)  # the horizon sweep at the first N0
        result = assess(trajs, config, work.root, unpredictable=unpredictable, jobs=jobs, scheduler=scheduler, horizons=sweep)
        stage.result = result  # its own numbers are the stage's metrics.json
        metrics, windows = result.predictions, result.windows
        if result.resumed:
            info(f"predict: {result.resumed} {'trajectory' if result.resumed == 1 else 'trajectories'} resumed from {work.root}")
        skipped = metrics.drop_duplicates(["study", "trial", "entity", "n0", "n_oc"])["n_skipped"].sum()
        if skipped:
            n_traj = metrics.loc[metrics["n_skipped"] > 0, ["study", "trial", "entity"]].drop_duplicates().shape[0]
            warn(f"predict: {skipped} windows of {n_traj} trajectories skipped (NaN positions in the measured past)")
        failed = metrics.loc[metrics["predictor"] == "oc", "n_failed"].sum() if "oc" in config.predictors else 0
        if failed:
            warn(f"predict: {failed} OC windows failed to converge (left out of every predictor's metrics)")
        meta = {"weights": weights or f"walking-2021 (walkers) / {conv.prediction.table_weights} (tables)", "g0": g0, "g1": g1,
                "convention": conv.name}
        stage.write_table("predictions.parquet", metrics, PREDICTIONS, **meta)
        stage.write_table("prediction_windows.parquet", windows, PREDICTION_WINDOWS, **meta)
        stage.write_table("prediction_summary.parquet", result.summary_table, PREDICTION_SUMMARY, **meta)
        stage.write_table("prediction_comparison.parquet", result.comparison, PREDICTION_COMPARISON, **meta)
        example = report.example_trajectory(metrics, trajs, config)
        for stem, fig in report.figures(metrics, example, config).items():
            stage.savefig(fig, stem)
        text = report.results_fragment(metrics, result.summary_table, result.comparison, config, example, unpredictable, directory,
                                       trajectories=trajs)
        other = Path(out) / registry.directory(stage_name, next(n for n in conventions.NAMES if n != conv.name))
        if (other / "prediction_summary.parquet").is_file() and (other / "prediction_comparison.parquet").is_file():
            try:
                both = report.conventions_table([stage.dir, other])
            except InputError as exc:  # e.g. written by an older version: this stage is still complete
                warn(f"predict: no table of both conventions ({exc})")
            else:
                text += "\n" + "\n".join(report.conventions_markdown(both) + ["", f"From this stage and `{other.name}`."]) + "\n"
        if horizon_list:
            text += "\n" + "\n".join(write_horizons(stage, result, config)) + "\n"
        stage.path("results.md").write_text(text)
    return Outcome(stage.final_dir, result)


def write_horizons(stage, result, config) -> list[str]:
    """The horizon sweep (docs/methods.md sec. 7.2) at the first setting's N0, computed by ``assess`` from the
    sweep's own predictions, into ``stage``: ``horizon_errors.parquet``, ``horizon_summary.parquet``,
    ``goal_inference.parquet``, figure ``horizons``; returns the results fragment."""
    from cobot_analysis.models.prediction.horizons import GOAL_INFERENCE, HORIZON_ERRORS, HORIZON_SUMMARY, horizon_summary
    from cobot_analysis.reports.horizons import horizon_figure, horizon_markdown
    errors, inference = result.horizon_errors, result.goal_inference
    summary = horizon_summary(errors)
    stage.write_table("horizon_errors.parquet", errors, HORIZON_ERRORS, convention=config.convention.name)
    stage.write_table("horizon_summary.parquet", summary, HORIZON_SUMMARY, convention=config.convention.name)
    stage.write_table("goal_inference.parquet", inference, GOAL_INFERENCE, convention=config.convention.name)
    stage.savefig(horizon_figure(summary), "horizons")
    return horizon_markdown(summary, inference)
