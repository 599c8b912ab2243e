"""``cobot-analysis results``: fragments assembled in pipeline order, whatever order the stages ran in."""

from __future__ import annotations

import os

from cobot_analysis.reports.results import assemble_results


def test_fragments_follow_the_pipeline_order(tmp_path):
    ws = tmp_path / "ws"
    for i, stage in enumerate(["predict", "fit-ioc-subjects", "custom-stage", "fit-ioc", "import-published"]):
        (ws / stage).mkdir(parents=True)
        (ws / stage / "results.md").write_text(f"## {stage}\n")
        os.utime(ws / stage / "results.md", (1000 + i, 1000 + i))  # ran in this order
    text = assemble_results([ws])
    order = [line[3:] for line in text.splitlines() if line.startswith("## ")]
    assert order == ["import-published", "fit-ioc", "fit-ioc-subjects", "predict", "custom-stage"]


def test_results_without_fragments_is_an_input_error(cli, tmp_path):
    (tmp_path / "empty").mkdir()
    code, _, err = cli("results", tmp_path / "empty", "--to", tmp_path / "out.md")
    assert code == 2 and "no results.md fragment" in err and not (tmp_path / "out.md").exists()
