"""What the metric regression (tests/regression.py, run by .ci/run) prints: by default only what failed
and one line per study with its counts; every step and every "ok" row only with --verbose."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from cobot_analysis.schema import TRAJECTORIES, write_table
from cobot_analysis.synth.tables import walking_table

sys.path.insert(0, str(Path(__file__).parent))
import regression  # noqa: E402

BASELINES = Path(__file__).resolve().parent / "baselines"


@pytest.fixture
def study(tmp_path, monkeypatch):
    """A one-study regression: a small synthetic walking workspace through `average`, its baseline
    written by `metrics update` beside the project's tolerances."""
    from cobot_analysis.cli import run

    ws = tmp_path / "ws"
    write_table(walking_table(seed=3, n_subjects=2, n_conditions=4, n_trials=2), ws / "preprocess" / "trajectories.parquet",
                TRAJECTORIES)
    baselines = tmp_path / "baselines"
    baselines.mkdir()
    shutil.copy(BASELINES / "tolerances.toml", baselines / "tolerances.toml")

    def plan(root, datasets, j):
        return [ws], [["average", "--out", str(ws)]]

    monkeypatch.setattr(regression, "STUDIES", {"tiny": regression.Study("tiny.json", plan)})
    assert run(["-q", "average", "--out", str(ws)]) == 0
    assert run(["-q", "metrics", "update", str(baselines / "tiny.json"), str(ws)]) == 0
    return baselines


def _n_metrics(baselines: Path) -> int:
    return len(json.loads((baselines / "tiny.json").read_text())["metrics"])


def test_a_passing_check_prints_one_line(study, capsys):
    assert regression.main(["--baselines", str(study), "--keep", str(study.parent / "keep")]) == 0
    out = capsys.readouterr().out
    n = _n_metrics(study)
    assert n > 3
    assert " ok " not in out and "$ cobot-analysis" not in out and "metric  " not in out
    lines = [line for line in out.splitlines() if line.strip()]
    assert lines[0] == "metric regression:"
    assert len(lines) == 2 and lines[1].split()[:2] == ["tiny", "passed"]
    assert lines[1].endswith(f"{n} metrics: {n} ok, 0 outside tolerance, 0 missing, 0 new")


def test_a_failing_check_prints_only_the_failures(study, capsys):
    doc = json.loads((study / "tiny.json").read_text())
    doc["metrics"]["average.walker.means"]["value"] += 1
    (study / "tiny.json").write_text(json.dumps(doc))
    assert regression.main(["--baselines", str(study), "--keep", str(study.parent / "keep")]) == 1
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("average.")]
    assert [r.split()[0] for r in rows] == ["average.walker.means"] and rows[0].split()[-1] == "FAIL"
    assert "FAILED: " in out and "tiny" in out.splitlines()[-1] and "1 outside tolerance" in out.splitlines()[-1]


def test_verbose_prints_every_step_and_every_row(study, capsys):
    assert regression.main(["--baselines", str(study), "--keep", str(study.parent / "keep"), "--verbose"]) == 0
    out = capsys.readouterr().out
    assert "$ cobot-analysis average" in out
    assert sum(line.rstrip().endswith(" ok") for line in out.splitlines()) == _n_metrics(study)
