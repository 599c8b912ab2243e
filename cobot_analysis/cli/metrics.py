"""``metrics show``, ``metrics check`` and ``metrics update``: the stages' headline numbers
(``<stage>/metrics.json``) against a committed baseline (``tests/baselines/``).

    cobot-analysis metrics check tests/baselines/walking-2020.json WS [WS-MODELS ...]
    cobot-analysis metrics update tests/baselines/walking-2020.json WS [WS-MODELS ...]
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from cobot_analysis.cli.app import PANEL_REPORT, PanelGroup, app, examples

metrics_app = typer.Typer(help="Stage metrics (metrics.json) against a committed baseline: show, check, update.",
                          cls=PanelGroup, no_args_is_help=True, rich_markup_mode=None)
app.add_typer(metrics_app, name="metrics", rich_help_panel=PANEL_REPORT)

BaselineArg = Annotated[Path, typer.Argument(help="Baseline JSON (e.g. tests/baselines/walking-2020.json); tolerances next to it.")]
WorkspacesArg = Annotated[list[Path], typer.Argument(help="Workspaces of one study (e.g. its analysis and its model stages of each convention).")]


@metrics_app.command("show", epilog=examples("cobot-analysis metrics show robot"))
def show_command(workspaces: WorkspacesArg) -> None:
    """Print every stage metric of the workspaces: name, value, unit, stage, convention."""
    from cobot_analysis.regression.baseline import collect

    study, metrics, errors, _ = collect(workspaces)  # refuses workspaces without metrics
    typer.echo(f"study: {study or 'unknown'}")
    for key, m in metrics.items():
        typer.echo(f"{key}\t{m.value!r}\t{m.unit}\t{m.stage}\t{m.convention or ''}")
    for e in errors:
        typer.echo(f"error: {e}", err=True)


@metrics_app.command("check", epilog=examples(
    "cobot-analysis metrics check robot-baseline.json robot",
    "cobot-analysis metrics check robot-baseline.json robot --failures-only"))
def check_command(
    baseline: BaselineArg,
    workspaces: WorkspacesArg,
    failures_only: Annotated[bool, typer.Option("--failures-only", help="List only the metrics that are not ok.")] = False,
) -> None:
    """Compare the workspaces' metrics with a baseline and print the table: metric, baseline, now,
    tolerance, change, status.

    Exit 0 when every metric is within its tolerance; 1 when one is outside it, missing (dropped by
    the stages) or new (not in the baseline: `metrics update` adds it); 2 for a bad baseline or
    tolerance file, a metric without tolerance, a missing stage, or workspaces of different studies.
    """
    from cobot_analysis.regression.baseline import OK, compare, summary, table

    rows, errors = compare(baseline, workspaces)
    typer.echo(f"metrics check: {baseline} vs {', '.join(map(str, workspaces))}")
    typer.echo(table(rows, only_failures=failures_only))
    for e in errors:
        typer.echo(f"error: {e}")
    bad = [r for r in rows if r.status != OK]
    typer.echo(("FAILED: " if bad else "passed: ") + summary(rows)
               + (f"; not ok: {', '.join(r.key for r in bad[:5])}{' ...' if len(bad) > 5 else ''}" if bad else ""))
    if bad:
        typer.echo(f"If the change is intended, review it and run `cobot-analysis metrics update {baseline} "
                   f"{' '.join(map(str, workspaces))}` (or `make regression-update`).")
        raise typer.Exit(1)


@metrics_app.command("update", epilog=examples(
    "cobot-analysis metrics update robot-baseline.json robot --dry-run",
    "cobot-analysis metrics update robot-baseline.json robot"))
def update_command(
    baseline: BaselineArg,
    workspaces: WorkspacesArg,
    dry_run: Annotated[bool, typer.Option("--dry-run", help="Print the differences only; leave the baseline as it is.")] = False,
) -> None:
    """Write the workspaces' metrics into the baseline, printing every changed, added and removed value.

    An explicit, reviewable step: commit the baseline with the change that moved its numbers, and
    say why in the commit message. Tolerances are not touched (edit the .tolerances.toml by hand).
    """
    from cobot_analysis.console import warn
    from cobot_analysis.regression.baseline import update

    lines, warnings, changed = update(baseline, workspaces, write=not dry_run)
    for line in lines:
        typer.echo(line)
    for w in warnings:
        warn(w)
    n = {k: sum(line.startswith(k) for line in lines) for k in ("changed", "added", "removed")}
    counts = f"{n['changed']} changed, {n['added']} added, {n['removed']} removed"
    if not changed:
        typer.echo(f"{baseline}: unchanged")
    elif dry_run:
        typer.echo(f"{baseline}: {counts} (dry run: not written)")
    else:
        typer.echo(f"{baseline}: {counts}; written (review with git diff)")
