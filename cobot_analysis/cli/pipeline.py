"""``demo`` (the whole pipeline on the embedded synthetic default) and ``results``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from cobot_analysis.cli.app import PANEL_REPORT, DEFAULT_OUT_PATH, OutOpt, app, count, examples, finished


@app.command("results", rich_help_panel=PANEL_REPORT, epilog=examples(
    "cobot-analysis results walking robot --to results.md",
    'cobot-analysis results walking --to walking.md --title "Synthetic walking"'))
def results_command(
    workspaces: Annotated[list[Path], typer.Argument(help="Workspaces whose stages wrote results.md fragments.")],
    to: Annotated[Path, typer.Option("--to", help="Markdown file to write.")] = Path("docs/results.md"),
    title: Annotated[str, typer.Option(help="Title of the document.")] = "Results",
    preface: Annotated[str, typer.Option(help="Paragraph under the title (what was run).")] = "",
) -> None:
    """Assemble docs/results.md from the results.md fragments of the given workspaces (generated, never typed)."""
    from cobot_analysis.reports.results import write_results
    from cobot_analysis.workspace import check_destination

    sections = write_results(workspaces, check_destination(to, "--to", directory=False), title=title, preface=preface)
    finished("results", f"{count(sections, 'section')} from {count(len(workspaces), 'workspace')}", to)


#: synth options per demo size: walking study, pair study. "default" is the full walking design and
#: 6 of the 20 pairs (all goals and scenarios: 324 trials, 972 trajectories, about 0.8 GB of C3D
#: instead of 2.7 GB for the full pair design).
DEMO_SIZES = {
    "small": (["--subjects", "2", "--repetitions", "1", "--conditions", "8"], ["--pairs", "2", "--goals", "3"]),
    "default": ([], ["--pairs", "6"]),
    "full": ([], []),
}


DEMO_IOC_EVALUATIONS = 6  # upper-level evaluations of the demo's IOC, per convention
#: the demo predicts this many walking trials of each start condition (a stratified sample: 40 of the 1200
#: trials at the default size, every condition, the subjects taking turns; api.prediction.stratified)
DEMO_PREDICT_PER_CONDITION = 1


def demo_steps(out: Path, size: str, jobs: int | None) -> dict[str, list[list[str]]]:
    """The stage commands of the demo, per study workspace (what a user would type)."""
    walking, pairs, loc = out / "walking", out / "pairs", out / "localisation"
    j = ["--jobs", str(jobs)] if jobs else []
    size_w, size_p = DEMO_SIZES[size]
    analysis = ["average", "compare", "stats"]
    means = str(walking / "average" / "means.parquet")
    models = []  # the walking-path models on the synthetic means, under both conventions (docs/methods.md sec. 11)
    for conv in ("continuous", "published"):
        models += [
            ["generate", "--out", str(walking), "--study", "walking-2020", "--weights", "walking-2021", "--convention", conv,
             *(["--means", means] if conv == "published" else []), *j],
            # a short IOC: DEMO_IOC_EVALUATIONS upper-level evaluations (a full fit: make walking)
            ["fit-ioc", "--out", str(walking), "--convention", conv, "--max-evaluations", str(DEMO_IOC_EVALUATIONS),
             "--no-compare", *j],
            # a short prediction: DEMO_PREDICT_PER_CONDITION trial(s) of each condition, (N0, N_OC) = (50, 100)
            ["predict", "--out", str(walking), "--kind", "trial", "--convention", conv, "--settings", "50:100",
             "--per-condition", str(DEMO_PREDICT_PER_CONDITION), *j],
        ]
    return {
        "walking": [
            ["synth", "walking", "--out", str(walking), *size_w, *j],
            ["import", str(walking / "synth-walking" / "protocol.yaml"), "--out", str(walking), *j],
            ["preprocess", "--out", str(walking), *j],
            *([cmd, "--out", str(walking)] for cmd in analysis),
            *models,
            ["report", "synthetic-walking", "--out", str(walking), "--to", str(out / "reports" / "walking")],
        ],
        "pairs": [
            ["synth", "pairs", "--out", str(pairs), *size_p, *j],
            ["import", str(pairs / "synth-pairs" / "protocol.yaml"), "--out", str(pairs), *j],
            ["preprocess", "--out", str(pairs), *j],
            *([cmd, "--out", str(pairs)] for cmd in [*analysis, "reconstruct"]),
            ["report", "synthetic-pairs", "--out", str(pairs), "--to", str(out / "reports" / "pairs")],
        ],
        "localisation": [
            ["synth", "localisation", "--out", str(loc)],
            ["localisation", "--out", str(loc), "--map-name", "synthetic"],
        ],
    }


@app.command("demo", rich_help_panel=PANEL_REPORT, epilog=examples(
    "cobot-analysis demo --out demo --size small"))
def demo_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    size: Annotated[str, typer.Option("--size", help="small (a quick look), default (full walking study, 6 of the 20 pairs) or full (both full designs).")] = "default",
    jobs: Annotated[int | None, typer.Option("--jobs", "-j", min=1, help="Local worker processes (default: all cores).")] = None,
) -> None:
    """Run the whole pipeline on the embedded synthetic studies and write a report.

    Generates the synthetic walking study (raw C3D), pair-carriage study and a robot run (rosbags),
    runs every stage on each, then writes OUT/report.md. Each study has its own workspace under
    OUT; stages already up to date are skipped.
    """
    from cobot_analysis.reports.results import DEMO_PREFACE, assemble_results

    if size not in DEMO_SIZES:
        raise typer.BadParameter(f"--size must be one of {', '.join(DEMO_SIZES)}", param_hint="--size")
    studies = demo_steps(out, size, jobs)
    for steps in studies.values():
        run_steps(steps)
    report = out / "report.md"
    report.write_text(assemble_results([out / s for s in studies], title="cobot-analysis demo report (synthetic studies)",
                                       preface=DEMO_PREFACE))
    finished("demo", f"{len(studies)} studies, Parquet outputs under {', '.join(str(out / s) for s in studies)}", report)


def run_steps(steps: list[list[str]]) -> None:
    """Run CLI steps in-process, at the verbosity of this run (-q, -v); stop at the first failing one
    with its exit code."""
    from cobot_analysis.cli import run
    from cobot_analysis.console import info, verbosity

    level = {0: ["-q"], 2: ["-v"]}.get(verbosity(), [])
    for argv in steps:
        info(f"[bold]$ cobot-analysis {' '.join(argv)}[/bold]")
        code = run([*level, *argv])
        if code != 0:
            raise SystemExit(code)
