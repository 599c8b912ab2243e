"""The ``cobot-analysis`` typer application and the options every stage shares.

Command modules in this package register their commands on ``app`` (or on a sub-app such as
``synth_app``); they import heavy libraries inside the command body so that ``--help`` is fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis import __version__
from cobot_analysis.console import console, set_verbosity, verbosity
from cobot_analysis.workspace import DEFAULT_OUT


def finished(stage: str, what: str, where) -> None:
    """The line every stage ends with: ``stage: what -> where`` (one line, silent under --quiet)."""
    from rich.markup import escape

    if verbosity() >= 1:
        console.print(f"[green]{escape(stage)}[/green]: {escape(str(what))} -> {escape(str(where))}", soft_wrap=True)


def count(n: int, noun: str, plural: str | None = None) -> str:
    """``1 figure``, ``2 figures`` (``plural`` where it is not noun + s)."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


EXIT_CODES = ("Exit codes: 0 success, 1 internal error, 2 bad usage or bad input, 130 interrupted (Ctrl-C), "
              "143 terminated (SIGTERM). An interrupted stage writes nothing and stops its workers.")
app = typer.Typer(
    name="cobot-analysis",
    help="Reproducible analysis of motion-capture studies of walking and collaborative carriage (CoBot).",
    epilog=EXIT_CODES,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)
synth_app = typer.Typer(help="Generate a deterministic synthetic study (raw C3D, trials, bags) with its ground truth.",
                        no_args_is_help=True)
app.add_typer(synth_app, name="synth", rich_help_panel="Data")

# Panels that group the commands in --help, in pipeline order.
PANEL_DATA = "Data"
PANEL_PROCESS = "Processing"
PANEL_ANALYSIS = "Analysis"
PANEL_MODELS = "Models"
PANEL_LOCALISATION = "Localisation"
PANEL_REPORT = "Reports"

# ---- options shared by stages --------------------------------------------------------------------
OutOpt = Annotated[Path, typer.Option("--out", "-o", help="Workspace directory: one sub-directory per stage.")]
ForceOpt = Annotated[bool, typer.Option("--force", help="Redo the stage even if inputs and parameters are unchanged.")]
JobsOpt = Annotated[Optional[int], typer.Option("--jobs", "-j", min=1, help="Local worker processes (default: all cores).")]
SchedulerOpt = Annotated[Optional[str], typer.Option("--scheduler", help="Dask scheduler ADDRESS (e.g. tcp://host:8786); default: local process pool.")]
SeedOpt = Annotated[int, typer.Option("--seed", help="Random seed (results are deterministic for a given seed).")]
ConventionOpt = Annotated[Optional[str], typer.Option(
    "--convention", help="published (the authors' discrete conventions, reproduces the papers) or continuous (ours); "
                         "docs/methods.md sec. 11. Outputs of the published convention go to STAGE-published/.")]
DEFAULT_OUT_PATH = DEFAULT_OUT


def _version(value: bool) -> None:
    if value:
        typer.echo(f"cobot-analysis {__version__}")
        raise typer.Exit()


@app.callback()
def _global(
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="More details (and tracebacks on internal errors).")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Only errors; no progress bars.")] = False,
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, help="Show the version and exit.")] = False,
) -> None:
    """Stages read and write Parquet in the workspace (--out); each writes a manifest.json.

    Exit codes: see EXIT_CODES (the epilog of --help).
    """
    set_verbosity(0 if quiet else 2 if verbose else 1)
