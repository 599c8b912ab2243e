"""``generate``, ``fit-ioc`` and ``velocity-commands``: walking-path models (docs/methods.md sec. 5, 6, 10)."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis.cli.app import (PANEL_MODELS, DEFAULT_OUT_PATH, ConventionOpt, ForceOpt, JobsOpt, OutOpt, SchedulerOpt,
                                   SeedOpt, app, count, examples, finished)

MODEL_CHOICES = ("unicycle", "clothoid", "mombaur", "improved", "table", "all")


class Duration(str, Enum):
    free = "free"
    search = "search"
    grid = "grid"


class Optimizer(str, Enum):
    powell = "powell"
    nelder_mead = "nelder-mead"


class Per(str, Enum):
    all = "all"
    subject = "subject"


class GoalChoice(str, Enum):
    auto = "auto"
    design = "design"
    end = "end"


class Format(str, Enum):
    csv = "csv"
    parquet = "parquet"


# ---- generate ----------------------------------------------------------------------------------
def _generate_task(task):
    """Worker: one model run (top-level, picklable)."""
    from cobot_analysis.models import generate

    model, start, goal, weights, kw = task
    return generate(model, start, goal, weights=weights, **kw)


@app.command("generate", rich_help_panel=PANEL_MODELS, epilog=examples(
    "cobot-analysis generate --out walking --start 2 3 0",
    "cobot-analysis generate --out walking --start -1.5,-3,0.5 --model unicycle \\",
    "    --convention continuous",
    "cobot-analysis generate --out walking --start 2 3 0 \\",
    "    --weights walking/fit-ioc/weights.json",
    "cobot-analysis generate --out walking --study walking-2020 --model clothoid"))
def generate_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    model: Annotated[str, typer.Option("--model", "-m", help=f"Model: {', '.join(MODEL_CHOICES)}.")] = "improved",
    weights: Annotated[Optional[str], typer.Option("--weights", "-w", help="Preset (mombaur-2010, walking-2021, table-2022) or weights.json from fit-ioc; default: the model's preset.")] = None,
    start: Annotated[Optional[tuple[float, float, float]], typer.Option("--start", metavar="X Y THETA", help="Start pose (m, m, rad): --start 2 3 0 or --start 2,3,0.")] = None,
    goal: Annotated[Optional[tuple[float, float, float]], typer.Option("--goal", metavar="X Y THETA", help="Goal pose (m, m, rad), as --start (default: the walking goal 0 0 1.5708, pi/2).")] = None,
    study: Annotated[Optional[str], typer.Option("--study", help="Generate all conditions of a study instead of one start: walking-2020.")] = None,
    samples: Annotated[int, typer.Option("--samples", "-n", min=2, help="Samples of each generated trajectory.")] = 500,
    intervals: Annotated[int, typer.Option("--intervals", min=10, help="Intervals of the OC grid (solution resampled to --samples).")] = 100,
    duration: Annotated[Optional[Duration], typer.Option("--duration", help="Duration T: free (decision variable), search (1-D Brent), grid (Mombaur); default per model.")] = None,
    v_nominal: Annotated[float, typer.Option("--v-nominal", min=0.01, help="Nominal speed for the initial duration d / v + 1 s (m/s); clothoid speed.")] = 1.0,
    max_iter: Annotated[int, typer.Option("--max-iter", min=1, help="Iteration limit of the OC solver (a path that hits it is flagged with --study, refused alone).")] = 500,
    means: Annotated[Optional[Path], typer.Option("--means", help="With --study: the mean trajectories whose starts (and, published, ends) the paths take, one path per condition they hold, as fit-ioc compares them (default: OUT/average/ (continuous), else the kind=mean rows of OUT/import-published/; continuous without means: the design's starts).")] = None,
    convention: ConventionOpt = None,
    jobs: JobsOpt = None,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Generate trajectories with a walking-path model (one start/goal, or every condition of a study).

    Writes OUT/generate/generated.parquet (the columns of measured trajectories plus the model's
    velocities, controls and cost, whether each reached its goal and its mean speed) and results.md. A path
    that does not converge or reach its goal is flagged (status column, summary); alone, it is an error.

    --convention (docs/methods.md sec. 11): default, the convention the weights were made under: published
    for the presets (the papers' weights only mean what they mean under it) and the convention recorded in a
    weights.json of fit-ioc; continuous otherwise. published: the authors' node step and duration rule, the
    path as the solution's nodes (--samples, --intervals and --duration do not apply), --study starts and
    ends from the measured means as the authors took them; writes OUT/generate-published/.
    """
    import math

    import pandas as pd

    from cobot_analysis import conventions
    from cobot_analysis.design import WALKING_GOAL
    from cobot_analysis.errors import InputError
    from cobot_analysis.models import MODELS, check_endpoints, refuse_unreached
    from cobot_analysis.models.outputs import GENERATED
    from cobot_analysis.models.presets import load_weights, weights_convention
    from cobot_analysis.models.report import generated_section
    from cobot_analysis.parallel import map_tasks
    from cobot_analysis.schema import write_table
    from cobot_analysis.workspace import Stage

    models = list(MODELS) if model == "all" else [model]
    if model not in MODEL_CHOICES:
        raise InputError(f"unknown model {model!r}", remedy=f"use one of {', '.join(MODEL_CHOICES)}")
    inputs = []
    if weights and any(m != "clothoid" for m in models):
        load_weights(weights, "improved")  # validate before any work
    if weights and Path(weights).is_file():
        inputs.append(Path(weights))
    oc_models = [m for m in models if m != "clothoid"]
    default = weights_convention(weights) if oc_models else None
    if default and convention is None and any(m not in conventions.get(default).oc for m in oc_models):
        default = None  # the weights' convention has no rule for a model asked for (unicycle): ours
    conv = conventions.get(convention or default or "continuous")
    for m in oc_models:
        conv.oc_rule(m)
    if conv.name == "published" and duration is not None:
        raise InputError("--duration does not apply to the published convention (it has the authors' duration rule)",
                         remedy="leave --duration out, or use --convention continuous")
    goal = tuple(goal) if goal is not None else WALKING_GOAL
    if study is not None:
        if study != "walking-2020":
            raise InputError(f"unknown study {study!r}", remedy="use --study walking-2020 or give --start")
        cases = _walking_cases(out, means, conv, goal)
        if isinstance(cases[-1], Path):
            inputs.append(cases.pop())
    elif start is not None:
        cases = [("", tuple(start), goal, math.nan, math.nan)]
    else:
        raise InputError("nothing to generate", remedy="give --start X Y THETA or --study walking-2020")
    for _, s, g, *_ in cases:
        check_endpoints(s, g)
    kw = {"n_samples": samples, "n_intervals": intervals, "duration": duration.value if duration else None,
          "v_nominal": v_nominal, "max_iter": max_iter, "convention": conv.name, "on_failure": "flag"}
    params = {"models": models, "weights": weights, "cases": [c[:3] for c in cases], **kw}
    with Stage(out, conventions.stage_name("generate", conv), inputs=inputs, params=params, force=force) as stage:
        if stage.skipped:
            return
        tasks = [(m, s, g, weights if m != "clothoid" else None,
                  {**kw, "trial": f"{m}_{c}" if c else m, "condition": c, "study": study or "model"})
                 for m in models for c, s, g, *_ in cases]
        frames = map_tasks(_generate_task, tasks, jobs=jobs, scheduler=scheduler, description="generate")
        df = pd.concat(frames, ignore_index=True)
        if study is None:
            refuse_unreached(df)  # one path asked for: exit 2, nothing written
        write_table(df, stage.path("generated.parquet"), GENERATED, n_samples=samples, n_intervals=intervals,
                    convention=conv.name)
        grid = (f"OC grid {intervals} intervals resampled to {samples} samples" if conv.name == "continuous" else
                "the authors' node step and duration rule, paths at their nodes")
        goals = sorted({(round(c[2][0], 3), round(c[2][1], 3), round(math.remainder(c[2][2], 2 * math.pi), 3)) for c in cases})
        lines = [f"## Generated trajectories ({conv.name} convention)", "",
                 f"Models {', '.join(models)}; weights {weights or 'model presets'}; "
                 f"goal{'s' if len(goals) > 1 else ''} {goals[0] if len(goals) == 1 else f'of the {len(goals)} measured means'}; "
                 f"{grid} (docs/methods.md sec. 11: {conv.summary}).", "",
                 *generated_section(df, conv, {f"{m}_{c}" if c else m: (T, v) for m in models for c, _, _, T, v in cases})]
        stage.path("results.md").write_text("\n".join(lines) + "\n")
    ends = df.groupby("trial").tail(1)
    missed = int((~ends["goal_reached"].astype(bool)).sum())
    finished(f"generate ({conv.name})", count(len(ends), "trajectory", "trajectories")
             + (f", {missed} not reaching their goal (results.md)" if missed else ", all at their goal")
             + f", mean speed {ends['mean_speed'].min():.3g}-{ends['mean_speed'].max():.3g} m/s", stage.final_dir / "generated.parquet")


def _walking_cases(out: Path, means: Path | None, conv, goal) -> list:
    """The walking conditions with the start and goal poses of the fit-ioc model comparison
    (``models.report.study_cases``), from the means (--means, else OUT/average/ under the continuous
    convention, else the kind=mean rows of OUT/import-published/); the last item is the file read.
    Continuous convention without any means: the design's start poses."""
    import math

    from cobot_analysis.design import WALKING_CONDITIONS, walking_condition
    from cobot_analysis.errors import InputError
    from cobot_analysis.models.report import study_cases
    from cobot_analysis.workspace import find_input

    path = means
    for name, stages in ((("means.parquet", ["average"]),) if conv.name == "continuous" else ()) + \
            (("trajectories.parquet", ["import-published"]),):
        if path is None:
            try:
                path = find_input(out, name, stages, "--means")
            except InputError:
                if conv.name == "published" and name == "trajectories.parquet":
                    raise
    if path is None:
        return [(c, walking_condition(c).start, goal, math.nan, math.nan) for c in WALKING_CONDITIONS]
    cases = study_cases(_read_trajectories(path), conv, goal, path=path)
    if not cases:
        raise InputError("no mean trajectory of a walking-study condition", path=path,
                         remedy="pass the walking-2020 means (import-published walking-2020, or average) with --means")
    return cases + [Path(path)]


# ---- fit-ioc -----------------------------------------------------------------------------------
def _read_trajectories(path: Path):
    """A trajectories or means table (chosen by the file's metadata)."""
    from cobot_analysis.averaging import MEANS
    from cobot_analysis.schema import TRAJECTORIES, read_table, table_metadata

    try:
        name = table_metadata(path).get("table")
    except Exception:  # noqa: BLE001 - read_table below reports the file properly
        name = None
    return read_table(path, MEANS if name == "means" else TRAJECTORIES)


@app.command("fit-ioc", rich_help_panel=PANEL_MODELS, epilog=examples(
    "cobot-analysis fit-ioc --out walking --max-evaluations 2 --no-compare",
    "cobot-analysis fit-ioc --out walking --max-evaluations 2 \\",
    "    --convention published",
    "cobot-analysis fit-ioc --out walking --per subject --max-evaluations 2 \\",
    "    --start-weights walking/fit-ioc/weights.json --no-compare"))
def fit_ioc_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    means: Annotated[Optional[Path], typer.Option("--means", help="means.parquet (default: OUT/average/, else the kind=mean rows of --trajectories).")] = None,
    trajectories: Annotated[Optional[Path], typer.Option("--trajectories", help="trajectories.parquet (default: OUT/import-published/ or OUT/preprocess/); its trials serve --per subject and the subjects-vs-mean statistics.")] = None,
    model: Annotated[str, typer.Option("--model", "-m", help="improved (walkers, D = d_xy + 0.5 d_gamma), table (D = d_xy + 0.5 d_theta) or coupled (two carriers, scenario-3 means, roles swapped on returns).")] = "improved",
    start_weights: Annotated[Optional[str], typer.Option("--start-weights", help="Preset or weights.json to start from; 'ones' = neutral start (every fitted weight 1).")] = None,
    fit_names: Annotated[Optional[str], typer.Option("--fit", help="Comma-separated weights to fit, the others stay at their start value (default: all but the scale weight and the weights no path depends on: continuous, a0 (scale), a1 (time scale) and b0..b3 (goal constraint); published, a0 and b0).")] = None,
    optimizer: Annotated[Optional[Optimizer], typer.Option("--optimizer", help="Upper-level derivative-free method.")] = Optimizer.powell,
    max_evaluations: Annotated[int, typer.Option("--max-evaluations", min=1, help="Budget of upper-level evaluations per fit.")] = 2000,
    per: Annotated[Per, typer.Option("--per", help="all: one fit over the means; subject: one fit per subject over its trials.")] = Per.all,
    subjects: Annotated[Optional[int], typer.Option("--subjects", min=1, help="With --per subject: fit only the first N subjects.")] = None,
    goal: Annotated[GoalChoice, typer.Option("--goal", help="Goal of each OC problem: design (walking goal 0 0 pi/2), end (last measured pose), auto (design for walking conditions).")] = GoalChoice.auto,
    intervals: Annotated[int, typer.Option("--intervals", min=10, help="Intervals of the OC grid (50: 2-12 mm from a 500-interval solve).")] = 50,
    v_nominal: Annotated[float, typer.Option("--v-nominal", min=0.05, help="Nominal speed (m/s) of T0 = distance / v + 1 s; the free duration T is bounded to (0.4, 2.5) x T0.")] = 1.0,
    compare: Annotated[bool, typer.Option("--compare/--no-compare", help="Compare unicycle, clothoid, Mombaur, published and fitted models.")] = True,
    resume: Annotated[bool, typer.Option("--resume", help="Continue from the checkpoint of an interrupted run with the same inputs and options.")] = False,
    convention: ConventionOpt = None,
    seed: SeedOpt = 0,
    jobs: JobsOpt = None,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Bi-level inverse optimal control: fit the OC cost weights to mean (or per-subject) trajectories.

    Writes OUT/fit-ioc/weights.json (all fits) and weights/<fit>.json (each usable as --weights),
    distances.parquet (per trajectory and model), fits.csv (objective, evaluations and weights per
    fit), figures and results.md. The coupled model writes the same into OUT/fit-ioc-coupled/ (the
    table or walker fit in OUT/fit-ioc/ stays), with the distances of each carrier; --per subject
    writes OUT/fit-ioc-subjects/ (start them from the fit over the means with
    --start-weights OUT/fit-ioc/weights.json). The log of upper-level evaluations is checkpointed in
    OUT/.<stage>.checkpoint after every upper-level iteration (--resume continues from it).
    """
    import json

    import pandas as pd

    from cobot_analysis.console import progress
    from cobot_analysis.design import WALKING_GOAL, walking_condition
    from cobot_analysis.errors import InputError
    from cobot_analysis.models.ioc import IOCSpec, fit, held_weights, pair_targets_from_table, targets_from_table
    from cobot_analysis.models.outputs import IOC_DISTANCES
    from cobot_analysis.models.presets import DEFAULT_PRESET, load_weights, names_for, weights_vector
    from cobot_analysis.models.report import (compare_models, compared_models, duration_flag, weight_limit_flag, figure_boxplots, figure_paths,
                                              statistics, subject_distances, summary_table)
    from cobot_analysis.parallel import default_jobs, executor
    from cobot_analysis.schema import Column, TableSchema, write_table
    from cobot_analysis.workspace import Stage, find_input

    from cobot_analysis import conventions

    if model not in ("improved", "table", "coupled"):
        raise InputError(f"fit-ioc fits the improved, table or coupled model, not {model!r}", remedy="use --model improved, table or coupled")
    conv = conventions.get(convention or "continuous")
    conv.oc_rule(model)
    all_names = names_for(model)
    held = held_weights(model, conv)  # the scale weight and the weights no path depends on (docs/methods.md 6, 11)
    fit_names = fit_names or ",".join(n for n in all_names if n not in held)
    names = tuple(n.strip() for n in fit_names.split(",") if n.strip())
    bad = [n for n in names if n not in all_names]
    if bad or not names:
        raise InputError(f"--fit names {bad or '(none)'} are not weights of the model ({', '.join(all_names)})", remedy="e.g. --fit a1,a2,a4")
    if model == "coupled" and per is Per.subject:
        raise InputError("--per subject is for the walking study", remedy="fit the coupled model over the pair means (--per all)")
    w0 = weights_vector(load_weights(None if start_weights == "ones" else start_weights, model), model)
    if start_weights == "ones":
        for n in names:
            w0[all_names.index(n)] = 1.0
    entity = "table" if model == "table" else "walker"

    # inputs
    traj_path = trajectories
    if traj_path is None:
        try:
            traj_path = find_input(out, "trajectories.parquet", ["import-published", "preprocess"], "--trajectories")
        except InputError:
            traj_path = None
    if means is None and conv.name == "published" and traj_path is not None and traj_path.parent.name == "import-published":
        means = traj_path  # the published convention compares with the authors' own mean block
    if means is None:
        try:
            means = find_input(out, "means.parquet", ["average"], "--means")
        except InputError:
            if traj_path is None:
                raise
    mean_df = _read_trajectories(means) if means is not None else _read_trajectories(traj_path)
    mean_src = means if means is not None else traj_path
    mean_df = mean_df[mean_df["kind"] == "mean"] if "kind" in mean_df else mean_df
    if "scenario" in mean_df and mean_df["scenario"].notna().any():
        mean_df = mean_df[mean_df["scenario"].notna()]  # pair study: per-scenario means, not the pooled 'all' means
    traj_df = _read_trajectories(traj_path) if traj_path is not None else None
    trial_df = traj_df[traj_df["kind"] == "trial"] if traj_df is not None else None

    def goal_for(df) -> tuple | None:
        if goal is GoalChoice.end:
            return None
        if goal is GoalChoice.design:
            return WALKING_GOAL
        try:
            for c in df["condition"].unique():
                walking_condition(str(c))
            return WALKING_GOAL
        except ValueError:
            return None

    if model == "coupled":
        mean_targets = pair_targets_from_table(mean_df, path=mean_src)
        compare = False
    else:
        mean_targets = targets_from_table(mean_df, path=mean_src, entity=entity, goal=goal_for(mean_df), convention=conv)
    fits: dict[str, list] = {}
    if per is Per.all:
        if not mean_targets:
            if model == "coupled":
                raise InputError("no scenario-3 mean path with both carriers (subject1 and subject2, with orientation)",
                                 path=mean_src, remedy="pass the pair study's means (run average on the pair workspace)")
            raise InputError(f"no mean {entity} trajectory with orientation", path=mean_src, remedy="check the input (run average first?)")
        fits["all"] = mean_targets
    else:
        if trial_df is None or trial_df.empty:
            raise InputError("--per subject needs subject trials", path=traj_path or out, remedy="pass --trajectories with kind=trial rows")
        for subject, g in sorted(trial_df.groupby("subject")):
            ts = targets_from_table(g, path=traj_path, entity=entity, goal=goal_for(g), convention=conv)
            if ts:
                fits[str(subject)] = ts
        if subjects:
            fits = dict(list(fits.items())[:subjects])
        if not fits:
            raise InputError("no subject trajectory with orientation", path=traj_path, remedy="check the input table")

    spec = IOCSpec(model=model, start_weights=tuple(map(float, w0)), fitted=names, optimizer=optimizer.value,
                   max_evaluations=max_evaluations, n_intervals=intervals, v_nominal=v_nominal, convention=conv.name,
                   # published: the iteration budget of the authors' DDP (crocoddyl's default maxiter)
                   **({"max_iter": 100} if conv.name == "published" else {}))
    inputs = [p for p in (means, traj_path) if p is not None]
    if start_weights and Path(start_weights).is_file():
        inputs.append(Path(start_weights))
    params = {"spec": spec.__dict__, "per": per.value, "subjects": subjects, "goal": goal.value, "compare": compare, "seed": seed}
    # own stages: the coupled fit never replaces the table fit, nor per-subject fits the fit over the means
    stage_name = conventions.stage_name(
        "fit-ioc-coupled" if model == "coupled" else "fit-ioc-subjects" if per is Per.subject else "fit-ioc", conv)
    checkpoint_dir = Path(out) / f".{stage_name}.checkpoint"
    n_chunks = 4 * (default_jobs() if jobs is None else jobs) if scheduler is None else 8
    with Stage(out, stage_name, inputs=inputs, params=params, force=force) as stage:
        if stage.skipped:
            return
        results = {}
        with executor(jobs, scheduler) as pool, progress() as bar:
            for key, targets in fits.items():
                task = bar.add_task(f"IOC {key} ({len(targets)} paths)", total=max_evaluations, status="")

                def on_eval(n, f, best, task=task):
                    bar.update(task, completed=n, status=f"D = {f:.4f}, best {best:.4f}")

                safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in key)
                results[key] = fit(spec, targets, pool=pool, chunks=n_chunks, checkpoint=checkpoint_dir / f"{safe}.json",
                                   resume=resume, on_evaluation=on_eval)
                bar.update(task, total=results[key].evaluations, completed=results[key].evaluations)
        stage.path("weights.json").write_text(json.dumps({
            "model": model, "convention": conv.name, "weights_order": list(all_names),
            "weights": results["all"].weights if "all" in results else None,
            "fits": {k: r.to_json() for k, r in results.items()}}, indent=2, default=float) + "\n")
        for k, r in results.items():  # each fit also as a file usable with --weights
            stage.path(f"weights/{k}.json").write_text(json.dumps({"convention": conv.name, "weights": r.weights}, indent=2) + "\n")

        # distances: fitted model per trajectory; full model comparison on the means
        coupled = None
        if model == "coupled":  # published and fitted weights, both cold-started, per carrier
            from cobot_analysis.models.presets import PRESETS
            from cobot_analysis.models.report import coupled_distances

            coupled = coupled_distances(spec, mean_targets, {
                "coupled OC (published)": weights_vector(PRESETS["pair-2022"], "coupled"),
                "coupled OC (fitted)": weights_vector(results["all"].weights, "coupled")}, jobs=jobs, scheduler=scheduler)
        rows = []
        for k, r in results.items():
            for t, d in zip(fits[k], r.per_target):
                rows.append({"model": "improved OC (fitted)", "fit": k, "trial": t.trial, "condition": t.condition, "subject": t.subject,
                             "orientation": "", "global_distance": t.global_distance, "d_xy": d["d_xy"], "d_theta": d["d_theta"],
                             "d_gamma": d["d_gamma"], "D": d["D"], "converged": d["success"]})
        dist = pd.DataFrame(rows) if coupled is None else coupled[0]
        angle = spec.angle
        comparison = None
        if compare and "all" in results:
            models = compared_models(conv) if model == "improved" else {"table OC (published)": ("table", "table-2022")}
            models["improved OC (fitted)" if model == "improved" else "table OC (fitted)"] = (
                "improved" if model == "improved" else "table", results["all"].weights)
            # every mean, those without orientation too (their d_xy; the authors compared all 40 walking means)
            compared = targets_from_table(mean_df, path=mean_src, entity=entity, goal=goal_for(mean_df), convention=conv,
                                          unoriented=True)
            # generate's grid (not the lower level's): the same paths as generate --study then compare
            comparison = compare_models(compared, models, angle=angle, jobs=jobs, scheduler=scheduler, convention=conv.name)
            if trial_df is not None and not trial_df.empty and model == "improved":
                trials = targets_from_table(trial_df, path=traj_path, entity=entity)
                comparison = pd.concat([comparison, subject_distances(trials, mean_targets, angle, conv.name)], ignore_index=True)
            dist = pd.concat([dist[dist["fit"] != "all"], comparison], ignore_index=True)
        from cobot_analysis.models.report import orientation_of

        dist["orientation"] = [orientation_of(c) for c in dist["condition"]]
        dist["subject"] = dist["subject"].fillna("")
        dist["convention"] = conv.name
        extra = {"converged": Column("bool", "", "the model's OC solve converged"),
                 "convention": Column("string", "", "published or continuous (docs/methods.md sec. 11)")}
        if coupled is not None:
            extra = {"direction": Column("string", "", "forward or return"),
                     "carrier": Column("int", "", "1 or 2; carrier 1 is Subject 1 forward, Subject 2 on returns (subject column)"),
                     "T": Column("float", "s", "duration of the pair's OC solution (free, within (0.4, 2.5) x T0)"),
                     "T_at_bound": Column("int", "", "-1 / +1: T on the lower / upper bound, 0 inside"), **extra}
        write_table(dist.drop(columns=["converged"]).assign(converged=dist["converged"].astype(bool)),
                    stage.path("distances.parquet"), TableSchema(
                        name=IOC_DISTANCES.name, version=IOC_DISTANCES.version, description=IOC_DISTANCES.description,
                        columns={**IOC_DISTANCES.columns, **extra}), convention=conv.name)
        hist = pd.DataFrame([{"fit": k, "objective": r.objective, "start_objective": r.start_objective,
                              "evaluations": r.evaluations, "iterations": r.iterations, "failed": r.failed, **r.weights}
                             for k, r in results.items()])
        hist.to_csv(stage.path("fits.csv"), index=False)

        # report
        if conv.name == "published":
            lower = ("lower level: the published convention (docs/methods.md sec. 11): explicit Euler at the authors' node "
                     "step, costs summed per node, the authors' start and goal poses; each path's horizon chosen by the authors' "
                     "duration rule (Nelder-Mead on J/T) at the start weights and held during the fit, then the rule run again "
                     "at the fitted weights (the D fitted below); distances after arc-length resampling of both paths, to "
                     + ("the authors' mean block" if Path(mean_src).parent.name == "import-published" else "the means")
                     + f" ({mean_src})")
        else:
            lower = (f"lower level: OC with free duration on {intervals} intervals (continuous convention, docs/methods.md "
                     "sec. 11), warm-started from the solution at the best weights so far")
        lines = [f"## Inverse optimal control ({model} model{', one fit per subject' if per is Per.subject else ''}, "
                 f"{conv.name} convention)", "",
                 f"Bi-level IOC (docs/methods.md sec. 6): upper level {optimizer.value} over log10 of ({', '.join(names)}), "
                 f"bounds 1e-7..1e3, the other weights held at their start value "
                 f"({'neutral start: fitted weights 1' if start_weights == 'ones' else start_weights or 'model preset'}); "
                 f"{lower}; objective D = d_xy + 0.5 d_{angle} averaged over the trajectories (orientation required; "
                 f"goal: {goal.value if conv.name == 'continuous' else 'the authors'})"
                 + ((". gamma of the measured path: " + ("recorded in the data" if conv.comparison.measured_gamma == "data" else
                                                           "from the path (metrics.gamma_from_path)") + "; of the model's path: from the path.")
                    if angle == "gamma" else "; pair study: per-scenario means (the pooled 'all' means left out).")
                 + (" Coupled model: scenario-3 forward and return means, Subject 2 as carrier 1 on returns." if model == "coupled" else ""),
                 "",
                 "| fit | paths | D start | D fitted | evaluations | not converged | " + " | ".join(names) + " |",
                 "|---|---|---|---|---|---|" + "---|" * len(names)]
        start_label = start_weights or DEFAULT_PRESET[model]
        for k, r in results.items():
            lines.append(f"| {k}: start weights ({start_label}) | {len(fits[k])} | {r.start_objective:.4f} |  |  |  | "
                         + " | ".join(f"{w0[all_names.index(n)]:.3g}" for n in names) + " |")
            lines.append(f"| {k}: fitted | {len(fits[k])} | {r.start_objective:.4f} | {r.objective:.4f} | {r.evaluations} | {r.failed} | "
                         + " | ".join(f"{r.weights[n]:.3g}" for n in names) + " |")
        lines.append("")
        for k, r in results.items():
            lines += [("" if per is Per.all else f"Fit {k}: ") + duration_flag(r.per_target, v_nominal, conv.name)
                      + " " + weight_limit_flag(r.weights, names)
                      + (f" Optimiser: {r.message.strip()}" if per is Per.all else ""), ""]
        if conv.name == "published" and "a0" not in names and model != "coupled":
            lines += ["a0 is held at its start value under the published convention: a constant per node, it adds a0 N to J "
                      "on a held horizon and a0 / dt to the duration rule's J / T, so no path depends on it (docs/methods.md "
                      "sec. 11).", ""]
            if r.held_objective is not None:
                lines += [f"{'' if per is Per.all else f'Fit {k}: '}with the horizons held, D = {r.held_objective:.4f} at the "
                          f"fitted weights; the duration rule run again there moves the horizon of {r.horizons_changed} of "
                          f"{len(fits[k])} paths (D = {r.objective:.4f}).", ""]
        if conv.name == "continuous" and model != "coupled" and per is Per.all:
            from cobot_analysis.models.report import pace_lines

            try:
                durations = pd.read_parquet(find_input(out, "durations.parquet", ["import-published"], "--means"))
            except InputError:
                durations = None  # walking study: no published durations (the line says so)
            lines += pace_lines(mean_df, fits["all"], results["all"].per_target, durations)
        if coupled is not None:
            from cobot_analysis.models.report import coupled_section

            durations = None
            try:
                durations = pd.read_parquet(find_input(out, "durations.parquet", ["import-published"], "--means"))
            except InputError:
                pass  # no published durations (e.g. a synthetic pair study): the section says so
            lines += coupled_section(results["all"], coupled, mean_targets, stage, durations)
        if comparison is not None:
            lines += [f"### Model comparison on the mean trajectories ({conv.name} convention)", "",
                      summary_table(comparison, angle, ddof=conv.comparison.sd_ddof),
                      "### Statistics", "", statistics(comparison, list(models)[-1], angle)]
            stage.savefig(figure_boxplots(comparison, angle), "distances_boxplot")
            lines += ["![distances per model](distances_boxplot.png)", ""]
            from cobot_analysis.models import generate

            fitted_w = results["all"].weights
            gen = {"published": [], "fitted": []}
            for t in mean_targets:
                for lab, w in (("published", "walking-2021" if model == "improved" else "table-2022"), ("fitted", fitted_w)):
                    try:
                        gen[lab].append(generate("table" if model == "table" else "improved", t.start, t.goal, weights=w,
                                                 n_samples=len(t.x), convention=conv))
                    except Exception:  # noqa: BLE001 - a failed model run is left out of the figure
                        gen[lab].append(None)
            stage.savefig(figure_paths(mean_targets, gen, "mean (black) vs improved OC: published, fitted"), "paths")
            lines += ["![generated vs mean paths](paths.png)", ""]
        stage.path("results.md").write_text("\n".join(lines) + "\n")
    n_paths = sum(len(fits[k]) for k in results)
    start_d = sum(r.start_objective for r in results.values()) / len(results)
    end_d = sum(r.objective for r in results.values()) / len(results)
    how = ", ".join([conv.name] + (["coupled"] if model == "coupled" else []) + (["per subject"] if per is Per.subject else []))
    fitted = f"{n_paths} paths, D" if len(results) == 1 else f"{len(results)} fits, {n_paths} paths, mean D"
    finished(f"fit-ioc ({how})", f"{fitted} {end_d:.3f} fitted ({start_d:.3f} at the start weights)", stage.final_dir)


# ---- velocity-commands -------------------------------------------------------------------------
@app.command("velocity-commands", rich_help_panel=PANEL_MODELS, epilog=examples(
    "cobot-analysis velocity-commands --out walking --trial clothoid_N1500",
    "cobot-analysis velocity-commands --out walking --trial clothoid_E1515 \\",
    "    --rate 20 --format parquet"))
def velocity_commands_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    generated: Annotated[Optional[Path], typer.Option("--generated", help="generated.parquet (default: OUT/generate/).")] = None,
    trial: Annotated[Optional[str], typer.Option("--trial", help="Generated trajectory to export (default: the only one).")] = None,
    rate: Annotated[float, typer.Option("--rate", min=0.1, help="Command rate f (Hz).")] = 10.0,
    v_max: Annotated[float, typer.Option("--v-max", min=0.0, help="Saturation of the x and y velocity commands (m/s).")] = 0.1,
    omega_max: Annotated[float, typer.Option("--omega-max", min=0.0, help="Saturation of the yaw-rate command (deg/s).")] = 7.0,
    fmt: Annotated[Format, typer.Option("--format", help="Output format.")] = Format.csv,
    force: ForceOpt = False,
) -> None:
    """Export velocity commands for a walking robot following a generated path (docs/methods.md sec. 10).

    v = (p_sim(t+1) - p_real(t)) f in the robot frame, open loop (p_real = p_sim), saturated at
    --v-max (x, y) and --omega-max (yaw). Writes OUT/velocity-commands/commands.csv (or .parquet).
    """
    import math

    from cobot_analysis.errors import InputError
    from cobot_analysis.models.outputs import GENERATED, VELOCITY_COMMANDS
    from cobot_analysis.models.velocity_commands import check_time_law, resample_path, velocity_commands
    from cobot_analysis.schema import read_table, write_table
    from cobot_analysis.workspace import Stage, find_input

    path = generated if generated is not None else find_input(out, "generated.parquet", ["generate", "generate-published"], "--generated")
    df = read_table(path, GENERATED)
    trials = list(dict.fromkeys(df["trial"]))
    if trial is None:
        if len(trials) != 1:
            raise InputError(f"holds {len(trials)} trajectories", path=path, remedy=f"choose one with --trial ({', '.join(trials[:5])}, ...)")
        trial = trials[0]
    g = df[df["trial"] == trial].sort_values("sample")
    if g.empty:
        raise InputError(f"no generated trajectory {trial!r}", path=path, remedy=f"use one of {', '.join(trials[:8])}")
    if g[["time", "x", "y", "theta"]].isna().any().any():
        raise InputError(f"trajectory {trial!r} has NaN time or pose", path=path, remedy="re-run generate")
    check_time_law(g, path=path)
    params = {"trial": trial, "rate": rate, "v_max": v_max, "omega_max": omega_max, "format": fmt.value}
    with Stage(out, "velocity-commands", inputs=[path], params=params, force=force) as stage:
        if stage.skipped:
            return
        sim = resample_path(g["time"], g["x"], g["y"], g["theta"], rate)
        cmd = velocity_commands(sim, rate, v_max=v_max, omega_max=math.radians(omega_max))
        cmd.insert(0, "trial", trial)
        if fmt is Format.csv:
            cmd.to_csv(stage.path("commands.csv"), index=False, float_format="%.6g")
        else:
            write_table(cmd, stage.path("commands.parquet"), VELOCITY_COMMANDS, rate=rate, v_max=v_max,
                        omega_max_deg_s=omega_max)
        stage.path("results.md").write_text(
            f"## Velocity commands\n\nTrajectory {trial} ({g['convention'].iloc[0]} convention, mean speed "
            f"{g['mean_speed'].iloc[0] if 'mean_speed' in g else float('nan'):.2f} m/s) at {rate:g} Hz: {len(cmd)} commands, saturated at "
            f"{v_max:g} m/s and {omega_max:g} deg/s; {cmd['saturated'].mean() * 100:.0f} % of the commands hit a limit.\n")
    finished("velocity-commands", f"{len(cmd)} commands of {trial} at {rate:g} Hz, {cmd['saturated'].mean() * 100:.0f} % saturated",
             stage.final_dir / f"commands.{fmt.value}")
