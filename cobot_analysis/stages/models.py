"""Model stages into a workspace: ``generate``, ``fit-ioc`` and ``velocity-commands`` (docs/methods.md
sec. 5, 6, 10); under the published convention they write ``STAGE-published/`` (``registry.directory``)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from cobot_analysis import api, registry
from cobot_analysis.api.models import check_profiles, ioc_spec, plan_generate, read_trajectories, same_study
from cobot_analysis.errors import InputError
from cobot_analysis.stages import Outcome
from cobot_analysis.workspace import Stage, find_input

#: the studies ``generate --study`` generates every mean of, and the model each runs by default
STUDIES = {"walking-2020": "improved", "pair-carriage-2022": "table"}


def generate(out: str | os.PathLike, *, model: str | None = None, weights: Any = None, start=None, goal=None,
             study: str | None = None, samples: int = 500, intervals: int = 100, duration: str | None = None,
             v_nominal: float = 1.0, max_iter: int = 500, means: str | os.PathLike | None = None,
             convention: str | None = None, jobs: int | None = None, scheduler: str | None = None, force: bool = False) -> Outcome:
    """``generate`` (``generate-published``): ``generated.parquet`` and its results fragment. ``study``: every
    walking-2020 condition, or every table mean of the pair study (``api.models.pair_cases``, the table model
    only); ``model`` defaults to the study's (``STUDIES``), else the improved one."""
    from cobot_analysis import conventions
    from cobot_analysis.models.comparison import measured_pace
    from cobot_analysis.models.outputs import GENERATED
    from cobot_analysis.reports.models import generate_markdown
    from cobot_analysis.schema import table_metadata

    if study is not None and study not in STUDIES:
        raise InputError(f"--study {study}: unknown study", remedy=f"use --study {' or '.join(STUDIES)}, or give --start")
    model = model or STUDIES.get(study, "improved")
    if study == "pair-carriage-2022" and model != "table":
        raise InputError(f"--model {model} on --study pair-carriage-2022: its means are the table's paths, whose orientation "
                         "is no walker's heading", remedy="use --model table (the default with this study)")
    inputs = [Path(weights)] if weights and Path(weights).is_file() else []
    _, conv, _ = plan_generate(model, weights=weights, cases=[], duration=duration, convention=convention)  # options first
    cases, measured, keys, source = None, None, None, None  # source: the means the cases come from
    if study is None and start is None:
        raise InputError("nothing to generate", remedy=f"give --start X Y THETA or --study {' or '.join(STUDIES)}")
    if study == "pair-carriage-2022":
        cases, keys, measured, used = _pair_cases(out, means, conv.name, goal)
        inputs += used
        source = used[0]
    elif study is not None:
        means_df, path = None, _walking_means(out, means, conv.name)
        source = path
        if path is not None:
            means_df = read_trajectories(path)
            inputs.append(path)
            try:  # the subjects' trials: their own pace where the means hold no travel time
                trials_path = find_input(out, "trajectories.parquet", ["import-published", "preprocess"], "--trajectories")
                trials_df = read_trajectories(trials_path)
                inputs.append(trials_path)
            except InputError:
                trials_df = None
            if not same_study(means_df, trials_df):  # walking-2020's import beside a study of one's own: not its pace
                trials_df = None
                inputs.pop()
            measured = measured_pace(means_df, trials_df)
        cases = api.walking_cases(conv.name, means_df, goal=goal, path=path)
    models, conv, cases = plan_generate(model, weights=weights, start=start, goal=goal, cases=cases, duration=duration,
                                        convention=convention, path=source)
    kw = {"n_samples": samples, "n_intervals": intervals, "duration": duration, "v_nominal": v_nominal, "max_iter": max_iter,
          "convention": conv.name}
    params = {"models": models, "weights": weights, "cases": cases, **kw}
    weigh = table_metadata(source).get("weigh", "trials") if source is not None else "trials"  # average --weigh
    if weigh != "trials":
        params["means_weigh"] = weigh
    with Stage(out, registry.directory("generate", conv.name), inputs=inputs, params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = api.generate(model, start=start, goal=goal, cases=cases, study=study, weights=weights, samples=samples,
                              intervals=intervals, duration=duration, v_nominal=v_nominal, max_iter=max_iter,
                              convention=conv.name, measured=measured, keys=keys, jobs=jobs, scheduler=scheduler)
        stage.result = result  # its own numbers are the stage's metrics.json
        stage.write_table("generated.parquet", result.generated, GENERATED, n_samples=samples, n_intervals=intervals,
                    convention=conv.name)
        stage.path("results.md").write_text(generate_markdown(result, conventions.get(conv.name).summary, weigh))
    return Outcome(stage.final_dir, result)


def _pair_cases(out, means, convention: str, goal) -> tuple[list, dict, dict, list[Path]]:
    """``generate --study pair-carriage-2022``: the cases and columns of the table means (``api.models.pair_cases``),
    the subjects' pace of each (``comparison.pair_pace``: the means' travel times, else OUT/import-published/
    durations.parquet) and the files read. The means: ``means``, else as for the walking study (``_walking_means``);
    none is an ``InputError`` naming the files looked for and ``import-published pair-carriage-2022``."""
    from cobot_analysis.lazy import pandas as pd

    from cobot_analysis.api.models import pair_cases
    from cobot_analysis.models.comparison import pair_pace

    if goal is not None:
        raise InputError("--goal does not apply to --study pair-carriage-2022 (each table mean ends on its own goal)",
                         remedy="leave --goal out")
    looked = ["average/means.parquet"] * (convention != "published") + ["import-published/trajectories.parquet"]
    try:
        path = _walking_means(out, means, convention)
    except InputError:
        path = None
    if path is None:
        raise InputError(f"--study pair-carriage-2022: no table means in {out} ({', '.join(looked)})",
                         remedy=f"run `cobot-analysis import-published pair-carriage-2022 DATASET --out {out}` first, or pass --means")
    means_df = read_trajectories(path)
    cases, keys = pair_cases(convention, means_df, path=path)
    used = [path]
    try:
        durations_path = find_input(out, "durations.parquet", ["import-published"], "--means")
        durations = pd.read_parquet(durations_path)
        used.append(durations_path)
    except InputError:
        durations = None
    return cases, keys, pair_pace(means_df, durations), used


def _walking_means(out, means, convention: str) -> Path | None:
    """The means ``generate --study`` takes its start (and, published, goal) poses from: ``means``, else
    OUT/average/means.parquet (continuous), else the kind=mean rows of OUT/import-published/; None
    under the continuous convention when there are none (the design's starts)."""
    if means is not None:
        return Path(means)
    looked = ([("means.parquet", ["average"])] if convention != "published" else []) + [("trajectories.parquet", ["import-published"])]
    for name, stages in looked:
        try:
            return find_input(out, name, stages, "--means")
        except InputError:
            if convention == "published":
                raise
    return None


def fit_inputs(out: str | os.PathLike, convention: str, *, means: str | os.PathLike | None = None,
               trajectories: str | os.PathLike | None = None) -> tuple[Path | None, Path | None]:
    """(means, trajectories): the files ``fit_ioc`` reads from the workspace ``out`` unless given. The
    trajectories: import-published's, else preprocess's (None when neither). The means: under the published
    convention the authors' own mean block (the kind=mean rows of import-published's trajectories), else
    average/means.parquet (None when absent and trajectories were found: the kind=mean rows of those)."""
    traj_path = Path(trajectories) if trajectories is not None else None
    if traj_path is None:
        try:
            traj_path = find_input(out, "trajectories.parquet", ["import-published", "preprocess"], "--trajectories")
        except InputError:
            traj_path = None
    if means is None and convention == "published" and traj_path is not None and traj_path.parent.name == "import-published":
        means = traj_path  # the published convention compares with the authors' own mean block
    if means is None:
        try:
            means = find_input(out, "means.parquet", ["average"], "--means")
        except InputError:
            if traj_path is None:
                raise
    return (Path(means) if means is not None else None), traj_path


def fit_ioc(out: str | os.PathLike, *, means: str | os.PathLike | None = None, trajectories: str | os.PathLike | None = None,
            model: str = "improved", start_weights: str | None = None, fit: list[str] | None = None, optimizer: str = "powell",
            max_evaluations: int = 2000, per: str = "all", subjects: int | None = None, goal: str = "auto", intervals: int = 50,
            v_nominal: float = 1.0, compare: bool = True, resume: bool = False, convention: str | None = None, seed: int = 0,
            jobs: int | None = None, scheduler: str | None = None, force: bool = False, on_evaluation=None,
            method: str = "bilevel", bootstrap: int = 200, profiles: str = "means") -> Outcome:
    """``fit-ioc`` (``fit-ioc-subjects`` with ``per="subject"``, ``fit-ioc-coupled`` for the coupled model, each
    ``-published`` under the published convention): weights.json, weights/<fit>.json, distances.parquet,
    fits.csv, figures and results.md. The upper level's evaluations are checkpointed in
    ``OUT/.<stage>.checkpoint`` after every iteration (``resume`` continues from it). The single-level
    method writes its own stage (``fit-ioc-single``, ``fit-ioc-subjects-single``) beside the bi-level one,
    and its report shows the bi-level fit of the workspace beside its own. ``bootstrap``: resamples of
    the weights' intervals (0: no intervals nor verdicts); ``profiles``: ``api.fit_ioc``'s."""
    from cobot_analysis.lazy import pandas as pd

    from cobot_analysis import conventions
    from cobot_analysis.models.ioc.single_level import check_method
    from cobot_analysis.models.outputs import ioc_distances_schema
    from cobot_analysis.reports.models import fit_ioc_markdown
    from cobot_analysis.schema import table_metadata

    check_method(method, bootstrap)
    check_profiles(profiles)
    conv = conventions.get(convention or "continuous")
    spec = ioc_spec(model, convention=conv.name, start_weights=start_weights, fit=fit, optimizer=optimizer,
                    max_evaluations=max_evaluations, intervals=intervals, v_nominal=v_nominal)  # options checked first
    if model == "coupled" and per == "subject":
        raise InputError("--per subject is for the walking study", remedy="fit the coupled model over the pair means (--per all)")
    means, traj_path = fit_inputs(out, conv.name, means=means, trajectories=trajectories)
    mean_df = read_trajectories(means) if means is not None else read_trajectories(traj_path)
    mean_src = means if means is not None else traj_path
    traj_df = read_trajectories(traj_path) if traj_path is not None else None
    inputs = [p for p in (means, traj_path) if p is not None]
    if start_weights and Path(start_weights).is_file():
        inputs.append(Path(start_weights))
    params = {"spec": spec.__dict__, "per": per, "subjects": subjects, "goal": goal, "compare": compare, "seed": seed,
              "bootstrap": bootstrap}
    if method != "bilevel":
        params["method"] = method
    if profiles != "means":
        params["profiles"] = profiles
    weigh = table_metadata(means).get("weigh", "trials") if means is not None else "trials"  # average --weigh
    if weigh != "trials":
        params["means_weigh"] = weigh
    # own stages: the coupled fit never replaces the table fit, nor per-subject fits the fit over the means, nor the
    # single-level fit the bi-level one
    base = "fit-ioc-coupled" if model == "coupled" else "fit-ioc-subjects" if per == "subject" else "fit-ioc"
    name = registry.directory(base + ("-single" if method == "single-level" else ""), conv.name)
    other = _bilevel_fit(out, registry.directory(base, conv.name), model) if method == "single-level" else None
    if other is not None:  # the report shows it: a new bi-level fit redoes the single-level stage's report
        inputs.append(Path(other["path"]))
    durations = None
    if model in ("coupled", "table"):  # the pair study's durations: the coupled section, the table fit's time gauge
        try:
            durations = pd.read_parquet(find_input(out, "durations.parquet", ["import-published"], "--means"))
        except InputError:
            pass  # no published durations (e.g. a synthetic pair study): the section says so
    with Stage(out, name, inputs=inputs, params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = api.fit_ioc(mean_df, trials=traj_df, model=model, start_weights=start_weights, fit=list(spec.fitted), optimizer=optimizer,
                             max_evaluations=max_evaluations, per=per, subjects=subjects, goal=goal, intervals=intervals,
                             v_nominal=v_nominal, compare=compare, convention=conv.name, resume=resume,
                             checkpoint=Path(out) / f".{name}.checkpoint", jobs=jobs, scheduler=scheduler, means_source=mean_src,
                             trials_source=traj_path or out, durations=durations, on_evaluation=on_evaluation, method=method,
                             bootstrap=bootstrap, seed=seed, profiles=profiles,
                             against={k: f["weights"] for k, f in other["fits"].items() if f.get("weights")} if other else None)
        stage.result = result  # its own numbers are the stage's metrics.json
        stage.write_json("weights.json", result.weights_json())
        for k, r in result.results.items():  # each fit also as a file usable with --weights
            stage.path(f"weights/{k}.json").write_text(json.dumps({"convention": conv.name, "weights": r.weights}, indent=2) + "\n")
        stage.write_table("distances.parquet", result.distances, ioc_distances_schema(coupled=result.coupled is not None),
                    convention=conv.name)
        result.fits_table().to_csv(stage.path("fits.csv"), index=False)
        stage.path("results.md").write_text(fit_ioc_markdown(result, stage, optimizer=optimizer, intervals=intervals,
                                                             v_nominal=v_nominal, durations=durations, other=other,
                                                             weigh=weigh))
    return Outcome(stage.final_dir, result)


def _bilevel_fit(out, directory: str, model: str) -> dict | None:
    """The bi-level fit of ``model`` in the workspace (``OUT/<directory>/weights.json``) for the single-level report
    and its cross-checks, None when there is none (another model's fit there, e.g. the walker's in a pair
    workspace, is none: its weights are no start, nor D a comparison, for this model)."""
    path = Path(out) / directory / "weights.json"
    if not path.is_file():
        return None
    data = json.loads(path.read_text())
    if data.get("model") != model:
        return None
    return {"path": str(path), "fits": data.get("fits", {})}


def velocity_commands(out: str | os.PathLike, *, generated: str | os.PathLike | None = None, trial: str | None = None,
                      rate: float = 10.0, v_max: float = 0.1, omega_max: float = 7.0, fmt: str = "csv",
                      force: bool = False) -> Outcome:
    """``velocity-commands``: ``commands.csv`` (or ``.parquet``) of one generated path."""
    from cobot_analysis.models.outputs import GENERATED, VELOCITY_COMMANDS
    from cobot_analysis.schema import read_table

    path = Path(generated) if generated is not None else find_input(out, "generated.parquet", ["generate", "generate-published"], "--generated")
    df = read_table(path, GENERATED)
    cmd = api.velocity_commands(df, trial=trial, rate=rate, v_max=v_max, omega_max=omega_max, path=path)
    params = {"trial": cmd.trial, "rate": rate, "v_max": v_max, "omega_max": omega_max, "format": fmt}
    with Stage(out, "velocity-commands", inputs=[path], params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        stage.result = cmd  # its own numbers are the stage's metrics.json
        if fmt == "csv":
            cmd.commands.to_csv(stage.path("commands.csv"), index=False, float_format="%.6g")
        else:
            stage.write_table("commands.parquet", cmd.commands, VELOCITY_COMMANDS, rate=rate, v_max=v_max,
                        omega_max_deg_s=omega_max)
        stage.path("results.md").write_text(
            f"## Velocity commands\n\nTrajectory {cmd.trial} at {rate:g} Hz: {len(cmd.commands)} commands, saturated at "
            f"{v_max:g} m/s and {omega_max:g} deg/s; {cmd.commands['saturated'].mean() * 100:.0f} % of the commands hit a limit.\n")
    return Outcome(stage.final_dir, cmd)
