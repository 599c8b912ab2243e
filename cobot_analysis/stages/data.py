"""Data stages into a workspace: ``synth walking`` / ``synth pairs``, ``import``, ``import-published``,
``preprocess`` (docs/methods.md sec. 1-2)."""

from __future__ import annotations

import os
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from cobot_analysis import api, refusals
from cobot_analysis.console import warn
from cobot_analysis.stages import Outcome
from cobot_analysis.workspace import Stage, find_input


def synth_walking(out: str | os.PathLike, *, seed: int = 0, subjects: int = 10, repetitions: int = 3,
                  conditions: str | int | list[str] | None = None, jobs: int | None = None, scheduler: str | None = None,
                  force: bool = False) -> Outcome:
    """``synth-walking``: the synthetic walking study's raw C3D, protocol and ground truth (``api.synth_walking``)."""
    from cobot_analysis.synth import GENERATOR_VERSION, walking

    o = api.synth_options("walking", seed=seed, subjects=subjects, repetitions=repetitions, conditions=conditions)
    params = {"seed": o["seed"], "subjects": o["subjects"], "trials": o["repetitions"], "conditions": o["conditions"],
              "generator": GENERATOR_VERSION}
    with Stage(out, walking.STAGE, params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = api.synth_walking(stage.dir, **o, jobs=jobs, scheduler=scheduler)
    return Outcome(stage.final_dir, result)


def synth_pairs(out: str | os.PathLike, *, seed: int = 0, pairs: int = 20, goals: str | int | list[str] | None = None,
                scenarios: str | list[int] | None = None, jobs: int | None = None, scheduler: str | None = None,
                force: bool = False) -> Outcome:
    """``synth-pairs``: the synthetic pair-carriage study's raw C3D, protocol and ground truth (``api.synth_pairs``)."""
    from cobot_analysis.synth import GENERATOR_VERSION
    from cobot_analysis.synth import pairs as synth

    o = api.synth_options("pairs", seed=seed, pairs=pairs, goals=goals, scenarios=scenarios)
    params = {"seed": o["seed"], "pairs": o["pairs"], "goals": o["goals"], "scenarios": o["scenarios"], "generator": GENERATOR_VERSION}
    with Stage(out, synth.STAGE, params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = api.synth_pairs(stage.dir, **o, jobs=jobs, scheduler=scheduler)
    return Outcome(stage.final_dir, result)


def import_markers(out: str | os.PathLike, protocol: str | os.PathLike, *, jobs: int | None = None,
                   scheduler: str | None = None, force: bool = False, preprocess: dict[str, Any] | None = None,
                   **options: Any) -> Outcome:
    """``import``: raw markers of a protocol -> ``import/markers.parquet`` and ``trials.parquet``
    (options: those of ``api.import_markers``). ``preprocess``: options of the preprocess stage (``{}``: its
    defaults): each trial is also preprocessed where it is read (``import_and_preprocess``)."""
    from cobot_analysis.api.options import import_limits
    from cobot_analysis.io.markers import plan_import

    import_limits(*(options.get(k) for k in ("lab_extent", "max_speed", "max_spike")))  # as import_markers checks them
    keep_all = options.pop("keep_all_markers", False)
    plan = plan_import(protocol, keep_all=keep_all, **options)
    if preprocess is not None:  # a --samples too large for the memory is refused before any work, as preprocess does
        from cobot_analysis.preprocess.stage import Params, check_memory_for

        trials = plan.protocol.trials
        check_memory_for(Params(**preprocess), len(trials), "pair" in trials.columns and trials["pair"].notna().any(),
                         plan.protocol.path)
    from cobot_analysis.reports.data import import_summary, vertical_line
    from cobot_analysis.schema import TRIALS

    # each raw file hashed once, for the manifest and trials.parquet's sha256: by the worker that reads it, or on
    # entering the stage when an earlier run's manifest is to be compared (skip when unchanged)
    with Stage(out, "import", inputs=plan.inputs, params=plan.params, force=force,
               hashed_by_run=[t.path for t in plan.tasks]) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        known = stage.input_hashes
        plan.tasks = [replace(t, sha256=known.get(str(t.path))) for t in plan.tasks]  # (file_path: resolved)
        result = api.import_markers(plan, jobs=jobs, scheduler=scheduler, markers_path=stage.path("markers.parquet"),
                                    preprocess=preprocess)
        files = {t.trial: str(t.path) for t in plan.tasks}
        stage.inputs_hashed({files[t.trial]: t.sha256 for t in result.imported})
        stage.result = result  # its own numbers are the stage's metrics.json
        for note in result.notes:
            warn(note)
        if line := vertical_line(result.imported, "detected"):
            warn(f"{line} (--up gives the axis)")
        refusals.record(stage, result.refused, len(plan.tasks), "import")
        stage.path("results.md").write_text(import_summary(plan.protocol, result.imported, result.refused, plan.limits,
                                                           plan.params["outside_files"]))
        stage.write_table("trials.parquet", result.trials, TRIALS, study=plan.protocol.study)
    return Outcome(stage.final_dir, result)


def import_published(out: str | os.PathLike, dataset: str, path: str | os.PathLike, *, gamma_limit: float | None = None,
                     force: bool = False) -> Outcome:
    """``import-published``: a published dataset -> ``import-published/trajectories.parquet`` (+ durations and
    subject_wrt_table for the pairs), ``facts.json`` and ``results.md``."""
    from cobot_analysis.errors import InputError
    from cobot_analysis.io import published as pub

    gamma_limit = pub.GAMMA_LIMIT if gamma_limit is None else gamma_limit
    if dataset not in pub.DATASETS:
        raise InputError(f"unknown dataset {dataset!r}", remedy=f"use one of {', '.join(pub.DATASETS)}")
    path = Path(path)
    if not path.is_dir():
        raise InputError("dataset folder not found", path=path, remedy=pub.REMEDY_DATASET)
    from cobot_analysis.reports.data import pair_results_markdown, walking_results_markdown
    from cobot_analysis.schema import TRAJECTORIES

    params = {"dataset": dataset, "gamma_limit": gamma_limit, "gamma_consistency": pub.GAMMA_CONSISTENCY,
              "end_orientation_tolerance": pub.END_ORIENTATION_TOLERANCE}
    with Stage(out, "import-published", inputs=[path], params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = api.import_published(dataset, path, gamma_limit=gamma_limit)
        stage.result = result  # its own numbers are the stage's metrics.json
        facts = result.facts
        if dataset == pub.WALKING:
            text = walking_results_markdown(facts)
            warn(f"walking-2020: {facts['orientation_missing_subject']} subject trajectories and "
                 f"{facts['orientation_missing_mean']} means without orientation (theta, gamma NaN); "
                 f"{facts['implausible_subject']} subject trajectories flagged implausible_gamma (see results.md)")
        else:
            warn(f"pair-carriage-2022: {len(facts['plain_angle_means'])} means flagged plain_angle_mean "
                 "(table orientation off its configuration: angles averaged as plain numbers; see results.md)")
            stage.write_table("durations.parquet", result.durations, pub.DURATIONS, study=pub.PAIRS)
            stage.write_table("subject_wrt_table.parquet", result.subject_wrt_table, pub.SUBJECT_WRT_TABLE, study=pub.PAIRS)
            text = pair_results_markdown(facts)
        stage.write_table("trajectories.parquet", result.trajectories, TRAJECTORIES, study=dataset,
                    n_samples=pub.N_SAMPLES, source=str(path.resolve()))
        stage.path("results.md").write_text(text)
        stage.write_json("facts.json", facts, default=str)
    return Outcome(stage.final_dir, result)


def import_and_preprocess(out: str | os.PathLike, protocol: str | os.PathLike, *, preprocess_options: dict[str, Any] | None = None,
                          jobs: int | None = None, scheduler: str | None = None, force: bool = False,
                          **options: Any) -> tuple[Outcome, Outcome]:
    """``import --preprocess``: the ``import`` and ``preprocess`` stages in one pass, each trial preprocessed by
    the worker that has just read it (no second start-up, the markers not read back): the same two stage
    directories, tables and manifests as ``import`` then ``preprocess`` (``options``: the import's)."""
    popts = dict(preprocess_options or {})
    imported = import_markers(out, protocol, jobs=jobs, scheduler=scheduler, force=force, preprocess=popts, **options)
    return imported, preprocess(out, jobs=jobs, scheduler=scheduler, force=force, imported=imported.result, **popts)


def preprocess(out: str | os.PathLike, *, markers: str | os.PathLike | None = None, trials: str | os.PathLike | None = None,
               jobs: int | None = None, scheduler: str | None = None, force: bool = False, imported: Any = None,
               **options: Any) -> Outcome:
    """``preprocess``: ``import/markers.parquet`` -> ``preprocess/trajectories.parquet``, ``gaps.parquet`` and
    ``results.md`` (options: the fields of ``preprocess.stage.Params``). ``imported``: the result of the import
    just run with the same options as ``preprocess`` (``import_and_preprocess``): its trials' preprocessing is
    assembled instead of reading the markers back."""
    markers_path = Path(markers) if markers is not None else find_input(out, "markers.parquet", ["import"], "--markers")
    trials_path = Path(trials) if trials is not None else markers_path.with_name("trials.parquet")
    from cobot_analysis.preprocess import gaps  # after the cheap checks: these import pandas
    from cobot_analysis.preprocess.stage import Params
    from cobot_analysis.reports.data import preprocess_summary
    from cobot_analysis.schema import TRAJECTORIES

    p = Params(**options)
    with Stage(out, "preprocess", inputs=[markers_path, trials_path], params=asdict(p), force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        if imported is not None and imported.preprocessed is not None:
            result = api.preprocess(imported, trials_path, **options)
        else:
            result = api.preprocess(markers_path, trials_path, jobs=jobs, scheduler=scheduler, **options)
        stage.result = result  # its own numbers are the stage's metrics.json
        refusals.record(stage, result.refused, result.n_recordings + len(result.refused), "preprocess")
        params = asdict(p)
        stage.write_table("trajectories.parquet", result.trajectories, TRAJECTORIES, stage="preprocess", **params)
        stage.write_table("gaps.parquet", result.gaps, gaps.GAPS, stage="preprocess", max_gap=p.max_gap)
        stage.path("results.md").write_text(preprocess_summary(result.trajectories, result.gaps, p, result.n_recordings,
                                                               result.refused))
    return Outcome(stage.final_dir, result)
