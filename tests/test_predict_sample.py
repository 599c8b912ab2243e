"""`predict --per-condition K`: a stratified sample, K trajectories of every condition, the subjects
taking turns (the demo predicts one walking trial of each start condition)."""

from __future__ import annotations

from collections import Counter

import pytest

from cobot_analysis.api.prediction import prediction_config, select
from cobot_analysis.synth.tables import walking_table


@pytest.fixture(scope="module")
def walks():
    return walking_table(n_subjects=5, n_conditions=12, n_trials=2, n=60)


def _chosen(walks, **options):
    trajs, _ = select(walks, prediction_config(settings="10:20", predictors="cv"), kind="trial", **options)
    return trajs


@pytest.mark.parametrize("k", [1, 2, 3])
def test_k_trajectories_of_every_condition(walks, k):
    trajs = _chosen(walks, per_condition=k)
    conditions = Counter(t.meta["condition"] for t in trajs)
    assert len(conditions) == 12 and set(conditions.values()) == {k}
    assert len({t.label for t in trajs}) == 12 * k  # no trajectory twice


def test_the_subjects_take_turns(walks):
    """One trial of each of the 12 conditions (10 trials each: 5 subjects x 2 repetitions): the offset moves
    on with the condition, so the sample holds every subject and both repetitions, not subject 0 twelve times."""
    trajs = _chosen(walks, per_condition=1)
    subjects = Counter(t.meta["subject"] for t in trajs)
    # ranks 0-9 take the 10 trials in turn (each subject twice), ranks 10-11 start again at the first subject
    assert sorted(subjects.values()) == [2, 2, 2, 2, 4]
    assert len({t.trial.rsplit("_", 1)[-1] for t in trajs}) == 2


def test_more_than_a_condition_has_is_all_of_them(walks):
    assert len(_chosen(walks, per_condition=50)) == len(_chosen(walks))


def test_the_option_reaches_the_stage(cli, tmp_path, walks):
    from cobot_analysis.schema import TRAJECTORIES, write_table
    import pandas as pd

    path = tmp_path / "trajectories.parquet"
    write_table(walks, path, TRAJECTORIES)
    out = tmp_path / "ws"
    code, _, err = cli("-q", "predict", "--out", out, "--trajectories", path, "--kind", "trial", "--settings", "10:20",
                       "--predictors", "cv", "--per-condition", "1", "--jobs", "1")
    assert code == 0, err
    p = pd.read_parquet(next(out.glob("predict*/predictions.parquet")))
    assert p["trial"].nunique() == 12
