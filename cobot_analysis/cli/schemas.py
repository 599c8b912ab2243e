"""``cobot-analysis schemas``: print the documented Parquet schemas (docs/schemas.md)."""

from __future__ import annotations

import importlib
import pkgutil

import typer

import cobot_analysis
from cobot_analysis.cli.app import PANEL_REPORT, app, examples, finished


@app.command("schemas", rich_help_panel=PANEL_REPORT, epilog=examples("cobot-analysis schemas"))
def schemas_command() -> None:
    """Print the columns, types, units and descriptions of every Parquet table, as Markdown.

    Each file also carries them: units and descriptions as Arrow field metadata per column and as
    JSON under the 'cobot_analysis' key of the Parquet metadata (docs/schemas.md).
    """
    # Import every module so that all TableSchema declarations are registered.
    for mod in pkgutil.walk_packages(cobot_analysis.__path__, "cobot_analysis."):
        if not mod.name.startswith("cobot_analysis.cli") and not mod.name.endswith("__main__"):
            importlib.import_module(mod.name)
    from cobot_analysis.schema import schemas_markdown

    text = schemas_markdown()
    typer.echo(text)
    finished("schemas", f"{sum(line.startswith('## ') for line in text.splitlines())} tables", "stdout")
