"""``cobot-analysis import-published``: the published CoBot datasets -> trajectories.parquet."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from cobot_analysis.cli.app import DEFAULT_OUT_PATH, PANEL_DATA, ForceOpt, OutOpt, app, examples


class Dataset(str, Enum):
    walking_2020 = "walking-2020"
    pair_carriage_2022 = "pair-carriage-2022"


@app.command("import-published", rich_help_panel=PANEL_DATA, epilog=examples(
    "cobot-analysis import-published walking-2020 \\",
    "    ../shared/datasets/walking-2020 --out walking-2020",
    "cobot-analysis import-published pair-carriage-2022 \\",
    "    ../shared/datasets/pair-carriage-2022 --out pair-carriage-2022"))
def import_published_command(
    dataset: Annotated[Dataset, typer.Argument(help="Which published dataset PATH holds.")],
    path: Annotated[Path, typer.Argument(help="Folder of the dataset (e.g. ../shared/datasets/walking-2020).")],
    out: OutOpt = DEFAULT_OUT_PATH,
    gamma_limit: Annotated[float, typer.Option("--gamma-limit", help="walking-2020: flag a trajectory implausible_gamma when its median |gamma| over 20-80 % of the path exceeds this (rad) (>= 0).")] = 0.5,
    force: ForceOpt = False,
) -> None:
    """Read a published dataset into OUT/import-published/trajectories.parquet (500-sample
    trajectories; pairs: also durations.parquet and subject_wrt_table.parquet) and report its
    data-quality facts (missing orientation, implausible gamma, trial counts) in results.md.
    """
    from cobot_analysis.console import info
    from cobot_analysis.stages import data

    done = data.import_published(out, dataset.value, path, gamma_limit=gamma_limit, force=force)
    if not done.skipped:
        info(f"[green]import-published[/green]: {done.result.summary()} -> {done.directory}")
