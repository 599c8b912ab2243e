"""Stages run into a workspace: each function here takes the workspace (``out``) and the stage's
options, finds its inputs in the workspace, runs the computation of ``cobot_analysis.api`` inside a
``workspace.Stage`` (atomic outputs, manifest, skip when up to date) and writes the tables, figures
and ``results.md`` fragment. The CLI commands call these functions and print their summary line.

One pattern for every stage (docs: DEVELOPERS.md)::

    def average(out, *, trajectories=None, by=None, force=False) -> Outcome:
        path, table = inputs.trajectories(out, trajectories)        # find and read the inputs
        with Stage(out, "average", inputs=[path], params=..., force=force) as stage:
            if stage.skipped:
                return Outcome.skip(stage)
            result = api.average(table, by=by)                       # the science: cobot_analysis.api
            stage.result = result                                    # its metrics() are the stage's metrics.json
            stage.write_table("means.parquet", result.means, MEANS)  # outputs with their schema
            stage.path("results.md").write_text(fragments.average(result))  # the report: cobot_analysis.reports
        return Outcome(stage.final_dir, result)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass
class Outcome:
    """What a stage run left: its directory and the API result (None when the stage was up to date and skipped)."""

    directory: Path
    result: Any = None
    copied_to: Path | None = None  # where the stage's outputs were also copied (``report --to``)

    @property
    def skipped(self) -> bool:
        return self.result is None

    @classmethod
    def skip(cls, stage) -> "Outcome":
        return cls(stage.final_dir, None)
