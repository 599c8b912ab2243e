"""The README's main job: `cobot-analysis demo`. The small demo end to end (every study, the report, a second
run that redoes nothing) is checked on the run of its `--help` example: tests/test_cli_examples.py,
``check_small_demo`` (one run of the demo in the suite, not two)."""

from __future__ import annotations

from pathlib import Path


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
