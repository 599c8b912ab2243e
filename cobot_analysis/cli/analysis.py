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

from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis.cli.app import (PANEL_ANALYSIS, PANEL_REPORT, DEFAULT_OUT_PATH, ConventionOpt, ForceOpt, OutOpt, app, count,
                                   examples, finished)

ByOpt = Annotated[Optional[str], typer.Option("--by", help="Comma-separated grouping columns of the means (default: walking condition x entity; pairs goal x direction x scenario x configuration x end orientation x entity).")]
TrajOpt = Annotated[Optional[Path], typer.Option("--trajectories", help="trajectories.parquet (default: the workspace's preprocess or import-published output).")]


def _columns(value: Optional[str]) -> list[str] | None:
    """``a,b`` -> ["a", "b"] (None when not given)."""
    return [c.strip() for c in value.split(",") if c.strip()] if value else None


# ---- average ------------------------------------------------------------------------------------
@app.command("average", rich_help_panel=PANEL_ANALYSIS, epilog=examples(
    "cobot-analysis average --out walking",
    "cobot-analysis average --out walking --weigh subjects",
    "cobot-analysis average --out walking --by condition,entity"))
def average_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    trajectories: TrajOpt = None,
    by: ByOpt = None,
    max_spread: Annotated[Optional[float], typer.Option("--max-spread", help="Largest spread (m) of a group's start or end points around their median; beyond it the trials do not share a frame and their mean is flagged frames_differ, not compared (default 1 m) (>= 0).")] = None,
    weigh: Annotated[str, typer.Option("--weigh", help="trials: every trajectory weighs alike (the published method); subjects: the mean of each subject's mean (each pair's, in the pair study), sd between them, so a subject with more trials in a condition weighs no more.")] = "trials",
    force: ForceOpt = False,
) -> None:
    """Mean trajectory per condition (circular means for angles) with counts, sd and 95 % band -> average/means.parquet.

    Trials (kind = trial) are averaged; when a table holds only published means (pair-carriage-2022),
    those are carried over unchanged (spread columns empty) so that later stages can compare them.
    A grouping column (e.g. condition) missing for some or all trials is refused: the means would
    pool unrelated trials.
    """
    from cobot_analysis.stages import analysis

    done = analysis.average(out, trajectories=trajectories, by=_columns(by), max_spread=max_spread, weigh=weigh, force=force)
    if not done.skipped:
        finished("average", done.result.summary(), done.directory / "means.parquet")


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
    from cobot_analysis.stages import analysis

    done = analysis.compare(out, trajectories=trajectories, means=means, against=against, comparison=comparison,
                            any_vs_any=_columns(any_any), by=_columns(by), convention=convention, force=force)
    if not done.skipped:
        finished(f"compare ({done.result.convention})", done.result.summary(), done.directory / "distances.parquet")


# ---- stats --------------------------------------------------------------------------------------
@app.command("stats", rich_help_panel=PANEL_ANALYSIS, epilog=examples(
    "cobot-analysis stats --out walking",
    "cobot-analysis stats --out walking \\",
    "    --config walking/synth-walking/study.toml"))
def stats_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    config: Annotated[Optional[Path], typer.Option("--config", help="Study file with the questions (docs/statistics.md; default: study.toml beside the protocol, else pipelines/<study>.toml, else descriptive statistics).")] = None,
    trajectories: TrajOpt = None,
    distances: Annotated[Optional[Path], typer.Option("--distances", help="distances.parquet (default: WS/compare/).")] = None,
    durations: Annotated[Optional[Path], typer.Option("--durations", help="Published per-trial durations (default: WS/import-published/durations.parquet if present).")] = None,
    anthropometrics: Annotated[Optional[Path], typer.Option("--anthropometrics", help="Directory with subjects.csv (id, weight, height) and pairs.csv (id, subject1, subject2) (default: the subjects and pairs of the protocol the workspace's import read).")] = None,
    convention: ConventionOpt = None,
    force: ForceOpt = False,
) -> None:
    """Every statistical question of the study file (tests, effect sizes, Holm) -> stats/stats.parquet and stats.md.

    --convention published: on the distances of compare-published/ (the authors' comparison); writes
    stats-published/."""
    from cobot_analysis.stages import analysis

    done = analysis.statistics(out, config=config, trajectories=trajectories, distances=distances, durations=durations,
                               anthropometrics=anthropometrics, convention=convention, force=force)
    if not done.skipped:
        finished(f"stats ({convention or 'continuous'})", done.result.summary(), done.directory / "stats.parquet")


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
    from cobot_analysis.stages import analysis

    done = analysis.reconstruct(out, trajectories=trajectories, wrt_table=wrt_table, scenario=scenario, force=force)
    if not done.skipped:
        finished("reconstruct", done.result.summary(), done.directory / "reconstruction.parquet")


# ---- report -------------------------------------------------------------------------------------
@app.command("report", rich_help_panel=PANEL_REPORT, epilog=examples(
    "cobot-analysis report --out walking --to walking-report",
    "cobot-analysis report synthetic-pairs --out pairs --to pairs-report"))
def report_command(
    study: Annotated[Optional[str], typer.Argument(help="The workspace's study, checked when given (default: the study of the data).")] = None,
    out: OutOpt = DEFAULT_OUT_PATH,
    to: Annotated[Optional[Path], typer.Option("--to", help="Report directory (default: reports/STUDY).")] = None,
    study_file: Annotated[Optional[Path], typer.Option("--study-file", help="Study file: labels, abbreviations, questions (docs/statistics.md; default: study.toml beside the protocol, else pipelines/<study>.toml).")] = None,
    force: ForceOpt = False,
) -> None:
    """Markdown report with tables and figures (PNG + PDF) of a study's workspace -> --to (and report/ in the workspace)."""
    from cobot_analysis.stages import analysis

    done = analysis.report(out, study, to=to, study_file=study_file, force=force)
    figures = len(list(done.copied_to.glob("*.png")))
    finished(f"report ({study})" if study else "report",
             count(figures, "figure") + (" (the report up to date in the workspace, copied)" if done.skipped else ""),
             done.copied_to / "README.md")
