"""The analysis commands end to end through the CLI: average, compare, stats, reconstruct, report;
bad input gives one line, exit code 2 and no stage directory."""

from __future__ import annotations

import contextlib
import io
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.schema import TRAJECTORIES, read_table, write_table
from cobot_analysis.stats.analyses import STATS

sys.path.insert(0, str(Path(__file__).parent))
from cobot_analysis.synth.tables import pair_table, walking_table  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _workspace(tmp_path, df) -> Path:
    ws = tmp_path / "ws"
    write_table(df, ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    return ws


@pytest.fixture(scope="module")
def pair_study(tmp_path_factory):
    """A small synthetic pair study run through every analysis command once, the report without a study
    name (the workspace's): the workspace and what that report printed on stderr."""
    from cobot_analysis.cli import run

    ws = _workspace(tmp_path_factory.mktemp("pairs"), pair_table(seed=7, n_pairs=5, goals=4, n=20))
    for args in (["average"], ["compare"], ["stats"], ["reconstruct"]):
        assert run(["-q", *args, "--out", str(ws)]) == 0, args
    err = io.StringIO()
    with contextlib.redirect_stderr(err):  # the CLI's rich console writes to sys.stderr as it is at each print
        code = run(["report", "--out", str(ws), "--to", str(ws.parent / "report")])
    assert code == 0, err.getvalue()
    return ws, err.getvalue()


@pytest.fixture
def pair_ws(pair_study):
    return pair_study[0]


def test_pair_study_every_question_has_a_row_and_figures(pair_ws):
    stats = read_table(pair_ws / "stats" / "stats.parquet", STATS)
    questions = set(stats["question"])
    for q in ("Q1.1", "Q1.2", "Q1.3", "Q2.1", "Q2.2", "Q3", "Q4.1", "Q4.2", "Q4.3", "Q4.4"):
        assert q in questions
        assert stats.loc[stats["question"].eq(q), "status"].eq("ok").all(), q
    assert stats.loc[stats["question"].str.startswith("A."), "status"].str.startswith("skipped").all()  # no weight/height
    assert stats.loc[stats["test"].eq("kruskal"), "effect_name"].eq("epsilon^2").all()
    report = (pair_ws.parent / "report" / "README.md").read_text()
    for stem in ("paths_forward", "paths_return", "box_d_xy", "box_symmetry", "box_travel_time", "bars_configuration",
                 "scatter_d_xy_global", "box_scenarios", "box_d_xy_pair", "scatter_d_xy_turn", "bars_returns",
                 "box_d_xy_scenario", "box_d_xy_direction"):
        assert f"({stem}.png)" in report
        assert (pair_ws.parent / "report" / f"{stem}.png").stat().st_size > 1000
        assert (pair_ws.parent / "report" / f"{stem}.pdf").is_file()
    assert "| Q1.1 |" in report and "Subjects reconstructed from the table" in report
    for stage in ("average", "compare", "stats", "reconstruct"):
        assert (pair_ws / stage / "results.md").is_file() and (pair_ws / stage / "manifest.json").is_file()


def test_means_and_distances_tables(pair_ws):
    from cobot_analysis.averaging import MEANS
    from cobot_analysis.compare import DISTANCES

    means = read_table(pair_ws / "average" / "means.parquet", MEANS)
    first = means[means["sample"].eq(0)]
    # 5 pairs x 4 goals: each (goal, scenario, end orientation, entity) mean holds its trials
    fwd = first[first["direction"].eq("forward")]
    assert fwd.groupby("entity")["n_trials"].sum().eq(5 * 4 * 3).all()
    d = read_table(pair_ws / "compare" / "distances.parquet", DISTANCES)
    ind = d[d["comparison"].eq("individual-mean")]
    single = int(first["n_trials"].eq(1).sum())  # a mean of one trial is not compared with that trial
    assert single > 0 and len(ind) == 5 * 4 * 3 * 2 * 3 - single and ind["d_xy"].gt(0).all()
    assert f"{single} trial(s) whose mean is of that trial alone" in (pair_ws / "compare" / "results.md").read_text()
    assert {"symmetry", "scenario-scenario", "scenario-scenario-mean", "symmetry-mean"} <= set(d["comparison"])


def test_second_run_is_skipped_and_force_redoes(pair_ws, cli):
    code, _, err = cli("average", "--out", pair_ws)
    assert code == 0 and "up to date" in err


def test_report_takes_the_workspace_study_and_checks_a_given_name(pair_study, cli):
    pair_ws, err = pair_study  # the fixture's report: no name, so the workspace's study
    first = pair_ws.parent / "report"
    lines = err.strip().splitlines()
    assert not any("warning" in line for line in lines)
    figures = sorted(p.name for p in first.glob("*.png"))
    assert len(figures) > 5 and lines[-1] == f"report: {len(figures)} figures -> {first / 'README.md'}"
    # the workspace's study named: the same report (its parameters, the study, unchanged: up to date, copied)
    to = pair_ws.parent / "report-again"
    code, _, err = cli("report", "synthetic-pairs", "--out", pair_ws, "--to", to)
    assert code == 0, err
    lines = err.strip().splitlines()
    assert lines[0] == f"report: up to date, skipped (--force redoes it) -> {pair_ws / 'report'}"
    assert lines[-1] == (f"report (synthetic-pairs): {len(figures)} figures (the report up to date in the workspace, copied) "
                         f"-> {to / 'README.md'}")
    assert sorted(p.name for p in to.glob("*.png")) == figures
    code, _, err = cli("report", "pairs", "--out", pair_ws, "--to", to)  # the old short name, then the check
    lines = err.strip().splitlines()
    assert code == 2 and lines[0] == "warning: pairs is deprecated in `report`: use pair-carriage-2022"
    assert "the workspace's study is 'synthetic-pairs', not 'pair-carriage-2022'" in lines[-1]


def test_compare_against_another_table_and_walking_questions(tmp_path, cli):
    ws = _workspace(tmp_path, walking_table(seed=2, n_subjects=5, n_conditions=8, n_trials=3, subject_effect=0.1))
    for args in (["average"], ["compare"], ["stats"]):
        code, _, err = cli(*args, "--out", ws)
        assert code == 0, err
    stats = read_table(ws / "stats" / "stats.parquet", STATS).set_index("id")
    assert stats.loc["W1.1", "significant"]  # planted: subjects differ in variability
    assert stats.loc["W1.3", "note"].endswith("subsets tried)")
    assert stats.loc["W2", "status"].startswith("skipped")  # no model rows yet
    # a "model": each mean shifted by 5, 6, ... 12 cm, compared through --against
    means = pd.read_parquet(ws / "average" / "means.parquet")
    shift = 0.05 + 0.01 * means.groupby("trial", sort=True).ngroup()
    model = means.assign(x=means["x"] + shift, kind="model", trial="model:" + means["trial"])
    model.to_parquet(tmp_path / "model.parquet")
    code, _, err = cli("compare", "--out", ws, "--against", tmp_path / "model.parquet", "--comparison", "model",
                       "--any-vs-any", "condition,entity")
    assert code == 0, err
    d = pd.read_parquet(ws / "compare" / "distances.parquet")
    assert np.allclose(np.sort(d.loc[d["comparison"].eq("model"), "d_xy"]), 0.05 + 0.01 * np.arange(8))
    assert d["comparison"].eq("any-any").sum() == 8 * (15 * 14 // 2)  # 8 conditions, 5 subjects x 3 trials each
    code, _, err = cli("stats", "--out", ws)
    assert code == 0, err
    stats = read_table(ws / "stats" / "stats.parquet", STATS).set_index("id")
    assert stats.loc["W2", "status"] == "ok" and stats.loc["W3", "status"] == "ok"


# ---- bad input ------------------------------------------------------------------------------------
def _no_stage(ws: Path, stage: str) -> bool:
    return not (ws / stage).exists() and not list(ws.glob(f".{stage}.*"))


def test_missing_and_corrupt_trajectories(tmp_path, cli):
    code, _, err = cli("average", "--out", tmp_path / "empty")
    assert code == 2 and "no trajectories.parquet in the workspace" in err and "--trajectories" in err
    bad = tmp_path / "bad.parquet"
    bad.write_bytes(b"PAR1 garbage")
    code, _, err = cli("average", "--out", tmp_path / "ws", "--trajectories", bad)
    assert code == 2 and "bad.parquet: not a readable Parquet file" in err and _no_stage(tmp_path / "ws", "average")


@pytest.mark.parametrize("spoil, message", [
    (lambda df: df.assign(x=np.where(df.index == 5, np.nan, df["x"])), "have NaN positions"),
    (lambda df: df[~((df["trial"] == df["trial"].iloc[0]) & (df["sample"] == 3))], "different numbers of samples (39 to 40; S00_N1500_0/walker has 39)"),
    (lambda df: pd.concat([df, df.iloc[[7]]]), "has sample 7 more than once; keep one row per trajectory and sample"),
])
def test_bad_trajectories_give_one_line_and_no_output(tmp_path, cli, spoil, message):
    ws = _workspace(tmp_path, spoil(walking_table(seed=1, n_subjects=2, n_conditions=1, n_trials=2)))
    code, _, err = cli("average", "--out", ws)
    assert code == 2 and message in err and "trajectories.parquet" in err
    assert len(err.strip().splitlines()) == 1 and _no_stage(ws, "average")


def test_bad_options_and_config(tmp_path, cli):
    ws = _workspace(tmp_path, walking_table(seed=1, n_subjects=3, n_conditions=2, n_trials=2))
    code, _, err = cli("average", "--out", ws, "--by", "condition,colour")
    assert code == 2 and "--by names unknown column(s) ['colour']" in err and _no_stage(ws, "average")
    assert cli("average", "--out", ws)[0] == 0 and cli("compare", "--out", ws)[0] == 0
    cfg = tmp_path / "bad.toml"
    cfg.write_text('[[analysis]]\nid = "X1"\nsource = "distances"\nvalue = "d_xyz"\ngroup = "subject"\ntest = "kruskal"\nfamily = "f"\n')
    code, _, err = cli("stats", "--out", ws, "--config", cfg)
    assert code == 2 and "bad.toml: analysis X1: unknown column(s) ['d_xyz']" in err and _no_stage(ws, "stats")
    cfg.write_text('[[analysis]]\nid = "X2"\nsource = "distances"\nvalue = "d_xy"\ngroup = "subject"\ntest = "kruskal"\nfamily = "f"\nlevels = ["S01", "S99"]\n')
    code, _, err = cli("stats", "--out", ws, "--config", cfg)
    assert code == 2 and "group level(s) ['S99'] not found" in err and _no_stage(ws, "stats")
    cfg.write_text("[[analysis]\n")
    code, _, err = cli("stats", "--out", ws, "--config", cfg)
    assert code == 2 and "not valid TOML" in err
    code, _, err = cli("reconstruct", "--out", ws)
    assert code == 2 and "no table trajectories" in err and _no_stage(ws, "reconstruct")
    code, _, err = cli("report", "lizards", "--out", ws)
    assert code == 2 and "the workspace's study is 'synthetic-walking', not 'lizards'" in err
    (tmp_path / "nope.parquet").write_text("x")
    code, _, err = cli("compare", "--out", ws, "--force", "--against", tmp_path / "nope.parquet")
    assert code == 2 and "nope.parquet: not a readable trajectory table" in err


# ---- published data ---------------------------------------------------------------------------------
@pytest.mark.datasets
def test_published_pair_study(datasets, tmp_path, cli):
    from scipy import stats as sps

    ws = tmp_path / "ws"
    assert cli("-q", "import-published", "pair-carriage-2022", datasets / "pair-carriage-2022", "--out", ws)[0] == 0
    for args in (["average"], ["compare"], ["stats"], ["reconstruct"]):
        code, _, err = cli("-q", *args, "--out", ws)
        assert code == 0, (args, err)
    s = read_table(ws / "stats" / "stats.parquet", STATS).set_index("id")
    assert s.loc["N", "summary"] == "forward: 1: 180, 2: 180, 3: 180; return: 3: 172"  # README counts
    dur = pd.read_parquet(ws / "import-published" / "durations.parquet")
    fwd = dur[dur["direction"].eq("forward")]
    ref = sps.kruskal(*[g["duration"].to_numpy() for _, g in fwd.groupby("scenario")])
    assert s.loc["Q1.1", "statistic"] == pytest.approx(ref.statistic) and s.loc["Q1.1", "significant"]
    assert s.loc["Q2.2", "status"] == "ok" and "172 pairs" in s.loc["Q2.2", "note"]
    for q in ("Q1.2", "Q3", "Q4.2", "Q4.3"):  # per-trial questions: the published data hold means only
        assert s.loc[s["question"].eq(q), "status"].str.startswith("skipped").all()
    rec = pd.read_parquet(ws / "reconstruct" / "reconstruction.parquet")
    assert len(rec) == 2 * (13 + 18) and rec["d_xy"].max() < 0.2  # scenario-3 forward + return means, both subjects


@pytest.mark.datasets
def test_published_walking_study(datasets, tmp_path, cli):
    ws = tmp_path / "ws"
    assert cli("-q", "import-published", "walking-2020", datasets / "walking-2020", "--out", ws)[0] == 0
    for args in (["average"], ["compare"], ["stats"]):
        code, _, err = cli("-q", *args, "--out", ws)
        assert code == 0, (args, err)
    d = pd.read_parquet(ws / "compare" / "distances.parquet")
    ind = d[d["comparison"].eq("individual-mean")]
    assert len(ind) == 400 and ind["d_theta"].isna().sum() == 125  # 125 subject blocks without orientation
    same = d[d["comparison"].eq("mean-published")]
    assert len(same) == 40 and same["d_xy"].max() < 1e-9  # published x, y = plain mean of the 10 subjects
    s = read_table(ws / "stats" / "stats.parquet", STATS).set_index("id")
    assert s.loc["W1.1", "status"] == "ok" and s.loc["W1.1", "n"] == 400
    assert "left out (no values): S02" in s.loc["W1.2", "note"]  # Subject 2 has no orientation in any file
    assert "exact (" in s.loc["W1.3", "note"]


@pytest.mark.slow
def test_end_to_end_from_the_synthetic_raw_pair_study(tmp_path, cli):
    """synth pairs -> import -> preprocess -> every analysis command, on a small study."""
    ws = tmp_path / "ws"
    steps = (["synth", "pairs", "--pairs", "2", "--goals", "2"], ["import", ws / "synth-pairs" / "protocol.yaml"],
             ["preprocess"], ["average"], ["compare"], ["stats"], ["reconstruct"])
    for args in steps:
        code, _, err = cli("-q", *args, "--out", ws)
        assert code == 0, (args, err)
    s = read_table(ws / "stats" / "stats.parquet", STATS).set_index("id")
    assert s.loc["N", "summary"] == "forward: 1: 4, 2: 4, 3: 4; return: 3: 12"
    assert s.loc["Q2.1", "status"] == "ok" and s.loc["Q4.1-entity", "status"] == "ok"
    assert s.loc["A.1[table]", "status"].endswith("(all: 2)")  # weight/height read from synth-pairs/: 2 pairs < 3
    rec = pd.read_parquet(ws / "reconstruct" / "reconstruction.parquet")
    assert len(rec) == 2 * 2 * (1 + 3) * 2 and rec["d_xy"].median() < 0.2


def test_a_comparison_that_leaves_trials_out_says_so_on_its_line(tmp_path, cli):
    """One trial per mean: no trial is compared with its mean (the distance would be 0); the command's own line
    says how many and why, not only '0 compared pairs'."""
    ws = _workspace(tmp_path, walking_table(seed=1, n_subjects=1, n_conditions=2, n_trials=1))
    assert cli("average", "--out", ws)[0] == 0
    code, _, err = cli("compare", "--out", ws)
    assert code == 0, err
    assert "0 compared pairs; not compared with their mean: 2 trial(s) whose mean is of that trial alone ->" in " ".join(err.split())
