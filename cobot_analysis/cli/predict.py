"""``cobot-analysis predict``: receding-horizon trajectory prediction assessed on every trajectory
(docs/methods.md sec. 7): the sweep, its tables, figures and results fragment."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis.cli.app import PANEL_MODELS, DEFAULT_OUT_PATH, ForceOpt, JobsOpt, OutOpt, SchedulerOpt, app, count, examples, finished

STAGE = "predict"
WORK = ".predict-work"
PUBLISHED_SUFFIX = "-published"


def weights_convention(weights: str | None) -> str:
    """The convention of ``--weights`` (docs/methods.md sec. 11): ``published`` for a preset (the
    published weights), the ``"convention"`` key of a fit-ioc weights.json, else ``continuous``."""
    import json

    from cobot_analysis.conventions import NAMES
    from cobot_analysis.errors import InputError
    from cobot_analysis.models.presets import PRESETS

    if weights is None or weights in PRESETS or not Path(weights).is_file():
        return "published"  # a preset (or a missing file, refused later by load_weights)
    try:
        data = json.loads(Path(weights).read_text())
    except ValueError:
        return "continuous"  # not JSON: load_weights names the file
    name = data.get("convention") if isinstance(data, dict) else None
    if name is None:
        return "continuous"
    if name not in NAMES:
        raise InputError(f"its \"convention\" {name!r} is not a convention", path=Path(weights),
                         remedy=f"write one of {', '.join(NAMES)} or pass --convention")
    return name


def stage_dir_name(stage_name: str, convention: str) -> str:
    """The stage directory: ``NAME`` (continuous) or ``NAME-published``, so both sit in one workspace."""
    return stage_name + (PUBLISHED_SUFFIX if convention == "published" else "")


def parse_settings(text: str) -> tuple[tuple[int, int], ...]:
    """``"25:100,50:100"`` -> ((25, 100), (50, 100))."""
    from cobot_analysis.errors import InputError

    out = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        try:
            n0, n_oc = (int(v) for v in part.split(":"))
        except ValueError:
            raise InputError(f"bad setting {part!r}", remedy="write settings as N0:N_OC pairs, e.g. 25:100,50:100") from None
        out.append((n0, n_oc))
    if not out:
        raise InputError("no (N0, N_OC) setting given", remedy="pass e.g. --settings 50:100")
    return tuple(out)


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
    g0: Annotated[float, typer.Option("--g0", min=0.0, help="Weight of the position tracking of the measured past.")] = 10.0,
    g1: Annotated[float, typer.Option("--g1", min=0.0, help="Weight of the orientation tracking (0 where theta is missing).")] = 10.0,
    t_oc: Annotated[Optional[float], typer.Option("--t-oc", help="Sampling period T_OC (s): resample each trajectory to it. Default: the trajectory's own sample period.")] = None,
    orientation: Annotated[str, typer.Option("--orientation", help="Give the measured theta to the predictors: auto (unless flagged orientation_missing / implausible_gamma), track (always), ignore (positions only).")] = "auto",
    nominal_speed: Annotated[float, typer.Option("--v-nominal", help="Nominal speed (m/s) giving the assumed duration (path length / speed) of trajectories without a travel time.")] = 1.0,
    study: Annotated[Optional[list[str]], typer.Option("--only-study", help="Only the trajectories of these studies, e.g. walking-2020 (repeatable).")] = None,
    entity: Annotated[Optional[list[str]], typer.Option("--entity", help="Only these entities: walker, subject1, subject2, table (repeatable).")] = None,
    kind: Annotated[str, typer.Option("--kind", help="'trial', 'mean' or 'all' trajectories.")] = "all",
    limit: Annotated[Optional[int], typer.Option("--limit", min=1, help="Only the first N trajectories (a quick look).")] = None,
    every: Annotated[int, typer.Option("--every", min=1, help="Only every K-th trajectory (in study, trial, entity order): a spread-out subset.")] = 1,
    stage_name: Annotated[str, typer.Option("--stage-name", help="Stage directory in OUT (NAME-published under the published convention): another name keeps a second sweep (e.g. with fitted weights) beside the first.")] = STAGE,
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

    from cobot_analysis import conventions
    from cobot_analysis.console import info, warn
    from cobot_analysis.errors import InputError
    from cobot_analysis.models.presets import load_weights
    from cobot_analysis.models.prediction.sweep import (PREDICTION_COMPARISON, PREDICTION_SUMMARY, PREDICTION_WINDOWS, PREDICTIONS,
                                             SweepConfig, WorkDir, compare_table, predictable_windows, run_sweep, summary_table,
                                             trajectories_from_table)
    from cobot_analysis.schema import TRAJECTORIES, read_table, write_table
    from cobot_analysis.workspace import Stage, find_input

    of_weights = weights_convention(weights)
    conv = conventions.get(convention if convention is not None else of_weights)
    if not re.fullmatch(r"predict[-_A-Za-z0-9]*", stage_name):
        raise InputError(f"--stage-name {stage_name!r} is not a predict stage name", remedy="use predict or predict-<label>, e.g. predict-fitted")
    if convention is not None and weights and Path(weights).is_file() and conv.name != of_weights:
        warn(f"predict: the weights {weights} are {of_weights}-convention weights, predicting under --convention {conv.name}")
    directory = stage_dir_name(stage_name, conv.name)

    from cobot_analysis.models.prediction.goal import check_goal, parse_candidates
    from cobot_analysis.models.prediction.horizons import parse_horizons, write_horizons

    config = SweepConfig(settings=parse_settings(settings), predictors=tuple(p.strip() for p in predictors.split(",") if p.strip()),
                         weights=weights, g0=g0, g1=g1, t_oc=t_oc, nominal_speed=nominal_speed, orientation=orientation,
                         convention=conv, goal=None if goal is None else check_goal(goal),
                         candidates=None if candidates is None else parse_candidates(candidates))
    horizon_list = None if horizons is None else parse_horizons(horizons)
    if kind not in ("trial", "mean", "all"):
        raise InputError(f"unknown --kind {kind!r}", remedy="use trial, mean or all")
    inputs = []
    if "oc" in config.predictors:
        for name in {config.weights_for(e) for e in ("walker", "table")}:
            load_weights(name, "improved")  # unknown preset / bad file: one-line error before any work
        if weights and Path(weights).is_file():
            inputs.append(Path(weights))
    path = trajectories if trajectories is not None else find_input(out, "trajectories.parquet", ["preprocess", "import-published"], "--trajectories")
    df = read_table(path, TRAJECTORIES)
    if study:
        df = df[df["study"].isin(study)]
    if entity:
        df = df[df["entity"].isin(entity)]
    if kind != "all":
        df = df[df["kind"] == kind]
    trajs = trajectories_from_table(df, config, path)
    trajs = trajs[::every]
    if limit:
        trajs = trajs[:limit]
    n0_min = min(n0 for n0, _ in config.settings)
    unpredictable = [t.label for t in trajs if not predictable_windows(t, n0_min)]
    trajs = [t for t in trajs if predictable_windows(t, n0_min)]
    if not trajs:
        raise InputError(f"no window can be predicted: no trajectory has {n0_min} consecutive samples with finite positions",
                         path=path, remedy="check the trajectories (gaps left by preprocess) or lower N0")
    if unpredictable:
        warn(f"predict: {len(unpredictable)} trajectories left out, fewer than N0 = {n0_min} consecutive finite positions: "
             + ", ".join(unpredictable[:5]) + (" ..." if len(unpredictable) > 5 else ""))
    params = {"convention": conv.name, "config": config.params(), "study": study, "entity": entity, "kind": kind,
              "limit": limit, "every": every}
    work = WorkDir(Path(out) / WORK)  # shared by every sweep: its results are keyed by trajectory, setting and options
    with Stage(out, directory, inputs=[path, *inputs], params=params, force=force) as stage:
        if stage.skipped:
            return
        if force:
            work.clear()  # --force recomputes everything
        info(f"predict ({conv.name} convention): {len(trajs)} trajectories x {len(config.settings)} settings x "
             f"{len(config.predictors)} predictors")
        metrics, windows, resumed = run_sweep(trajs, config, work, jobs=jobs, scheduler=scheduler)
        if resumed:
            info(f"predict: {resumed} trajectories resumed from {work.root}")
        skipped = metrics.drop_duplicates(["study", "trial", "entity", "n0", "n_oc"])["n_skipped"].sum()
        if skipped:
            n_traj = metrics.loc[metrics["n_skipped"] > 0, ["study", "trial", "entity"]].drop_duplicates().shape[0]
            warn(f"predict: {skipped} windows of {n_traj} trajectories skipped (NaN positions in the measured past)")
        failed = metrics.loc[metrics["predictor"] == "oc", "n_failed"].sum() if "oc" in config.predictors else 0
        if failed:
            warn(f"predict: {failed} OC windows failed to converge (left out of every predictor's metrics)")
        summary = summary_table(metrics, conv)
        comparison = compare_table(metrics, windows, conv)
        meta = {"weights": weights or f"walking-2021 (walkers) / {conv.prediction.table_weights} (tables)", "g0": g0, "g1": g1,
                "convention": conv.name}
        write_table(metrics, stage.path("predictions.parquet"), PREDICTIONS, **meta)
        write_table(windows, stage.path("prediction_windows.parquet"), PREDICTION_WINDOWS, **meta)
        write_table(summary, stage.path("prediction_summary.parquet"), PREDICTION_SUMMARY, **meta)
        write_table(comparison, stage.path("prediction_comparison.parquet"), PREDICTION_COMPARISON, **meta)
        example = example_trajectory(metrics, trajs, config)
        for stem, fig in figures(metrics, example, config).items():
            stage.savefig(fig, stem)
        text = results_fragment(metrics, summary, comparison, config, example, unpredictable, directory)
        other = Path(out) / stage_dir_name(stage_name, next(n for n in conventions.NAMES if n != conv.name))
        if (other / "prediction_summary.parquet").is_file() and (other / "prediction_comparison.parquet").is_file():
            from cobot_analysis.models.prediction.report import conventions_markdown, conventions_table

            try:
                both = conventions_table([stage.dir, other])
            except InputError as exc:  # e.g. written by an older version: this stage is still complete
                warn(f"predict: no table of both conventions ({exc})")
            else:
                text += "\n" + "\n".join(conventions_markdown(both) + [f"", f"From this stage and `{other.name}`."]) + "\n"
        if horizon_list:
            text += "\n" + "\n".join(write_horizons(stage, trajs, config, horizon_list, jobs=jobs, scheduler=scheduler)) + "\n"
        stage.path("results.md").write_text(text)
    n_windows = int(metrics.drop_duplicates(["study", "trial", "entity", "n0", "n_oc"])["n_windows"].sum())
    finished(f"predict ({conv.name})", f"{count(len(trajs), 'trajectory', 'trajectories')} x {count(len(config.settings), 'setting')} x "
             f"{count(len(config.predictors), 'predictor')}, {n_windows} windows per predictor", stage.final_dir)


# ---- figures and report -----------------------------------------------------------------------
def figure_setting(config) -> tuple[int, int]:
    return (50, 100) if (50, 100) in config.settings else config.settings[0]


def example_trajectory(metrics, trajs, config):
    """The trajectory with the median delta_xy of the first predictor at the figure setting."""
    import numpy as np

    n0, n_oc = figure_setting(config)
    m = metrics[(metrics["n0"] == n0) & (metrics["n_oc"] == n_oc) & (metrics["predictor"] == config.predictors[0])]
    m = m[np.isfinite(m["delta_xy"])].sort_values("delta_xy")
    row = m.iloc[len(m) // 2]
    return next(t for t in trajs if (t.study, t.trial, t.entity) == (row["study"], row["trial"], row["entity"]))


def figures(metrics, traj, config) -> dict:
    """The stage's figures by file stem: every prediction of one trajectory (``prediction_overlay``),
    the predictions at six samples k (``prediction_at_k``) and the error against the global distance
    (``prediction_error_vs_distance``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.collections import LineCollection
    from matplotlib.legend_handler import HandlerTuple

    from cobot_analysis.models.prediction.predictor import make_predictor
    from cobot_analysis.models.prediction.sweep import predictor_options

    n0, n_oc = figure_setting(config)
    preds = {}
    for name in config.predictors:
        options = predictor_options(name, traj, config)
        preds[name] = make_predictor(name, n0, n_oc, traj.dt, convention=config.convention, **options).predict_offline(traj.seen)
    xy = traj.poses[:, :2]
    colours = {"oc": "tab:blue", "cv": "tab:orange", "ctrv": "tab:green", "goal": "tab:red", "goal-inferred": "tab:purple"}
    conv = config.convention
    span = np.nanmax(xy, axis=0) - np.nanmin(xy, axis=0)
    aspect = float(np.clip(span[1] / max(span[0], 1e-9), 0.3, 1.5))  # of the equal-aspect path panels
    out = {}

    fig, axes = plt.subplots(1, len(preds), figsize=(4.2 * len(preds), 4.2 * aspect + 1.2), squeeze=False, layout="constrained")
    for ax, (name, P) in zip(axes[0], preds.items()):
        ok = np.isfinite(P[:, 0, 0])
        ax.plot(*xy.T, color="0.6", lw=2.5, label="recorded", zorder=1)
        ax.add_collection(LineCollection(P[ok, :, :2], colors=colours[name], linewidths=0.5, alpha=0.4, zorder=2,
                                         label=f"{name}: prediction from each k"))
        ax.set_title(f"{name}: all {ok.sum()} predictions")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="best", fontsize=7)
    step = f"OC nodes of {conv.prediction.node_dt:g} s" if conv.prediction.node_dt else f"T_OC = {traj.dt * 1000:.1f} ms"
    fig.suptitle(f"{traj.label}, N0 = {n0}, N_OC = {n_oc}, {step}, {conv.name} convention")
    out["prediction_overlay"] = fig

    ks = np.linspace(n0 - 1, len(xy) - 1 - (n_oc - n0) // 2, 6).astype(int)
    fig, axes = plt.subplots(2, 3, figsize=(12, 2 * 4 * aspect + 1.6), squeeze=False, layout="constrained")
    for ax, k in zip(axes.ravel(), ks):
        ax.plot(*xy.T, color="0.8", lw=1, label="recorded path")
        ax.plot(*xy[k - n0 + 1: k + 1].T, color="k", lw=2.5, label="measured past (N0 samples)")
        ax.plot(*xy[k: k + n_oc - n0 + 1].T, color="k", ls="--", lw=1, label="recorded future (N_OC - N0 samples)")
        for name, P in reversed(preds.items()):  # the first predictor (oc) drawn on top
            ax.plot(*P[k - n0 + 1][:, :2].T, color=colours[name], lw=1.5, label=f"{name} prediction")
        ax.set_title(f"k = {k} ({100 * k / (len(xy) - 1):.0f} %)")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    order = [*range(3), *reversed(range(3, len(labels)))]  # the predictors in the order given
    fig.legend([handles[i] for i in order], [labels[i] for i in order], loc="outside lower center", ncol=3 + len(preds),
               fontsize=8)
    fig.suptitle(f"Prediction at k: {traj.label}, N0 = {n0}, N_OC = {n_oc}, {conv.name} convention")
    out["prediction_at_k"] = fig

    m = metrics[(metrics["n0"] == n0) & (metrics["n_oc"] == n_oc)]
    orientations = sorted(m["start_orientation"].replace("", "all").unique())
    fig, axes = plt.subplots(1, len(preds), figsize=(4.2 * len(preds), 4.2), squeeze=False, sharey=True, layout="constrained")
    series = {}
    for ax, name in zip(axes[0], preds):
        mp = m[m["predictor"] == name]
        for i, (orient, g) in enumerate(mp.groupby(mp["start_orientation"].replace("", "all"), sort=True)):
            c = g.groupby("condition").agg(d=("global_distance", "mean"), mean=("delta_xy", "mean"),
                                           lo=("delta_xy", "min"), hi=("delta_xy", "max")).sort_values("d")
            colour = f"C{orientations.index(orient)}"
            line, = ax.plot(c["d"], c["mean"], marker="o", ms=3, color=colour, label=orient)
            band = ax.fill_between(c["d"], c["lo"], c["hi"], color=colour, alpha=0.15, label=orient)
            series.setdefault(orient, (line, band))
        ax.set_title(name)
        ax.set_xlabel("global distance (m)")
    axes[0, 0].set_ylabel("delta_xy per condition, mean and min-max (m)")
    fig.legend(list(series.values()), list(series), handler_map={tuple: HandlerTuple(ndivide=1)}, title="start orientation",
               loc="outside right center", fontsize=8)
    fig.suptitle(f"Prediction error vs global distance, N0 = {n0}, N_OC = {n_oc}, {conv.name} convention")
    out["prediction_error_vs_distance"] = fig
    return out


def _fmt(v, digits=3) -> str:
    import math

    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"


def _p(v) -> str:
    import math

    return "n/a" if math.isnan(v) else ("< 0.001" if v < 1e-3 else f"{v:.3f}")


def results_fragment(metrics, summary, comparison, config, example, unpredictable=(), stage_name: str = STAGE) -> str:
    """Markdown fragment of the stage (assembled into docs/results.md)."""
    import numpy as np

    traj = metrics.drop_duplicates(["study", "trial", "entity"])
    studies = ", ".join(f"{s} ({n})" for s, n in traj.groupby("study").size().items())
    no_theta = int((~traj["orientation"]).sum())
    untracked = int((traj["orientation"] & ~traj["theta_tracked"]).sum())
    assumed = traj[traj["duration_source"] == "nominal_speed"]
    conv = config.convention
    period = traj["sample_period"]
    sampled = (f"{'resampled every %g s' % config.t_oc if config.t_oc else 'the sample period of each trajectory'}, "
               f"median {1000 * period.median():.1f} ms (range {1000 * period.min():.1f}-{1000 * period.max():.1f} ms)")
    lines = [
        "## Trajectory prediction (docs/methods.md sec. 7)" + ("" if stage_name == STAGE else f", stage {stage_name}"), "",
        f"Convention: **{conv.name}** (docs/methods.md sec. 11): {conv.summary}.",
        f"{len(traj)} trajectories: {studies}; entities " + ", ".join(f"{e} ({n})" for e, n in traj.groupby("entity").size().items()) + ".",
        f"Predictors: {', '.join(config.predictors)}; settings (N0, N_OC): {', '.join(f'({a}, {b})' for a, b in config.settings)}; "
        f"OC weights {config.weights or f'walking-2021 (walkers) / {conv.prediction.table_weights} (tables)'}, g0 = {config.g0}, g1 = {config.g1}.",
        (f"T_OC: {sampled}. " if conv.prediction.node_dt is None else
         f"OC nodes: one of {conv.prediction.node_dt:g} s per sample whatever the sample period ({sampled}). ")
        + (f"{len(assumed)} trajectories have no recorded duration: assumed duration = path length / {config.nominal_speed:g} m/s "
           f"(median {assumed['duration'].median():.2f} s). " if len(assumed) else "Durations: recorded travel times. ")
        + (f"{no_theta} trajectories have no orientation" if no_theta else "")
        + (f"; {untracked} have one that was not used (orientation mode {config.orientation}: flagged "
           "implausible or ignored)" if untracked else "")
        + (": predicted from positions only (OC g1 = 0, start heading = direction of travel), no delta_theta."
           if no_theta or untracked else ""),
    ]
    first = metrics.drop_duplicates(["study", "trial", "entity", "n0", "n_oc"])
    skipped = int(first["n_skipped"].sum())
    failed = int(metrics.loc[metrics["predictor"] == "oc", "n_failed"].sum()) if "oc" in config.predictors else 0
    lines.append(f"Windows: {int(first['n_windows'].sum())} per predictor, {skipped} skipped (NaN positions), "
                 f"{failed} failed OC solves; metrics use the windows every predictor predicted."
                 + (f" {len(unpredictable)} trajectories left out (no N0 consecutive finite positions)." if unpredictable else ""))
    lines += ["", "### Errors per setting (mean +- sd over trajectories; r = Pearson correlation with the global distance)", "",
              "| N0 | N_OC | predictor | delta_xy (m) | delta_theta (rad) | d_pred (m) | ADE (m) | FDE (m) | r(delta_xy, D) |",
              "|---|---|---|---|---|---|---|---|---|"]
    for (n0, n_oc, pred), g in summary.groupby(["n0", "n_oc", "predictor"], sort=True):
        cell = {r["metric"]: r for _, r in g.iterrows()}
        vals = [f"{_fmt(cell[k]['mean'])} +- {_fmt(cell[k]['sd'])}" for k in ("delta_xy", "delta_theta", "d_pred", "ade", "fde")]
        r = cell["delta_xy"]
        lines.append(f"| {n0} | {n_oc} | {pred} | " + " | ".join(vals) + f" | {_fmt(r['pearson_r'], 2)} (p {_p(r['pearson_p'])}) |")
    if len(comparison):
        lines += ["", "### OC predictor vs baselines on the same windows (delta_xy; Wilcoxon signed-rank over trajectories)", "",
                  "| N0 | N_OC | baseline | group | n | OC median (m) | baseline median (m) | median OC - baseline (m) | OC better (trajectories) | OC better (windows) | W | p | r |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for _, c in comparison.iterrows():
            if c["baseline"] != "cv" and c["group"] != "all":
                continue  # the other baselines: overall only (every group is in prediction_comparison.parquet)
            lines.append(f"| {c['n0']} | {c['n_oc']} | {c['baseline']} | {c['group']} | {c['n']} | {_fmt(c['oc_median'])} | "
                         f"{_fmt(c['baseline_median'])} | {_fmt(c['median_difference'])} | {100 * c['oc_wins']:.0f} % | "
                         f"{100 * c['oc_wins_windows']:.0f} % | {_fmt(c['wilcoxon_w'], 0)} | {_p(c['wilcoxon_p'])} | {_fmt(c['effect_r'], 2)} |")
        lines += ["", "r: matched-pairs rank-biserial correlation, > 0 when the OC predictor has the smaller error."]
    if "oc" in config.predictors:
        from cobot_analysis.models.prediction.report import paper_rows

        paper = paper_rows(metrics, conv)
        start = ("started from rest at the window's first sample (published convention)" if conv.prediction.start == "rest"
                 else "started from the velocity estimated at the window's first sample")
        lines += ([""] + paper if paper else []) + [
                  "", "What the OC prediction is (the reading of the tables above): beyond the measured past the window "
                  "carries only control costs, so the predicted path is the walker coasting from its state at sample k "
                  "with constant body-frame velocities (v_forw, v_orth) and yaw rate omega, an arc of curvature "
                  "omega / speed (`OCPredictor`). The state at k is a smoothed fit of the past (tracking g0, g1 against "
                  f"the control weights a1-a3) {start}. Where the "
                  "orientation is tracked, its gait oscillation and any turn on the spot enter omega (a3 is nearly zero "
                  "with the walking weights), and the arc curls away from the path: compare the 'theta tracked' and "
                  "'positions only' rows. The constant-velocity baseline extrapolates the last measured displacement "
                  "and has no such lag."]
    lines += ["", f"Figures: `prediction_overlay.png` (all predictions of {example.label}), `prediction_at_k.png`, "
              "`prediction_error_vs_distance.png` (per start orientation, min-max bands over trajectories of a condition)."]
    return "\n".join(lines) + "\n"
