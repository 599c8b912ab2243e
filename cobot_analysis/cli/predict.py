"""``cobot-analysis predict``: receding-horizon trajectory prediction assessed on every trajectory
(docs/methods.md sec. 7); the stage is ``stages.predict``, the computation ``api.predict``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis.cli.app import PANEL_MODELS, DEFAULT_OUT_PATH, ForceOpt, JobsOpt, OutOpt, SchedulerOpt, app, examples, finished

@app.command("predict", rich_help_panel=PANEL_MODELS, epilog=examples(
    "cobot-analysis predict --out walking --settings 50:100 --every 50",
    "cobot-analysis predict --out walking --predictors cv,ctrv --kind trial",
    "cobot-analysis predict --out walking --settings 50:100 --every 50 \\",
    "    -w walking/fit-ioc/weights.json --stage-name predict-fitted"))
def predict_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    trajectories: Annotated[Optional[Path], typer.Option("--trajectories", help="trajectories.parquet (default: from preprocess or import-published in OUT).")] = None,
    settings: Annotated[str, typer.Option("--settings", help="(N0, N_OC) pairs in samples, as N0:N_OC,...")] = "25:100,50:100,75:100,50:200",
    predictors: Annotated[str, typer.Option("--predictors", help="Comma-separated: oc (receding-horizon OC), cv (constant velocity), ctrv (constant turn rate and velocity), goal (goal-aware OC, the goal known), goal-inferred (goal-aware OC, the goal inferred among --candidates); docs/methods.md sec. 7.1.")] = "oc,cv,ctrv",
    goal: Annotated[Optional[tuple[float, float, float]], typer.Option("--goal", metavar="X Y THETA", help="Goal pose (m, m, rad) of the goal predictor, in the study frame, as generate --goal. Default: each trajectory's design goal.")] = None,
    candidates: Annotated[Optional[str], typer.Option("--candidates", help="Candidate goals of goal-inferred, as x,y;x,y;... Default: the study's goals.")] = None,
    horizons: Annotated[Optional[str], typer.Option("--horizons", help="Also sweep the horizon at the first setting's N0: samples ahead and/or 'all' (the whole remaining path), e.g. 5,10,25,50,100,200,all (docs/methods.md sec. 7.2).")] = None,
    weights: Annotated[Optional[str], typer.Option("--weights", "-w", help="OC cost weights a0..a3: a preset (walking-2021, table-2022, ...) or a fitted weights.json. Default: walking-2021, and for tables the convention's table preset (published: table-prediction-2022, the authors' predictor; continuous: table-2022).")] = None,
    convention: Annotated[Optional[str], typer.Option("--convention", help="published (the authors' code: one node of 0.1 s per sample, every window from rest, explicit Euler, costs summed per node, cold solves, population sd) or continuous (the real sample period, the start velocity estimated, warm starts, sample sd); docs/methods.md sec. 11. Default: the convention of the weights: published for a preset, the \"convention\" key of a fit-ioc weights.json, else continuous. Stage directory: STAGE-NAME (continuous) or STAGE-NAME-published.")] = None,
    g0: Annotated[float, typer.Option("--g0", help="Weight of the position tracking of the measured past (>= 0).")] = 10.0,
    g1: Annotated[float, typer.Option("--g1", help="Weight of the orientation tracking (0 where theta is missing) (>= 0).")] = 10.0,
    t_oc: Annotated[Optional[float], typer.Option("--t-oc", help="Sampling period T_OC (s): resample each trajectory to it. Default: the trajectory's own sample period.")] = None,
    orientation: Annotated[str, typer.Option("--orientation", help="Give the measured theta to the predictors: auto (unless flagged orientation_missing / implausible_gamma), track (always), ignore (positions only).")] = "auto",
    nominal_speed: Annotated[float, typer.Option("--v-nominal", help="Nominal speed (m/s) giving the assumed duration (path length / speed) of trajectories without a travel time.")] = 1.0,
    study: Annotated[Optional[list[str]], typer.Option("--only-study", help="Only the trajectories of these studies, e.g. walking-2020 (repeatable).")] = None,
    entity: Annotated[Optional[list[str]], typer.Option("--entity", help="Only these entities: walker, subject1, subject2, table (repeatable).")] = None,
    kind: Annotated[str, typer.Option("--kind", help="'trial', 'mean' or 'all' trajectories.")] = "all",
    limit: Annotated[Optional[int], typer.Option("--limit", help="Only the first N trajectories (a quick look) (>= 1).")] = None,
    every: Annotated[int, typer.Option("--every", help="Only every K-th trajectory (in study, trial, entity order): a spread-out subset (>= 1).")] = 1,
    per_condition: Annotated[Optional[int], typer.Option("--per-condition", help="Only K trajectories of each condition (study, entity, condition), evenly spaced in its list, the subjects taking turns across conditions: a stratified subset (before --every and --limit) (>= 1).")] = None,
    stage_name: Annotated[str, typer.Option("--stage-name", help="Stage directory in OUT (NAME-published under the published convention): another name keeps a second sweep (e.g. with fitted weights) beside the first.")] = "predict",
    jobs: JobsOpt = None,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Predict every trajectory at every sample from its recent past and assess the predictions.

    For each trajectory x (N0, N_OC) setting x predictor: delta_xy, delta_theta, d_pred (docs/methods.md
    sec. 7), ADE/FDE; a summary per setting (mean +- sd, Pearson r with the global distance), the
    OC predictor vs the baselines on the same windows (Wilcoxon), figures and results.md.
    Resumable: an interrupted run continues where it stopped, and a run that adds a setting
    computes only that one (finished trajectory x setting results are kept in OUT/.predict-work;
    --force clears them).
    """
    from cobot_analysis.stages.predict import predict

    done = predict(out, trajectories=trajectories, settings=settings, predictors=predictors, weights=weights, convention=convention,
                   g0=g0, g1=g1, t_oc=t_oc, orientation=orientation, v_nominal=nominal_speed, studies=study, entities=entity,
                   kind=kind, limit=limit, every=every, per_condition=per_condition, stage_name=stage_name, jobs=jobs, scheduler=scheduler, force=force,
                   goal=goal, candidates=candidates, horizons=horizons)
    if not done.skipped:
        finished(f"predict ({done.result.config.convention.name})", done.result.summary(), done.directory)
