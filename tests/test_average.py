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


def _two_subjects():
    """Subject A: 3 identical trials at y = 0, theta = 0, 10 s; subject B: 1 trial at y = 1, theta = pi/2, 14 s."""
    t = walking_table(n_subjects=2, n_conditions=1, n_trials=3)
    t = t[~(t["subject"].eq("S02") & ~t["trial"].str.endswith("_1"))].copy()
    b = t["subject"].eq("S02")
    return t.assign(x=t["x"].groupby(t["sample"]).transform("first"), y=np.where(b, 1.0, 0.0), theta=np.where(b, np.pi / 2, 0.0), gamma=np.where(b, np.pi / 2, 0.0),
                    travel_time=np.where(b, 14.0, 10.0))


def test_weigh_subjects_takes_the_mean_of_each_subjects_mean():
    """Every trajectory weighs alike by default (the published method): A's 3 trials pull the mean to y = 0.25; the
    mean of the subjects' means is 0.5, with the sd between the 2 subjects (0.707), the angles' mean of the subjects'
    mean directions (pi/4, not atan2(1, 3)) and the subjects' mean travel time (12 s, not 11 s)."""
    from cobot_analysis.api import average
    from cobot_analysis.reports.analysis import average_markdown

    t = _two_subjects()
    trials = average(t).means.iloc[0]
    assert (trials["n_trials"], trials["y"], trials["y_sd"], trials["travel_time"]) == (4, 0.25, 0.5, 11.0)
    np.testing.assert_allclose(trials["theta"], np.arctan2(1, 3))
    result = average(t, weigh="subjects")
    first = result.means.iloc[0]
    assert (first["n_trials"], first["n_theta"], first["y"], first["travel_time"]) == (4, 4, 0.5, 12.0)
    np.testing.assert_allclose([first["y_sd"], first["theta"], first["gamma"], first["theta_sd"]],
                               [np.sqrt(0.5), np.pi / 4, np.pi / 4, np.sqrt(np.log(2))])
    np.testing.assert_allclose(result.means["x"], average(t).means["x"])
    assert result.weigh == "subjects" and average(t).weigh == "trials"
    assert "- Weighting (`average --weigh trials`, the published method): every trajectory alike." in average_markdown(average(t), "t")
    text = " ".join(average_markdown(result, "t.parquet").split())
    assert ("Weighting (`average --weigh subjects`): each mean is the mean of its subjects' means (2 subjects per mean; "
            "1 to 3 trajectories per subject), sd between the subjects' means") in text


def test_weigh_subjects_is_recorded_and_read_downstream(tmp_path, cli):
    """The means' weighting is in means.parquet's metadata, average's manifest and results.md, and compare says which
    means it was given (its manifest and results.md)."""
    import json

    from cobot_analysis.schema import table_metadata

    ws = _workspace(tmp_path, _two_subjects())
    code, _, err = cli("average", "--out", ws)
    assert code == 0, err
    assert table_metadata(ws / "average" / "means.parquet")["weigh"] == "trials"
    code, _, err = cli("average", "--out", ws, "--weigh", "subjects")
    assert code == 0, err
    assert table_metadata(ws / "average" / "means.parquet")["weigh"] == "subjects"
    assert json.loads((ws / "average" / "manifest.json").read_text())["params"]["weigh"] == "subjects"
    assert "`average --weigh subjects`" in (ws / "average" / "results.md").read_text()
    means = read_table(ws / "average" / "means.parquet", MEANS)
    assert means["y"].unique().tolist() == [0.5]
    code, _, err = cli("compare", "--out", ws)
    assert code == 0, err
    assert json.loads((ws / "compare" / "manifest.json").read_text())["params"]["means_weigh"] == "subjects"
    assert "means weighted by subjects (`average --weigh subjects`)" in " ".join((ws / "compare" / "results.md").read_text().split())


def test_weigh_subjects_without_subjects_is_refused(tmp_path, cli):
    t = _two_subjects()
    ws = _workspace(tmp_path, t.assign(subject=None))
    msg = _refused(cli, ws, "--weigh", "subjects")
    assert "--weigh subjects needs each trial's subject (or pair), and no trial has one" in msg and "or use --weigh trials" in msg
    ws = _workspace(tmp_path / "some", t.assign(subject=t["subject"].where(t["trial"] != t["trial"].iloc[0])))
    msg = _refused(cli, ws, "--weigh", "subjects")
    assert f"--weigh subjects: 1 of 4 trajectories have no 'subject' value ({t['trial'].iloc[0]}...)" in msg
    ws = _workspace(tmp_path / "by", t)
    msg = _refused(cli, ws, "--weigh", "subjects", "--by", "condition,subject,entity")
    assert "--weigh subjects with 'subject' in --by: each mean is one subject's, with no spread between subjects" in msg
    msg = _refused(cli, ws, "--weigh", "pairs")
    assert "unknown --weigh 'pairs'; use one of trials, subjects" in msg


def test_stats_fit_ioc_and_generate_say_which_means_they_were_given(tmp_path):
    """stats (its distances to the means), fit-ioc (the means it fits) and generate (the means its poses come from)
    record the means' weighting in their manifests and say it in results.md; nothing is said of the default."""
    import json

    from cobot_analysis.stages import analysis, models

    t = walking_table(n_subjects=2, n_conditions=1, n_trials=3)  # real paths: generate --study takes N1500 as the code
    ws = _workspace(tmp_path, t[~(t["subject"].eq("S02") & ~t["trial"].str.endswith("_1"))])  # S01 3 trials, S02 1
    analysis.average(ws, weigh="subjects")
    analysis.compare(ws)
    analysis.statistics(ws)
    models.fit_ioc(ws, max_evaluations=2, intervals=10, bootstrap=0, compare=False, jobs=1)
    models.generate(ws, study="walking-2020", samples=50, intervals=10, jobs=1, convention="continuous")
    for stage in ("stats", "fit-ioc", "generate"):
        assert json.loads((ws / stage / "manifest.json").read_text())["params"]["means_weigh"] == "subjects", stage
        assert "weighted by subjects (`average --weigh subjects`)" in (ws / stage / "results.md").read_text(), stage
    analysis.average(ws)
    analysis.compare(ws)
    analysis.statistics(ws)
    assert "means_weigh" not in json.loads((ws / "stats" / "manifest.json").read_text())["params"]
    assert "--weigh" not in (ws / "stats" / "results.md").read_text()
