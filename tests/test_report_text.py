"""What the report and the statistics table say of a small study (the five recordings of three labs):
one value per group is given as such, not with a spread of 0; no table of headers alone."""

from __future__ import annotations

from types import SimpleNamespace

import pandas as pd

from cobot_analysis.reports.analysis import compare_markdown
from cobot_analysis.stats.analyses import _summary


def test_describe_gives_one_value_without_a_spread():
    assert _summary({"BTK-A": [3.14], "BTK-B": [1.0, 2.0, 3.0], "none": []}) == \
        "BTK-A: 3.14 (n = 1); BTK-B: 2 [1.5, 2.5], 2 +- 1; none: none"


def _result(rows: list[dict], **excluded) -> SimpleNamespace:
    cols = ["comparison", "entity", "d_xy", "d_theta", "d_gamma"]
    return SimpleNamespace(distances=pd.DataFrame(rows, columns=cols), convention="continuous", excluded=excluded)


def test_no_compared_pair_gives_a_sentence_not_an_empty_table():
    md = compare_markdown(_result([], single=0, frames=3), sd_ddof=1)
    assert "| comparison |" not in md
    assert "No pair of trajectories was compared (below: which were left out and why)." in md
    assert "3 trial(s) whose mean mixes trajectories that do not share a frame" in md
    md = compare_markdown(_result([{"comparison": "individual-mean", "entity": "walker", "d_xy": 0.1, "d_theta": 0.2,
                                    "d_gamma": 0.3}] * 2), sd_ddof=1)
    assert "| individual-mean | walker | 2 | 0.100 +- 0.000 (n=2)" in md


def test_a_study_of_means_only_says_so_instead_of_zero_trajectories():
    import numpy as np

    from cobot_analysis.reports.builders import _data_section

    meta = pd.DataFrame({"kind": ["mean"] * 3, "entity": ["table", "table", "subject1"]})
    ts = SimpleNamespace(meta=meta, theta=np.zeros((3, 5)))
    lines, results = [], []
    _data_section(SimpleNamespace(title="Pairs"), {"ts": ts}, lines, results)
    assert "No individual trials in the data: 3 mean trajectories (subject1: 1, table: 2)." in lines
    assert "## Pairs: data" in results and not any("0 trajectories" in x for x in lines)


def test_published_model_rows_say_why_fit_ioc_gives_another_d_gamma():
    """One answer per question: under the published convention compare's model rows are against the recomputed
    means, fit-ioc's against the authors' mean block; the fragment says so with the two means' d_gamma."""
    rows = [{"comparison": "model", "entity": "walker", "d_xy": 0.08, "d_theta": 0.5, "d_gamma": 0.5},
            {"comparison": "mean-published", "entity": "walker", "d_xy": 0.0, "d_theta": 0.3, "d_gamma": 0.18},
            {"comparison": "mean-published", "entity": "walker", "d_xy": 0.0, "d_theta": 0.3, "d_gamma": 0.2}]
    published = SimpleNamespace(distances=pd.DataFrame(rows), convention="published", excluded={})
    md = compare_markdown(published, sd_ddof=0)
    assert "the same d_xy; d_gamma differs" in md and "(they differ by d_gamma 0.190 rad, row mean-published)" in md
    continuous = SimpleNamespace(distances=pd.DataFrame(rows), convention="continuous", excluded={})
    assert "d_gamma differs" not in compare_markdown(continuous, sd_ddof=1)  # there both compare the same means
