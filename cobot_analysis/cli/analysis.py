"""``average``, ``compare``, ``stats``, ``reconstruct`` and ``report``: the analyses of docs/methods.md
sec. 3, 4 and 8 on a workspace's trajectories.

Typical sequence (published walking data imported into WS):
    cobot-analysis average --out WS
    cobot-analysis compare --out WS
    cobot-analysis stats --out WS                 # pipelines/<study>.toml
    cobot-analysis reconstruct --out WS --wrt-table DATASETS/pair-carriage-2022   (pair study)
    cobot-analysis report walking-2020 --out WS --to reports/walking
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis.cli.app import (PANEL_ANALYSIS, PANEL_REPORT, DEFAULT_OUT_PATH, ConventionOpt, ForceOpt, OutOpt, app, count,
                                   examples, finished)
from cobot_analysis.errors import InputError

TRAJ_STAGES = ["preprocess", "import-published"]
TrajOpt = Annotated[Optional[Path], typer.Option("--trajectories", help="trajectories.parquet (default: the workspace's preprocess or import-published output).")]
ByOpt = Annotated[Optional[str], typer.Option("--by", help="Comma-separated grouping columns of the means (default: walking condition x entity; pairs goal x direction x scenario x configuration x end orientation x entity).")]
PIPELINES = Path(__file__).resolve().parents[2] / "pipelines"


def _trajectories(out: Path, path: Optional[Path]):
    from cobot_analysis.compare import read_trajectory_set
    from cobot_analysis.workspace import find_input

    path = path or find_input(out, "trajectories.parquet", TRAJ_STAGES, "--trajectories")
    return path, read_trajectory_set(path, ("trajectories",))


def _plain(df):
    """Drop the file metadata from ``df.attrs``: pandas deep-copies attrs on every operation."""
    df.attrs = {}
    return df


def _by(value: Optional[str], columns, path=None) -> list[str] | None:
    if not value:
        return None
    by = [c.strip() for c in value.split(",") if c.strip()]
    bad = [c for c in by if c not in columns]
    if bad:
        raise InputError(f"--by names unknown column(s) {bad}", path=path, remedy=f"use columns of the trajectories: {', '.join(columns)}")
    return by


def _study(ts) -> str:
    studies = sorted(ts.meta["study"].dropna().astype(str).unique())
    return studies[0] if len(studies) == 1 else "+".join(studies)


# ---- average ------------------------------------------------------------------------------------
@app.command("average", rich_help_panel=PANEL_ANALYSIS, epilog=examples(
    "cobot-analysis average --out walking",
    "cobot-analysis average --out walking --by condition,entity"))
def average_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    trajectories: TrajOpt = None,
    by: ByOpt = None,
    force: ForceOpt = False,
) -> None:
    """Mean trajectory per condition (circular means for angles) with counts, sd and 95 % band -> average/means.parquet.

    Trials (kind = trial) are averaged; when a table holds only published means (pair-carriage-2022),
    those are carried over unchanged (spread columns empty) so that later stages can compare them.
    A grouping column (e.g. condition) missing for some or all trials is refused: the means would
    pool unrelated trials.
    """
    import numpy as np

    from cobot_analysis.averaging import MEANS, check_groups, mean_trajectories
    from cobot_analysis.compare import default_groups
    from cobot_analysis.console import warn
    from cobot_analysis.schema import TRAJECTORIES, read_table, write_table
    from cobot_analysis.workspace import Stage

    path, ts = _trajectories(out, trajectories)
    cols = _by(by, list(ts.meta.columns), path)
    groups = cols or default_groups(ts.meta)
    trials = ts.subset(ts.meta["kind"].eq("trial").to_numpy())
    if len(trials):
        check_groups(trials.meta, groups, path)
    with Stage(out, "average", inputs=[path], params={"by": groups}, force=force) as stage:
        if stage.skipped:
            return
        if len(trials):
            means = mean_trajectories(trials, groups)
            how = f"recomputed from {len(trials)} trajectories"
        else:
            warn(f"{path}: no per-trial trajectories; the published means are carried over unchanged")
            means = _plain(read_table(path, TRAJECTORIES))
            means = means[means["kind"].eq("mean")].copy()
            means["n_theta"] = np.where(means.groupby(["study", "trial", "entity"])["theta"].transform(lambda v: v.notna().all()),
                                        means["n_trials"], 0)
            for c in MEANS.columns:
                if c not in means.columns:
                    means[c] = np.nan
            how = "published means carried over (no per-trial data)"
        write_table(means, stage.path("means.parquet"), MEANS, grouping=groups, source=how)
        n_means = means.drop_duplicates(["trial", "entity"]).shape[0]
        first = means[means["sample"].eq(0)]
        lines = ["## Mean trajectories", "",
                 f"- Input: `{path.name}` ({_study(ts)}); {how}.",
                 f"- Grouping: {', '.join(groups)}; {n_means} mean trajectories; trials per mean "
                 f"{int(first['n_trials'].min())} to {int(first['n_trials'].max())}.",
                 "- Positions: sample-wise arithmetic mean; angles: circular mean (theta unwrapped along the path), "
                 "trajectories without orientation excluded from the angle means only; band = mean +- 1.96 sd.",
                 f"- Means without any orientation: {int((first['n_theta'] == 0).sum())}."]
        if len(trials) and "quality" in trials.meta.columns:
            cut = int(trials.meta["quality"].fillna("").str.split(";").map(lambda f: "truncated" in f).sum())
            if cut:
                lines.append(f"- {cut} of the {len(trials)} trajectories averaged are flagged `truncated` (they run off their "
                             "recording: travel time and path cover only the recorded part).")
        lines.append("")
        stage.path("results.md").write_text("\n".join(lines))
    finished("average", f"{n_means} means", stage.final_dir / "means.parquet")


# ---- compare ------------------------------------------------------------------------------------
@app.command("compare", rich_help_panel=PANEL_ANALYSIS, epilog=examples(
    "cobot-analysis compare --out walking",
    "cobot-analysis compare --out walking --convention published",
    "cobot-analysis compare --out walking --any-vs-any condition,entity",
    "cobot-analysis compare --out walking --comparison model \\",
    "    --against walking/generate/generated.parquet"))
def compare_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    trajectories: TrajOpt = None,
    means: Annotated[Optional[Path], typer.Option("--means", help="means.parquet (default: WS/average/means.parquet).")] = None,
    against: Annotated[Optional[Path], typer.Option("--against", help="Another trajectory table (e.g. model-generated paths) to compare with the means of the same group.")] = None,
    comparison: Annotated[str, typer.Option("--comparison", help="Name of the --against rows in the comparison column (e.g. model).")] = "against",
    any_any: Annotated[Optional[str], typer.Option("--any-vs-any", help="Also compare every two trials that agree on these comma-separated columns (e.g. condition,entity) -> comparison any-any.")] = None,
    by: ByOpt = None,
    convention: ConventionOpt = None,
    force: ForceOpt = False,
) -> None:
    """Distances d_xy, d_theta, d_gamma: individual vs mean, between scenarios, forward vs reversed return,
    recomputed vs published means, --against vs means, --any-vs-any -> compare/distances.parquet (one row per pair).

    --convention continuous (default: the pointwise distances of docs/methods.md sec. 3 on time-normalised
    samples) or published (both paths resampled by arc length first, angles wrapped one by one, population
    sd: the authors' scripts; writes compare-published/). An --against table made under the other
    convention is refused."""
    import pandas as pd

    from cobot_analysis import conventions
    from cobot_analysis.compare import (DISTANCES, WALKING_GROUPS, against_set, against_vs_mean, any_vs_any, compare_sets,
                                        default_groups, read_trajectory_set)
    from cobot_analysis.schema import table_metadata, write_table
    from cobot_analysis.workspace import Stage, find_input

    conv = conventions.get(convention or "continuous")
    path, ts = _trajectories(out, trajectories)
    means_path = means or find_input(out, "means.parquet", ["average"], "--means")
    mts = read_trajectory_set(means_path, ("means",))
    stored = table_metadata(means_path).get("grouping")
    groups = _by(by, list(ts.meta.columns), path) or stored or default_groups(ts.meta)
    other = against_set(against, mts.n_samples, conv) if against is not None else None
    same = _by(any_any, list(ts.meta.columns), path)
    inputs = [path, means_path] + ([against] if against else [])
    params = {"by": groups, "label": comparison, "any_vs_any": same, "convention": conv.name}
    with Stage(out, conventions.stage_name("compare", conv), inputs=inputs, params=params, force=force) as stage:
        if stage.skipped:
            return
        ts, mts = ts.compared_as(conv.comparison), mts.compared_as(conv.comparison)
        if other is not None:
            other.angle_difference = conv.comparison.angle_difference
        trials = ts.subset(ts.meta["kind"].eq("trial").to_numpy())
        parts = [compare_sets(trials, mts, by=groups)]
        published = ts.subset(ts.meta["kind"].eq("mean").to_numpy())
        if len(published) and len(trials):  # our means vs the authors' means of the same condition
            keys = [c for c in groups if c in WALKING_GROUPS or c in ("direction", "scenario", "end_orientation")]
            parts.append(any_vs_any(mts, same=keys, comparison="mean-published", other=published))
        if same:
            parts.append(any_vs_any(trials, same=["study", *same]))
        if other is not None:
            parts.append(against_vs_mean(other, mts, groups, comparison, against))
        d = pd.concat([p for p in parts if len(p)] or parts[:1], ignore_index=True)
        d["convention"] = conv.name
        write_table(d, stage.path("distances.parquet"), DISTANCES, grouping=groups, convention=conv.name)
        ddof = conv.comparison.sd_ddof
        summary = d.groupby(["comparison", "entity"])[["d_xy", "d_theta", "d_gamma"]].agg(
            ["mean", lambda v: v.std(ddof=ddof), "count"]).rename(columns={"<lambda_0>": "std"})
        how = ("pointwise on the time-normalised samples, angle differences wrapped to [-pi, pi], sample sd"
               if conv.name == "continuous" else
               "after resampling both paths by arc length (scipy splprep, s = 0), each angle wrapped to [-pi, pi] on "
               "its own, population sd (the authors' scripts)")
        lines = [f"## Distances between trajectories ({conv.name} convention)", "",
                 f"d_xy (m), d_theta (rad), d_gamma (rad, N-1 samples) (docs/methods.md sec. 3, 11), {how}; "
                 "symmetry = forward vs time-reversed return; angular distances only where both trajectories have "
                 "orientation.", "",
                 "| comparison | entity | n | d_xy mean +- sd | d_theta mean +- sd | d_gamma mean +- sd |", "|---|---|---|---|---|---|"]
        for (comp, ent), r in summary.iterrows():
            fmt = [f"{r[(k, 'mean')]:.3f} +- {r[(k, 'std')]:.3f} (n={int(r[(k, 'count')])})" if r[(k, "count")] else "n/a"
                   for k in ("d_xy", "d_theta", "d_gamma")]
            lines.append(f"| {comp} | {ent} | {int(r[('d_xy', 'count')])} | " + " | ".join(fmt) + " |")
        stage.path("results.md").write_text("\n".join(lines) + "\n")
    finished(f"compare ({conv.name})", f"{len(d)} compared pairs", stage.final_dir / "distances.parquet")


# ---- stats --------------------------------------------------------------------------------------
def default_config(study: str) -> Path:
    """``pipelines/<study>.toml`` in the current directory or the source tree; walking / pair fallbacks."""
    names = [study]
    if "walking" in study:
        names.append("walking-2020")
    elif "pair" in study:
        names += ["synthetic-pairs", "pair-carriage-2022"] if "synth" in study else ["pair-carriage-2022"]
    for base in (Path.cwd() / "pipelines", PIPELINES):
        for n in names:
            if (base / f"{n}.toml").is_file():
                return base / f"{n}.toml"
    raise InputError(f"no statistics configuration for study {study!r}", path=PIPELINES, remedy="pass --config FILE.toml")


@app.command("stats", rich_help_panel=PANEL_ANALYSIS, epilog=examples(
    "cobot-analysis stats --out walking",
    "cobot-analysis stats --out walking --config pipelines/walking-2020.toml"))
def stats_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    config: Annotated[Optional[Path], typer.Option("--config", help="Declarative analyses (default: pipelines/<study>.toml).")] = None,
    trajectories: TrajOpt = None,
    distances: Annotated[Optional[Path], typer.Option("--distances", help="distances.parquet (default: WS/compare/).")] = None,
    durations: Annotated[Optional[Path], typer.Option("--durations", help="Published per-trial durations (default: WS/import-published/durations.parquet if present).")] = None,
    anthropometrics: Annotated[Optional[Path], typer.Option("--anthropometrics", help="Directory with subjects.csv (id, weight, height) and pairs.csv (id, subject1, subject2).")] = None,
    convention: ConventionOpt = None,
    force: ForceOpt = False,
) -> None:
    """Every statistical question of the study's configuration (tests, effect sizes, Holm) -> stats/stats.parquet and stats.md.

    --convention published: on the distances of compare-published/ (the authors' comparison); writes
    stats-published/."""
    from cobot_analysis.compare import DISTANCES
    from cobot_analysis.console import track, warn
    from cobot_analysis.schema import read_table, write_table
    from cobot_analysis.stats import analyses
    from cobot_analysis.stats import config as cfg
    from cobot_analysis.stats.sources import build_sources, read_anthropometrics
    from cobot_analysis.workspace import Stage, find_input

    study_cfg = cfg.load(config) if config else None  # validate a given configuration before anything else
    path, ts = _trajectories(out, trajectories)
    study = _study(ts)
    if study_cfg is None:
        config = default_config(study)
        study_cfg = cfg.load(config)
    cfg.check_study(study_cfg, study)
    from cobot_analysis import conventions

    conv = conventions.get(convention or "continuous")
    dist_path = distances or find_input(out, "distances.parquet", [conventions.stage_name("compare", conv)], "--distances")
    dist = _plain(read_table(dist_path, DISTANCES))
    dur_path = durations or (out / "import-published" / "durations.parquet")
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
    anthro_dir = anthropometrics or (out / "synth-pairs" if (out / "synth-pairs" / "pairs.csv").is_file() else None)
    anthro = read_anthropometrics(anthro_dir)
    inputs = [p for p in (config, path, dist_path, dur_path if dur is not None else None) if p] + \
        ([anthro_dir / "subjects.csv", anthro_dir / "pairs.csv"] if anthro is not None else [])
    with Stage(out, conventions.stage_name("stats", conv), inputs=inputs, params={"config": str(config), "convention": conv.name},
               force=force) as stage:
        if stage.skipped:
            return
        sources = build_sources(ts, dist, dur, anthro, study_cfg.alpha)
        cfg.check_levels(study_cfg, sources)
        unmatched = cfg.filter_problems(study_cfg, sources)
        if unmatched:  # a typo, or data not there yet (e.g. no model compared): either way, said once
            warn(f"{config}: {len(unmatched)} filter value(s) match no row, their analyses are skipped (stats.md says "
                 f"why): {'; '.join(unmatched)}")
        table = analyses.run(study_cfg, sources, progress=track)
        table["study"] = study  # the data's study (a configuration may serve several, e.g. synthetic-walking)
        write_table(table, stage.path("stats.parquet"), analyses.STATS, config=str(config))
        md = analyses.markdown(table, f"Statistics: {study} ({Path(config).name}, {conv.name} convention)", study_cfg.alpha)
        stage.path("stats.md").write_text(md)
        ok = table["status"].eq("ok")
        note = (f"{int(ok.sum())} tests run, {int((~ok).sum())} skipped (reason in the table); "
                f"{int(table['significant'].sum())} significant after Holm within each family.")
        choices = [
            "Choices behind these numbers:",
            f"- Trajectories: {len(ts)} from `{path.name}`, {ts.n_samples} time-normalised samples each (as given; "
            "no further resampling); angle differences wrapped to [-pi, pi] before averaging (d_theta, d_gamma).",
            f"- Distances: `{dist_path.parent.name}/{dist_path.name}` ({conv.name} convention, docs/methods.md sec. 11).",
            f"- Configuration `{Path(config).name}`: each row names its subset, test and grouping. Holm correction "
            f"(statsmodels) within each family; alpha = {study_cfg.alpha}; descriptive rows (describe, largest subset) "
            "are outside the families.",
            "- Trial-level tests treat every trial as independent; `pair-level` rows first average each pair; "
            "`paired` rows (Wilcoxon) match values by the listed columns (several returns of a pair and goal are averaged); "
            "`unpaired` rows ignore the pairing.",
            "- Normality (Shapiro-Wilk for the pair study, Kolmogorov-Smirnov against N(mean, sd) for the walking study) "
            "only switches to the parametric test where the configuration names one.",
            "- Largest indistinguishable subset: exact search over all subsets up to 12 groups, greedy backward "
            "elimination above (the row says which).",
        ]
        stage.path("results.md").write_text(md + "\n" + note + "\n\n" + "\n".join(choices) + "\n")
    finished(f"stats ({conv.name})", note, stage.final_dir / "stats.parquet")


# ---- reconstruct --------------------------------------------------------------------------------
@app.command("reconstruct", rich_help_panel=PANEL_ANALYSIS, epilog=examples(
    "cobot-analysis reconstruct --out pairs"))
def reconstruct_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    trajectories: TrajOpt = None,
    wrt_table: Annotated[Optional[Path], typer.Option("--wrt-table", help="Directory with the published subject1_wrt_table.dat and subject2_wrt_table.dat (default: WS/import-published/subject_wrt_table.parquet when present).")] = None,
    scenario: Annotated[int, typer.Option("--scenario", help="Scenario whose trials give the relative pose and are reconstructed.")] = 3,
    force: ForceOpt = False,
) -> None:
    """Subjects reconstructed from the table trajectory (docs/methods.md sec. 8), d_xy / d_theta vs measured -> reconstruct/reconstruction.parquet."""
    import pandas as pd

    from cobot_analysis.console import track
    from cobot_analysis.reconstruct import RECONSTRUCTION, accuracy, read_wrt_table, relative_pose, relative_pose_table
    from cobot_analysis.schema import write_table
    from cobot_analysis.workspace import Stage

    path, ts = _trajectories(out, trajectories)
    if not ts.meta["entity"].eq("table").any():
        raise InputError("no table trajectories to reconstruct the subjects from", path=path, remedy="use pair-study trajectories")
    imported = out / "import-published" / "subject_wrt_table.parquet"
    if wrt_table:
        published, inputs = read_wrt_table(wrt_table), [path, wrt_table / "subject1_wrt_table.dat", wrt_table / "subject2_wrt_table.dat"]
    elif imported.is_file():
        published, inputs = relative_pose_table(_plain(pd.read_parquet(imported))), [path, imported]
    else:
        published, inputs = None, [path]
    with Stage(out, "reconstruct", inputs=inputs, params={"scenario": scenario}, force=force) as stage:
        if stage.skipped:
            return
        parts = []
        from_trials = relative_pose(ts, scenario, "trial")
        if from_trials:
            parts.append(accuracy(ts, from_trials, "trials", scenario, progress=track))
        if published:
            parts.append(accuracy(ts, published, "published", scenario, progress=track))
        if not parts:
            from_means = relative_pose(ts, scenario, "mean")
            parts.append(accuracy(ts, from_means, "means", scenario, progress=track))
        rec = pd.concat(parts, ignore_index=True)
        if rec.empty:
            raise InputError(f"no scenario-{scenario} trajectory has both a table and a subject", path=path,
                             remedy="check --scenario and the entities of the trajectories")
        write_table(rec, stage.path("reconstruction.parquet"), RECONSTRUCTION)
        s = rec.groupby(["relative_pose", "kind", "direction", "entity"])[["d_xy", "d_theta"]].agg(["mean", "std", "count"])
        lines = ["## Subjects reconstructed from the table", "",
                 f"Relative pose: mean subject pose in the table frame over scenario-{scenario} trajectories "
                 "(or the published subject*_wrt_table.dat); reconstructed trajectories compared with the measured ones "
                 "(docs/methods.md sec. 8).", "",
                 "| relative pose | trajectories | direction | subject | n | d_xy (m) mean +- sd | d_theta (rad) mean +- sd |",
                 "|---|---|---|---|---|---|---|"]
        for (src, kind, direction, ent), r in s.iterrows():
            lines.append(f"| {src} | {kind} | {direction} | {ent} | {int(r[('d_xy', 'count')])} | "
                         f"{r[('d_xy', 'mean')]:.3f} +- {r[('d_xy', 'std')]:.3f} | {r[('d_theta', 'mean')]:.3f} +- {r[('d_theta', 'std')]:.3f} |")
        stage.path("results.md").write_text("\n".join(lines) + "\n")
    finished("reconstruct", f"{len(rec)} reconstructions", stage.final_dir / "reconstruction.parquet")


# ---- report -------------------------------------------------------------------------------------
#: Study names (the 'study' column of the data) -> the design their report follows.
STUDY_DESIGNS = {"walking-2020": "walking", "synthetic-walking": "walking", "pair-carriage-2022": "pairs", "synthetic-pairs": "pairs"}


@app.command("report", rich_help_panel=PANEL_REPORT, epilog=examples(
    "cobot-analysis report synthetic-walking --out walking --to walking-report",
    "cobot-analysis report synthetic-pairs --out pairs --to pairs-report"))
def report_command(
    study: Annotated[str, typer.Argument(help=f"The workspace's study: {', '.join(STUDY_DESIGNS)}.")],
    out: OutOpt = DEFAULT_OUT_PATH,
    to: Annotated[Optional[Path], typer.Option("--to", help="Report directory (default: reports/STUDY).")] = None,
    force: ForceOpt = False,
) -> None:
    """Markdown report with tables and figures (PNG + PDF) of a study's workspace -> --to (and report/ in the workspace)."""
    from cobot_analysis.reports.builders import build_report, report_inputs
    from cobot_analysis.workspace import Stage

    if study not in STUDY_DESIGNS:
        raise InputError(f"unknown study {study!r}", remedy=f"use one of {', '.join(STUDY_DESIGNS)}")
    design = STUDY_DESIGNS[study]
    inputs = report_inputs(out)
    if not inputs:
        raise InputError("nothing to report in this workspace", path=out, remedy="run average, compare and stats first")
    to = to or Path("reports") / study
    with Stage(out, "report", inputs=list(inputs.values()), params={"study": design}, force=force) as stage:
        if not stage.skipped:
            build_report(design, inputs, stage, out)
    tmp = to.with_name(f".{to.name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(stage.final_dir, tmp, ignore=shutil.ignore_patterns("manifest.json"))
    if to.exists():
        shutil.rmtree(to)
    tmp.rename(to)
    figures = len(list(to.glob("*.png")))
    finished(f"report ({study})", count(figures, "figure"), to / "README.md")
