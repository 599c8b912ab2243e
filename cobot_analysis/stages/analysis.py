"""Analysis stages into a workspace: ``average``, ``compare``, ``stats``, ``reconstruct`` and ``report``
(docs/methods.md sec. 2.9, 3, 4, 8)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from cobot_analysis import api, conventions, registry
from cobot_analysis.console import warn
from cobot_analysis.errors import InputError
from cobot_analysis.stages import Outcome
from cobot_analysis.workspace import Stage, find_input

#: where a study's trajectories come from in a workspace, in order of preference
TRAJ_STAGES = ["preprocess", "import-published"]


def trajectories_input(out: str | os.PathLike, path: str | os.PathLike | None):
    """The workspace's trajectories (``--trajectories``, else preprocess/ or import-published/) and their set."""
    path = Path(path) if path is not None else find_input(out, "trajectories.parquet", TRAJ_STAGES, "--trajectories")
    return path, api.trajectory_set(path, ("trajectories",))


def average(out: str | os.PathLike, *, trajectories: str | os.PathLike | None = None, by: list[str] | None = None,
            max_spread: float | None = None, weigh: str = "trials", force: bool = False) -> Outcome:
    """``average``: ``average/means.parquet`` (its metadata: the grouping and the weighting) and its results fragment."""
    path, ts = trajectories_input(out, trajectories)  # refuses a missing input before the heavy imports below
    from cobot_analysis.api.options import one_of
    from cobot_analysis.averaging import MEANS, WEIGHTS, check_groups, check_units

    one_of(weigh, "--weigh", WEIGHTS)
    from cobot_analysis.compare import default_groups
    from cobot_analysis.reports.analysis import average_markdown

    groups = api.check_by(by, list(ts.meta.columns), path) or default_groups(ts.meta)
    trials = ts.subset(ts.meta["kind"].eq("trial").to_numpy())
    if len(trials):
        check_groups(trials.meta, groups, path)
        if weigh != "trials":
            check_units(trials.meta, groups, path)
    params = {"by": groups, **({"max_spread": max_spread} if max_spread is not None else {}),
              **({"weigh": weigh} if weigh != "trials" else {})}  # the default's params as before: its stage stays up to date
    with Stage(out, "average", inputs=[path], params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = api.average(path if not len(trials) else ts, by=groups, max_spread=max_spread, weigh=weigh)
        stage.result = result  # its own numbers are the stage's metrics.json
        if not result.n_averaged:
            warn(f"{path}: no per-trial trajectories; the published means are carried over unchanged")
        for line in result.spread:
            warn(line)
        stage.write_table("means.parquet", result.means, MEANS, grouping=groups, source=result.source, weigh=weigh)
        stage.path("results.md").write_text(average_markdown(result, path.name))
    return Outcome(stage.final_dir, result)


def compare(out: str | os.PathLike, *, trajectories: str | os.PathLike | None = None, means: str | os.PathLike | None = None,
            against: str | os.PathLike | None = None, comparison: str = "against", any_vs_any: list[str] | None = None,
            by: list[str] | None = None, convention: str | None = None, force: bool = False) -> Outcome:
    """``compare`` (``compare-published`` under the published convention): ``distances.parquet``."""
    from cobot_analysis import conventions

    conv = conventions.get(convention or "continuous")
    path, ts = trajectories_input(out, trajectories)  # refuses a missing input before the heavy imports below
    from cobot_analysis.compare import DISTANCES, default_groups
    from cobot_analysis.reports.analysis import compare_markdown
    from cobot_analysis.schema import table_metadata

    means_path = Path(means) if means is not None else find_input(out, "means.parquet", ["average"], "--means")
    mts = api.trajectory_set(means_path, ("means",))
    groups = api.check_by(by, list(ts.meta.columns), path) or table_metadata(means_path).get("grouping") or default_groups(ts.meta)
    same = api.check_by(any_vs_any, list(ts.meta.columns), path)
    if against is not None:
        from cobot_analysis.compare import against_set
        from cobot_analysis.models.outputs import GENERATED

        against_set(Path(against), mts.n_samples, conv, GENERATED)  # a bad --against table is refused before the stage starts
    inputs = [path, means_path] + ([Path(against)] if against is not None else [])
    params = {"by": groups, "label": comparison, "any_vs_any": same, "convention": conv.name}
    weigh = table_metadata(means_path).get("weigh", "trials")  # how average weighed the means (average --weigh)
    if weigh != "trials":
        params["means_weigh"] = weigh
    with Stage(out, registry.directory("compare", conv.name), inputs=inputs, params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = api.compare(ts, mts, against=against, comparison=comparison, any_vs_any=same, by=groups, convention=conv.name)
        stage.result = result  # its own numbers are the stage's metrics.json
        stage.write_table("distances.parquet", result.distances, DISTANCES, grouping=groups, convention=conv.name,
                          excluded=result.excluded, means_weigh=weigh)  # why trials were left out: stats reads it (api.distances_table)
        stage.path("results.md").write_text(compare_markdown(result, conv.comparison.sd_ddof, weigh))
    return Outcome(stage.final_dir, result)


def protocol_anthropometrics(out: Path) -> tuple[object, list[Path]]:
    """(``stats.sources.anthropometrics`` of the subjects and pairs of the protocol the workspace's ``import`` read, the
    files they come from); (None, []) without an import, its protocol, pairs in it, or the subjects' weight and
    height. Not a synthetic study's
    tables because the workspace holds one: a lab's pairs P01... would get the synthetic pairs' weights."""
    import json

    from cobot_analysis.io.markers import protocol_tables
    from cobot_analysis.io.protocol import load_protocol
    from cobot_analysis.stats.sources import anthropometrics

    manifest = out / "import" / "manifest.json"
    try:
        protocol = Path(json.loads(manifest.read_text())["params"]["protocol"])
    except (OSError, ValueError, KeyError, IndexError, TypeError):
        return None, []
    if not protocol.is_file():
        return None, []
    p = load_protocol(protocol)
    if not {"weight", "height"} <= set(p.subjects.columns):
        return None, []
    table = anthropometrics(p.subjects, p.pairs, protocol)
    return table, ([protocol, *protocol_tables(protocol, ("subjects", "pairs"))] if table is not None else [])


def statistics(out: str | os.PathLike, *, config: str | os.PathLike | None = None, trajectories: str | os.PathLike | None = None,
               distances: str | os.PathLike | None = None, durations: str | os.PathLike | None = None,
               anthropometrics: str | os.PathLike | None = None, convention: str | None = None,
               force: bool = False) -> Outcome:
    """``stats``: ``stats/stats.parquet``, ``stats.md`` and the results fragment. The questions are those of
    the study file (``config``, else ``study.locate``: beside the protocol, else ``pipelines/<study>.toml``),
    or the default descriptive ones (docs/statistics.md). Under the published convention on the distances of
    ``compare-published/``, into ``stats-published/``."""
    from cobot_analysis import study as st
    from cobot_analysis.console import info, track

    out = Path(out)
    if config is not None:
        st.load(config)  # validate a given study file before anything else
    path, ts = trajectories_input(out, trajectories)  # refuses a missing input before the heavy imports below
    from cobot_analysis.reports.analysis import statistics_markdown
    from cobot_analysis.stats import analyses
    from cobot_analysis.stats.sources import read_anthropometrics

    study = st.resolve(out, api.study_of(ts), Path(config) if config is not None else None)
    config = study.path
    conv = conventions.get(convention or "continuous")
    dist_path = Path(distances) if distances is not None else find_input(
        out, "distances.parquet", [registry.directory("compare", conv.name)], "--distances")
    api.distances_table(dist_path)  # refused before the stage starts: a missing column, no row (and no why)
    dur_path = Path(durations) if durations is not None else out / "import-published" / "durations.parquet"
    dur = None
    if dur_path.is_file():
        import pyarrow.parquet as pq

        try:
            dur = pq.read_table(dur_path).to_pandas()
        except Exception as exc:
            raise InputError(f"not a readable Parquet file ({type(exc).__name__})", path=dur_path, remedy="re-run import-published") from None
        if not {"duration", "duration_s"} & set(dur.columns):
            raise InputError("durations table lacks a duration column", path=dur_path, remedy="re-run import-published")
    elif durations is not None:
        raise InputError("file not found", path=durations, remedy="check --durations")
    if anthropometrics is not None:
        anthro_dir = Path(anthropometrics)
        anthro = read_anthropometrics(anthro_dir)
        if anthro is None:
            raise InputError("no subjects.csv and pairs.csv in this directory", path=anthro_dir,
                             remedy="pass the folder of the study's subjects.csv and pairs.csv, or omit --anthropometrics")
        anthro_files = [anthro_dir / "subjects.csv", anthro_dir / "pairs.csv"]
    else:  # the study's own subjects and pairs: those of the protocol its import read
        anthro, anthro_files = protocol_anthropometrics(out)
    inputs = [p for p in (config, path, dist_path, dur_path if dur is not None else None) if p] + anthro_files
    from cobot_analysis.schema import table_metadata

    weigh = table_metadata(dist_path).get("means_weigh", "trials")  # the means compare measured to (average --weigh)
    params = {"config": str(config), "convention": conv.name, **({"means_weigh": weigh} if weigh != "trials" else {})}
    with Stage(out, registry.directory("stats", conv.name), inputs=inputs, params=params, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        result = api.statistics(ts, dist_path, config=study, durations=dur, anthropometrics=anthro, progress=track)
        stage.result = result  # its own numbers are the stage's metrics.json
        if result.unmatched:  # a typo, or data not there yet: said once
            warn(f"{config}: {len(result.unmatched)} filter value(s) match no row, their analyses are skipped (stats.md says "
                 f"why): {'; '.join(result.unmatched)}")
        for why, ids in result.waiting.items():  # expected: e.g. no model compared yet
            info(f"stats: {', '.join(ids)} skipped as expected: {why}")
        if not result.declared:
            info(f"stats: {'no study file' if config is None else config} declares no questions: the default descriptive "
                 "statistics (docs/statistics.md)")
        stage.write_table("stats.parquet", result.table, analyses.STATS, config=str(config))
        md, fragment = statistics_markdown(result, config, len(ts), ts.n_samples, path.name, dist_path, conv.name, weigh)
        stage.path("stats.md").write_text(md)
        stage.path("results.md").write_text(fragment)
    return Outcome(stage.final_dir, result)


def reconstruct(out: str | os.PathLike, *, trajectories: str | os.PathLike | None = None, wrt_table: str | os.PathLike | None = None,
                scenario: int = 3, force: bool = False) -> Outcome:
    """``reconstruct``: ``reconstruct/reconstruction.parquet`` and its results fragment."""
    from cobot_analysis.console import track

    path, ts = trajectories_input(out, trajectories)  # refuses a missing input before the heavy imports below
    import pandas as pd

    from cobot_analysis.reconstruct import RECONSTRUCTION, read_wrt_table, relative_pose_table
    from cobot_analysis.reports.analysis import reconstruct_markdown

    if not ts.meta["entity"].eq("table").any():
        raise InputError("no table trajectories to reconstruct the subjects from", path=path, remedy="use pair-study trajectories")
    imported = Path(out) / "import-published" / "subject_wrt_table.parquet"
    if wrt_table:
        wrt_table = Path(wrt_table)
        published, inputs = read_wrt_table(wrt_table), [path, wrt_table / "subject1_wrt_table.dat", wrt_table / "subject2_wrt_table.dat"]
    elif imported.is_file():
        table = pd.read_parquet(imported)
        table.attrs = {}
        published, inputs = relative_pose_table(table), [path, imported]
    else:
        published, inputs = None, [path]
    with Stage(out, "reconstruct", inputs=inputs, params={"scenario": scenario}, force=force) as stage:
        if stage.skipped:
            return Outcome.skip(stage)
        try:
            result = api.reconstruct(ts, relative_pose=published, scenario=scenario, progress=track)
            stage.result = result  # its own numbers are the stage's metrics.json
        except InputError as exc:
            raise InputError(exc.detail, path=path, remedy=exc.remedy) from None
        stage.write_table("reconstruction.parquet", result.reconstruction, RECONSTRUCTION)
        stage.path("results.md").write_text(reconstruct_markdown(result))
    return Outcome(stage.final_dir, result)


def report(out: str | os.PathLike, study: str | None = None, *, to: str | os.PathLike | None = None,
           study_file: str | os.PathLike | None = None, force: bool = False) -> Outcome:
    """``report``: the study's Markdown report with its figures in ``report/``, copied to ``to``
    (default ``reports/STUDY``); the outcome's result is the report directory. Labels, abbreviations and
    questions come from the study file (``study_file``, else ``study.locate``); ``study``, when given,
    must be the workspace's study."""
    from cobot_analysis import study as st
    from cobot_analysis.reports.builders import build_report, report_inputs
    from cobot_analysis.workspace import check_destination, check_workspace

    check_workspace(out)
    if to is not None:
        check_destination(to, "--to", directory=True)
    inputs = report_inputs(Path(out))
    if not inputs:
        raise InputError("nothing to report in this workspace", path=out, remedy="run average, compare and stats first")
    source = inputs.get("trajectories") or inputs.get("means")
    name = api.study_of(api.trajectory_set(source, ("trajectories", "means"))) if source else (study or "")
    if study is not None and study != name:
        raise InputError(f"the workspace's study is {name!r}, not {study!r}", path=out,
                         remedy=f"omit the study name (the report takes the workspace's) or pass --out of a {study} workspace")
    described = st.resolve(Path(out), name, Path(study_file) if study_file is not None else None)
    if described.path is not None:
        inputs = {**inputs, "study_file": described.path}
    to = Path(to) if to is not None else check_destination(Path("reports") / name, "--to", directory=True)
    with Stage(out, "report", inputs=list(inputs.values()), params={"study": name}, force=force) as stage:
        if not stage.skipped:
            build_report(described, {k: v for k, v in inputs.items() if k != "study_file"}, stage, Path(out))
    tmp = to.with_name(f".{to.name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(stage.final_dir, tmp, ignore=shutil.ignore_patterns("manifest.json"))
    if to.exists():
        shutil.rmtree(to)
    tmp.rename(to)
    return Outcome(stage.final_dir, None if stage.skipped else to, copied_to=to)
