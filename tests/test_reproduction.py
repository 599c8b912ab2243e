"""The reproduction table of docs/results.md (reports/reproduction.py): our values read from a
workspace per convention, the 15 % verdict, and the measured accounts."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.reports import reproduction as rep


def _distances(ws, stage: str, d_theta: list[float]) -> None:
    (ws / stage).mkdir(parents=True)
    n = len(d_theta)
    pd.DataFrame({"model": ["table OC (published)"] * n, "d_xy": np.linspace(0.1, 0.2, n),
                  "d_theta": d_theta}).to_parquet(ws / stage / "distances.parquet")


def test_verdict_is_the_relative_difference_to_the_papers_mean():
    assert rep.verdict((0.1, 0.05), (0.114, 0.0, 3)) == "yes"
    assert rep.verdict((0.1, 0.05), (0.116, 0.0, 3)) == "no (+16%)"
    assert rep.verdict((0.1, None), None) == "–"


def test_table_reads_each_convention_from_its_own_stage(tmp_path):
    _distances(tmp_path, "fit-ioc-published", [0.2, 0.4, 6.0])
    _distances(tmp_path, "fit-ioc", [0.1, 0.3])
    lines = rep.table(tmp_path, "pair-carriage-2022", rep.accounts(tmp_path, "pair-carriage-2022"))
    row = next(line for line in lines if "d_theta (means" in line).split(" | ")
    pub = np.array([0.2, 0.4, 6.0])
    assert row[2] == f"{pub.mean():.4f} ± {pub.std(ddof=0):.4f} (n = 3)"  # published: population sd
    assert row[3] == f"0.2000 ± {np.std([0.1, 0.3], ddof=1):.4f} (n = 2)"  # continuous: sample sd
    assert row[4] == f"no ({(pub.mean() - 0.36) / 0.36:+.0%})"
    assert "1 of 3 means above pi (up to 6.00); without them 0.300, median of all 0.400" in row[5]
    assert "not run" in next(line for line in lines if "table prediction" in line)


@pytest.mark.parametrize("study", ["walking-2020", "pair-carriage-2022"])
def test_every_figure_has_a_paper_value_and_a_source(study):
    for fig in rep.FIGURES[study]:
        assert fig.paper[0] > 0 and fig.note and fig.unit in ("m", "rad")
