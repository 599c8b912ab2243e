"""`cobot-analysis average`: the groups the means are made over must be real conditions (issue #11)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from cobot_analysis.averaging import MEANS
from cobot_analysis.schema import TRAJECTORIES, read_table, write_table

sys.path.insert(0, str(Path(__file__).parent))
from cobot_analysis.synth.tables import pair_table, walking_table  # noqa: E402


def _workspace(tmp_path, df) -> Path:
    ws = tmp_path / "ws"
    write_table(df, ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    return ws


def _refused(cli, ws, *args) -> str:
    code, _, err = cli("average", "--out", ws, *args)
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and not (ws / "average").exists() and not list(ws.glob(".average.*"))
    return " ".join(err.split())


def test_trials_without_condition_are_not_averaged_into_one_mean(tmp_path, cli):
    df = walking_table(seed=1, n_subjects=2, n_conditions=3, n_trials=2)  # 12 trajectories
    ws = _workspace(tmp_path, df.assign(condition=None))
    msg = _refused(cli, ws)
    assert "trajectories.parquet: no trial has a 'condition' value: the means would average all 12 trajectories into one" in msg
    assert "give every trial its condition in the protocol's trials table" in msg and "--by study,entity" in msg
    code, _, err = cli("average", "--out", ws, "--by", "study,entity")  # one mean over everything, when asked for
    assert code == 0, err
    means = read_table(ws / "average" / "means.parquet", MEANS)
    assert means["n_trials"].unique().tolist() == [12]
    x = df.pivot_table(index="sample", columns="trial", values="x").mean(axis=1).to_numpy()
    np.testing.assert_allclose(means.sort_values("sample")["x"], x, atol=1e-12)


def test_some_trials_without_condition_are_refused(tmp_path, cli):
    df = walking_table(seed=1, n_subjects=2, n_conditions=2, n_trials=2)
    lost = df["trial"].unique()[:2]
    ws = _workspace(tmp_path, df.assign(condition=np.where(df["trial"].isin(lost), None, df["condition"])))
    msg = _refused(cli, ws)
    assert f"2 of 8 trajectories have no 'condition' value ({lost[0]}, {lost[1]}...): they would be averaged together" in msg


def test_truncated_trajectories_are_counted(tmp_path, cli):
    df = walking_table(seed=1, n_subjects=2, n_conditions=1, n_trials=2)
    first = df["trial"] == df["trial"].iloc[0]
    ws = _workspace(tmp_path, df.assign(quality=np.where(first, "truncated", df["quality"])))
    code, _, err = cli("average", "--out", ws)
    assert code == 0, err
    assert "1 of the 4 trajectories averaged are flagged `truncated`" in (ws / "average" / "results.md").read_text()


def test_labels_that_differ_only_by_case_or_spaces_are_refused(tmp_path, cli):
    """Two trials tables' spellings of one goal ("d1_p4_gris" and "D1_P4_GRIS ") made two conditions, each mean
    over part of the trials, without a word."""
    df = pair_table(seed=1, n_pairs=2, goals=1)
    pair2 = df["pair"] == "P02"
    assert df["condition"].unique().tolist() == ["d1_p4_gris"]
    ws = _workspace(tmp_path, df.assign(condition=df["condition"].where(~pair2, "D1_P4_GRIS ")))
    msg = _refused(cli, ws)
    assert ("trajectories.parquet: condition labels 'D1_P4_GRIS ' and 'd1_p4_gris' differ only by case or spaces: "
            "they would be averaged as two conditions") in msg
    assert "write each condition alike in the protocol's trials table" in msg


def test_means_say_when_their_subjects_weigh_unequally():
    """Each mean weighs its trajectories alike: a subject with 2 trials in a condition, beside subjects with 1, weighs
    twice. The published means had one per subject; a study of one's own often has not, and results.md now says so
    (the balanced study: nothing)."""
    from cobot_analysis.api import average
    from cobot_analysis.reports.analysis import average_markdown
    from cobot_analysis.synth.tables import walking_table

    t = walking_table(n_subjects=3, n_conditions=2, n_trials=2)
    assert average(t).unequal == (0, "subject", 0, 0)
    assert "contribute unequal" not in average_markdown(average(t), "t.parquet")
    one = t[~(t["subject"].isin(["S01", "S02"]) & t["trial"].str.endswith("_1") & t["condition"].eq("E1500"))]
    result = average(one)
    assert result.unequal == (1, "subject", 1, 2)
    assert ("In 1 mean(s) the subjects contribute unequal numbers of trajectories (1 to 2): each mean weighs its "
            "trajectories alike, so a subject with more of them weighs more") in average_markdown(result, "t.parquet")
