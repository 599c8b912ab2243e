"""The README's main job: `cobot-analysis demo` runs every study end to end and writes a report."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from cobot_analysis.schema import TRAJECTORIES, read_table


@pytest.mark.slow
def test_small_demo_runs_every_stage_and_writes_the_report(cli, tmp_path):
    out = tmp_path / "demo"
    code, _, err = cli("-q", "demo", "--out", out, "--size", "small", "--jobs", "1")
    assert code == 0, err
    report = (out / "report.md").read_text()
    for section in ("Preprocessing", "Statistics", "Localisation accuracy"):
        assert section in report
    walking = read_table(out / "walking" / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    assert walking.groupby(["trial", "entity"]).ngroups == 16  # 2 subjects x 8 conditions x 1 trial
    pairs = read_table(out / "pairs" / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    # 2 pairs x 3 goals x 3 scenarios recordings -> forward + return trials, 3 entities each
    assert pairs.groupby(["trial", "entity"]).ngroups == 2 * 3 * 3 * 2 * 3
    assert (out / "reports" / "walking" / "README.md").is_file() and (out / "reports" / "pairs" / "README.md").is_file()
    runs = pd.read_parquet(out / "localisation" / "localisation" / "localisation.parquet")
    assert len(runs) == 3  # ROS1, ROS2 and MCAP versions of the same run
    # a second run finds every stage up to date and changes nothing
    before = (out / "walking" / "preprocess" / "manifest.json").read_text()
    assert cli("-q", "demo", "--out", out, "--size", "small", "--jobs", "1")[0] == 0
    assert (out / "walking" / "preprocess" / "manifest.json").read_text() == before


def test_demo_rejects_an_unknown_size(cli, tmp_path):
    code, _, err = cli("demo", "--out", tmp_path / "d", "--size", "huge")
    assert code == 2 and "--size" in err and not (tmp_path / "d").exists()


def test_demo_prediction_sample_covers_every_condition():
    """The demo's prediction sample is stratified: one trial of each of the 40 walking conditions (every
    60th trial fell on two conditions, two dots per panel of prediction_error_vs_distance), spread over
    the subjects."""
    from cobot_analysis.api.prediction import prediction_config, select
    from cobot_analysis.cli.pipeline import DEMO_PREDICT_PER_CONDITION, demo_steps
    from cobot_analysis.synth.tables import walking_table

    steps = [s for s in demo_steps(Path("demo"), "default", None)["walking"] if s[0] == "predict"]
    assert len(steps) == 2 and all("--every" not in s for s in steps)
    k = int(steps[0][steps[0].index("--per-condition") + 1])
    assert k == DEMO_PREDICT_PER_CONDITION
    walks = walking_table(n_subjects=10, n_conditions=40, n_trials=3, n=60)  # the demo's default design
    trajs, _ = select(walks, prediction_config(settings="50:60", predictors="cv"), kind="trial", per_condition=k)
    assert len({t.meta["condition"] for t in trajs}) == 40 == len(trajs) / k
    assert len({t.meta["subject"] for t in trajs}) == 10
