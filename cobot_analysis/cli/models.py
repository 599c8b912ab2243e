"""``generate``, ``fit-ioc`` and ``velocity-commands``: walking-path models (docs/methods.md sec. 5, 6, 10)."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis.cli.app import (PANEL_MODELS, DEFAULT_OUT_PATH, ConventionOpt, ForceOpt, JobsOpt, OutOpt, SchedulerOpt,
                                   SeedOpt, app, examples, finished)

MODEL_CHOICES = ("unicycle", "clothoid", "mombaur", "improved", "table", "all")  # api.models.MODEL_CHOICES


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
@app.command("generate", rich_help_panel=PANEL_MODELS, epilog=examples(
    "cobot-analysis generate --out walking --start 2 3 0",
    "cobot-analysis generate --out walking --start -1.5,-3,0.5 --model unicycle \\",
    "    --convention continuous",
    "cobot-analysis generate --out walking --start 2 3 0 \\",
    "    --weights walking/fit-ioc/weights.json",
    "cobot-analysis generate --out walking --study walking-2020 --model clothoid"))
def generate_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    model: Annotated[Optional[str], typer.Option("--model", "-m", help=f"Model: {', '.join(MODEL_CHOICES)}; default improved (table with --study pair-carriage-2022).")] = None,
    weights: Annotated[Optional[str], typer.Option("--weights", "-w", help="Preset (mombaur-2010, walking-2021, table-2022) or weights.json from fit-ioc; default: the model's preset.")] = None,
    start: Annotated[Optional[tuple[float, float, float]], typer.Option("--start", metavar="X Y THETA", help="Start pose (m, m, rad): --start 2 3 0 or --start 2,3,0.")] = None,
    goal: Annotated[Optional[tuple[float, float, float]], typer.Option("--goal", metavar="X Y THETA", help="Goal pose (m, m, rad), as --start (default: the walking goal 0 0 1.5708, pi/2).")] = None,
    study: Annotated[Optional[str], typer.Option("--study", help="Generate every mean of a study instead of one start: walking-2020 (its 40 conditions) or pair-carriage-2022 (its per-scenario table means, start and goal their first and last poses).")] = None,
    samples: Annotated[int, typer.Option("--samples", "-n", help="Samples of each generated trajectory (>= 2).")] = 500,
    intervals: Annotated[int, typer.Option("--intervals", help="Intervals of the OC grid (solution resampled to --samples) (>= 10).")] = 100,
    duration: Annotated[Optional[Duration], typer.Option("--duration", help="Duration T: free (decision variable), search (1-D Brent), grid (Mombaur); default per model.")] = None,
    v_nominal: Annotated[float, typer.Option("--v-nominal", help="Nominal speed for the initial duration d / v + 1 s (m/s); clothoid speed (>= 0.01).")] = 1.0,
    max_iter: Annotated[int, typer.Option("--max-iter", help="Iteration limit of the OC solver (a path that hits it is flagged with --study, refused alone) (>= 1).")] = 500,
    means: Annotated[Optional[Path], typer.Option("--means", help="With --study: the mean trajectories whose starts (and, published or pair study, ends) the paths take, one path per mean they hold, as fit-ioc compares them (default: OUT/average/ (continuous), else the kind=mean rows of OUT/import-published/; walking, continuous, without means: the design's starts).")] = None,
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
    from cobot_analysis.stages import models

    done = models.generate(out, model=model, weights=weights, start=start, goal=goal, study=study, samples=samples,
                           intervals=intervals, duration=duration.value if duration else None, v_nominal=v_nominal,
                           max_iter=max_iter, means=means, convention=convention, jobs=jobs, scheduler=scheduler, force=force)
    if not done.skipped:
        finished(f"generate ({done.result.convention})", done.result.summary(where=str(done.directory / "results.md")),
                 done.directory / "generated.parquet")


# ---- fit-ioc -----------------------------------------------------------------------------------
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
    fit_names: Annotated[Optional[str], typer.Option("--fit", help="Comma-separated weights to fit, the others stay at their start value (default: all but the scale weights and the weights no path depends on: continuous, a0 (scale), a1 (time scale) and b0..b3 (goal constraint); published, a0 and b0; and a5, a6 (the Mombaur model's) but for the coupled model).")] = None,
    optimizer: Annotated[Optional[Optimizer], typer.Option("--optimizer", help="Upper-level derivative-free method.")] = Optimizer.powell,
    max_evaluations: Annotated[int, typer.Option("--max-evaluations", help="Budget of upper-level evaluations per fit (--method single-level: of its steps, when below its own number) (>= 1).")] = 2000,
    per: Annotated[Per, typer.Option("--per", help="all: one fit over the means; subject: one fit per subject over its trials.")] = Per.all,
    subjects: Annotated[Optional[int], typer.Option("--subjects", help="With --per subject: fit only the first N subjects (>= 1).")] = None,
    goal: Annotated[GoalChoice, typer.Option("--goal", help="Goal of each OC problem: design (walking goal 0 0 pi/2), end (last measured pose), auto (design for walking-2020 conditions ending within 0.5 m of it, else end).")] = GoalChoice.auto,
    intervals: Annotated[int, typer.Option("--intervals", help="Intervals of the OC grid (50: 2-12 mm from a 500-interval solve) (>= 10).")] = 50,
    v_nominal: Annotated[float, typer.Option("--v-nominal", help="Nominal speed (m/s) of T0 = distance / v + 1 s; the free duration T is bounded to (0.4, 2.5) x T0 (>= 0.05).")] = 1.0,
    compare: Annotated[bool, typer.Option("--compare/--no-compare", help="Compare unicycle, clothoid, Mombaur, published and fitted models.")] = True,
    resume: Annotated[bool, typer.Option("--resume", help="Continue from the checkpoint of an interrupted run with the same inputs and options.")] = False,
    convention: ConventionOpt = None,
    method: Annotated[str, typer.Option("--method", help="bilevel (the published method) or single-level (one NLP with the lower level's KKT conditions; improved and table models; under the published convention at held horizons; docs/methods.md 6.1).")] = "bilevel",
    bootstrap: Annotated[int, typer.Option("--bootstrap", help="Resamples of the fitted units (means, or a subject's trials) for each weight's 95 % interval, with its identifiability verdict (docs/methods.md 6.3); 0: neither. --resume reuses the finished curvature evaluations (>= 0).")] = 200,
    profiles: Annotated[str, typer.Option("--profiles", help="Where the curvature of D and the bootstrap cannot judge alike (D not smooth at the fit, or a 'determined' the bootstrap overturns; continuous convention), each weight's verdict from its profile likelihood (docs/methods.md 6.3), for the fits: means (the fit over the means), all (per subject too), none.")] = "means",
    seed: SeedOpt = 0,
    jobs: JobsOpt = None,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Inverse optimal control (bi-level, or --method single-level): fit the OC cost weights to mean (or per-subject) trajectories.

    --convention continuous (default: the integrated costs and free duration of docs/methods.md sec. 6)
    or published (the authors' discrete conventions; writes fit-ioc-published/). Writes OUT/fit-ioc/weights.json (all fits) and weights/<fit>.json (each usable as --weights),
    distances.parquet (per trajectory and model), fits.csv (objective, evaluations and weights per
    fit), figures and results.md. The coupled model writes the same into OUT/fit-ioc-coupled/ (the
    table or walker fit in OUT/fit-ioc/ stays), with the distances of each carrier; --per subject
    writes OUT/fit-ioc-subjects/ (start them from the fit over the means with
    --start-weights OUT/fit-ioc/weights.json); --method single-level writes OUT/fit-ioc-single/
    (OUT/fit-ioc-subjects-single/), beside the bi-level fit. The log of upper-level evaluations is checkpointed in
    OUT/.<stage>.checkpoint after every upper-level iteration (--resume continues from it).
    """
    from cobot_analysis.api.models import fit_budget
    from cobot_analysis.console import progress
    from cobot_analysis.stages import models

    fitted = [n.strip() for n in fit_names.split(",") if n.strip()] if fit_names else None
    if fit_names is not None and not fitted:
        from cobot_analysis.errors import InputError

        raise InputError("--fit names (none) are not weights of the model", remedy="e.g. --fit a1,a2,a4")
    bar, tasks = progress(), {}  # shown from the first upper-level evaluation on (nothing when the stage is skipped)

    def on_evaluation(key: str, n: int, f: float, best: float) -> None:
        if not tasks:
            bar.start()
        if key not in tasks:
            tasks[key] = bar.add_task(f"IOC {key}", total=fit_budget(method, max_evaluations), status="", budget=True)
        bar.update(tasks[key], completed=n, status=f"D = {f:.4f}, best {best:.4f}")

    try:
        done = models.fit_ioc(out, means=means, trajectories=trajectories, model=model, start_weights=start_weights, fit=fitted,
                              optimizer=optimizer.value, max_evaluations=max_evaluations, per=per.value, subjects=subjects,
                              goal=goal.value, intervals=intervals, v_nominal=v_nominal, compare=compare, resume=resume,
                              convention=convention, seed=seed, jobs=jobs, scheduler=scheduler, force=force, method=method,
                              bootstrap=bootstrap, profiles=profiles, on_evaluation=on_evaluation)
        for key, task in tasks.items():
            r = done.result.results[key]
            count = r.evaluations if method != "single-level" else r.iterations  # upper-level evaluations, or steps
            bar.update(task, total=count, completed=count)
    finally:
        if tasks:
            bar.stop()
    if not done.skipped:
        r = done.result
        how = ", ".join([r.convention] + (["coupled"] if model == "coupled" else []) + (["per subject"] if per is Per.subject else []))
        finished(f"fit-ioc ({how})", r.summary(), done.directory)


# ---- velocity-commands -------------------------------------------------------------------------
@app.command("velocity-commands", rich_help_panel=PANEL_MODELS, epilog=examples(
    "cobot-analysis velocity-commands --out walking --trial clothoid_N1500",
    "cobot-analysis velocity-commands --out walking --trial clothoid_E1515 \\",
    "    --rate 20 --format parquet"))
def velocity_commands_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    generated: Annotated[Optional[Path], typer.Option("--generated", help="generated.parquet (default: OUT/generate/).")] = None,
    trial: Annotated[Optional[str], typer.Option("--trial", help="Generated trajectory to export (default: the only one).")] = None,
    rate: Annotated[float, typer.Option("--rate", help="Command rate f (Hz) (>= 0.1).")] = 10.0,
    v_max: Annotated[float, typer.Option("--v-max", help="Saturation of the x and y velocity commands (m/s) (>= 0).")] = 0.1,
    omega_max: Annotated[float, typer.Option("--omega-max", help="Saturation of the yaw-rate command (deg/s) (>= 0).")] = 7.0,
    fmt: Annotated[Format, typer.Option("--format", help="Output format.")] = Format.csv,
    force: ForceOpt = False,
) -> None:
    """Export velocity commands for a walking robot following a generated path (docs/methods.md sec. 10).

    v = (p_sim(t+1) - p_real(t)) f in the robot frame, open loop (p_real = p_sim), saturated at
    --v-max (x, y) and --omega-max (yaw). Writes OUT/velocity-commands/commands.csv (or .parquet).
    Refused: a path of the published convention (no pace), one that is no solution of its model (converged
    false) and one that spins (its status says so).
    """
    from cobot_analysis.stages import models

    done = models.velocity_commands(out, generated=generated, trial=trial, rate=rate, v_max=v_max, omega_max=omega_max,
                                    fmt=fmt.value, force=force)
    if not done.skipped:
        finished("velocity-commands", done.result.summary(), done.directory / f"commands.{fmt.value}")
