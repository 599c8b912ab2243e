"""generate --study pair-carriage-2022 (issue 17, point 1 on the pair study): one path per per-scenario table mean,
from its first to its last measured pose, that ends at its goal or says why not, with the subjects' pace beside it;
compare --against finds each path's mean and gives fit-ioc's distances; bad input exits 2 without output."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.schema import TRAJECTORIES, write_table
from cobot_analysis.synth.tables import pair_table, walking_table

GRID = ("--intervals", "20", "--samples", "20", "-j", "1")  # a coarse grid: a second for the six means


@pytest.fixture(scope="module")
def pair_ws(tmp_path_factory):
    """A small synthetic pair study (2 pairs, 1 goal, 20 samples: 6 per-scenario table means) averaged, generated
    on under the continuous convention with the table-2022 weights, and compared with its means."""
    from cobot_analysis.cli import run

    ws = tmp_path_factory.mktemp("pairgen") / "ws"
    write_table(pair_table(seed=7, n_pairs=2, goals=1, n=20), ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    assert run(["-q", "average", "--out", str(ws)]) == 0
    assert run(["-q", "generate", "--out", str(ws), "--study", "pair-carriage-2022", "--convention", "continuous", *GRID]) == 0
    assert run(["-q", "compare", "--out", str(ws), "--against", str(ws / "generate" / "generated.parquet"),
                "--comparison", "model"]) == 0
    return ws


def _table_means(ws) -> pd.DataFrame:
    m = pd.read_parquet(ws / "average" / "means.parquet")
    return m[(m["entity"] == "table") & m["scenario"].notna()]


def test_every_table_mean_has_a_path_from_its_first_to_its_last_pose(pair_ws):
    means = _table_means(pair_ws)
    gen = pd.read_parquet(pair_ws / "generate" / "generated.parquet")
    assert gen["trial"].nunique() == means["trial"].nunique() == 6
    for trial, g in means.groupby("trial"):
        g = g.sort_values("sample")
        p = gen[gen["trial"] == f"table_{trial}"].sort_values("sample")
        assert len(p) == 20 and (p["model"] == "table").all() and (p["entity"] == "table").all()
        for c in ("study", "condition", "direction", "scenario", "configuration", "end_orientation"):  # compare's keys
            assert (p[c] == g[c].iloc[0]).all(), c
        assert np.hypot(p["x"].iloc[0] - g["x"].iloc[0], p["y"].iloc[0] - g["y"].iloc[0]) < 1e-6
        assert np.hypot(p["x"].iloc[-1] - g["x"].iloc[-1], p["y"].iloc[-1] - g["y"].iloc[-1]) < 0.01  # at its goal
        end = p.iloc[-1]
        assert end.goal_reached and end.converged and end.status == "ok" and end.end_heading_error <= 0.05


def test_the_report_states_goals_and_the_subjects_pace(pair_ws):
    text = (pair_ws / "generate" / "results.md").read_text()
    assert "pair study" in text and "the 6 per-scenario table means" in text
    assert "Goal reached (end within 1 cm and 0.05 rad): 6 of 6 paths" in text
    means = _table_means(pair_ws).groupby("trial").first()
    name = f"table_{means.index[0]}".replace("|", "\\|")  # a synthetic mean's name holds '|', escaped in the table
    row = next(line for line in text.splitlines() if line.startswith(f"| {name} |"))
    cells = [c.strip() for c in re.split(r"(?<!\\)\|", row.strip().strip("|"))]
    g = _table_means(pair_ws).query("trial == @means.index[0]").sort_values("sample")
    T = float(means["travel_time"].iloc[0])
    length = float(np.hypot(np.diff(g["x"]), np.diff(g["y"])).sum())
    assert cells[3] == f"{T:.2f}" and cells[4] == f"{length / T:.2f}"  # the subjects': the mean's travel time, length / it
    assert cells[8] == "yes" and cells[9] == "ok"  # goal reached, status
    assert "outside 0.5-2 m/s. The subjects' own (T " in text


def test_summary_line_counts_goals_and_speeds_beside_the_subjects():
    from cobot_analysis.api import average
    from cobot_analysis.api.models import generate, pair_cases
    from cobot_analysis.models.comparison import pair_pace

    means = average(pair_table(seed=7, n_pairs=2, goals=1, n=20)).means
    cases, keys = pair_cases("continuous", means)
    pace = pair_pace(means)
    assert set(pace) == {c for c, _, _ in cases}
    r = generate("table", cases=cases[:2], keys=keys, measured=pace, study="pair-carriage-2022", weights="table-2022",
                 convention="continuous", samples=20, intervals=20, jobs=1)
    speeds = [pace[c][1] for c, _, _ in cases[:2]]
    assert r.summary().startswith("2 trajectories, all at their goal, mean speed ")
    assert r.summary().endswith(f"(2 of 2 outside 0.5-2 m/s; the subjects' {sum(not 0.5 <= v <= 2 for v in speeds)} of 2)")


def test_compare_finds_each_paths_mean_with_fit_iocs_distances(pair_ws):
    """One answer per question on the pair study: generate --study + compare --against = fit-ioc's comparison
    (compare_models on the targets fit-ioc takes), a mean of one trial compared too."""
    from cobot_analysis.models.comparison import compare_models
    from cobot_analysis.models.ioc import targets_from_table

    d = pd.read_parquet(pair_ws / "compare" / "distances.parquet")
    model = d[d["comparison"] == "model"]
    means = _table_means(pair_ws)
    assert len(model) == means["trial"].nunique() and (means.groupby("trial")["n_trials"].first() == 1).any()
    targets = targets_from_table(means, entity="table", unoriented=True)
    inside = compare_models(targets, {"table OC (published)": ("table", "table-2022")}, n_intervals=20, angle="theta",
                            jobs=1, convention="continuous")
    assert inside["goal_reached"].all()
    a = inside.assign(key=inside["trial"]).set_index("key").sort_index()
    b = model.assign(key=model["b_trial"]).set_index("key").sort_index()  # the mean each path was compared with
    assert list(a.index) == list(b.index)
    for k in ("d_xy", "d_theta"):
        assert np.allclose(a[k].to_numpy(float), b[k].to_numpy(float), rtol=1e-9, atol=1e-12), k


def test_fit_ioc_comparison_counts_the_paths_at_their_goal():
    from cobot_analysis.reports.models import goal_lines

    cmp = pd.DataFrame({"model": ["table OC (published)"] * 2 + ["table OC (fitted)"] * 2 + ["subjects vs mean"],
                        "trial": ["m1", "m2", "m1", "m2", "t1"], "goal_reached": [True, True, True, False, np.nan]})
    text = "\n".join(goal_lines(cmp, "continuous"))
    assert text.startswith("Goal reached (end within 1 cm and 0.05 rad): table OC (published) 2 of 2 paths at the goal; "
                           "table OC (fitted) 1 of 2 paths at the goal (not: m2).")
    assert "subjects vs mean" not in text and "did not converge" in text
    assert "terminal cost" in "\n".join(goal_lines(cmp, "published"))


def _refused(cli, out, *args):
    code, _, err = cli("-q", "generate", "--out", out, *args, *GRID)
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: "), err
    assert not (out / "generate").exists() and not (out / "generate-published").exists()
    return err


def test_pair_study_without_table_means_exits_2_naming_the_files_and_the_remedy(cli, tmp_path):
    err = _refused(cli, tmp_path / "empty", "--study", "pair-carriage-2022", "--convention", "continuous")
    assert "--study pair-carriage-2022: no table means" in err
    assert "(average/means.parquet, import-published/trajectories.parquet)" in err
    assert "run `cobot-analysis import-published pair-carriage-2022 DATASET --out" in err
    # the default weights (table-2022) are the paper's: the published convention, the authors' mean block only
    err = _refused(cli, tmp_path / "empty", "--study", "pair-carriage-2022")
    assert "(import-published/trajectories.parquet)" in err and "import-published pair-carriage-2022" in err
    # a walking workspace: means, none of the table
    ws = tmp_path / "walking"
    write_table(walking_table(n_subjects=2, n_conditions=1, n_trials=2), ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    assert cli("-q", "average", "--out", ws)[0] == 0
    err = _refused(cli, ws, "--study", "pair-carriage-2022", "--convention", "continuous")
    assert "means.parquet" in err and "no mean table trajectory of the pair study" in err and "--means" in err


@pytest.mark.parametrize("args, message", [
    (["--study", "pairs"], "--study pairs: unknown study; use --study walking-2020 or pair-carriage-2022, or give --start"),
    (["--study", "pair-carriage-2022", "--goal", "1", "1", "0"], "--goal does not apply to --study pair-carriage-2022"),
    (["--study", "pair-carriage-2022", "--model", "all"], "--model all on --study pair-carriage-2022: its means are the table's"),
])
def test_bad_study_options_exit_2_without_output(cli, pair_ws, tmp_path, args, message):
    import shutil

    ws = tmp_path / "ws"
    shutil.copytree(pair_ws / "average", ws / "average")
    assert message in _refused(cli, ws, *args)


def test_a_model_run_that_missed_its_goal_is_left_out_of_the_comparison_means():
    """fit-ioc's comparison table says 'Not converged (left out of the means)': a continuous path that missed its goal
    (converged false, distances finite) is left out, not averaged in."""
    from cobot_analysis.reports.models import summary_table

    cmp = pd.DataFrame({"model": ["table OC (fitted)"] * 3, "trial": ["m1", "m2", "m3"], "orientation": "",
                        "global_distance": [2.0, 4.0, 4.0], "d_xy": [0.1, 0.3, 5.0], "d_theta": [0.2, 0.2, 3.0],
                        "converged": [True, True, False]})
    text = summary_table(cmp, "theta")
    assert "| table OC (fitted) | 2 | 0.200 ± 0.141 |" in text and "| table OC (fitted) | 2 | 0.200 ± 0.000 |" in text
    assert "Not converged (left out of the means): 1 of 3 model runs (table OC (fitted))." in text


def test_published_table_model_rows_say_they_are_fit_iocs():
    """compare-published on the pair study: its model rows are fit-ioc's comparison (same paths and means, measured on
    the published data: d_xy 0.1724, d_theta 0.6937 both ways), not the walking study's d_gamma account."""
    from types import SimpleNamespace

    from cobot_analysis.reports.analysis import compare_markdown

    rows = [{"comparison": "model", "entity": "table", "d_xy": 0.17, "d_theta": 0.69, "d_gamma": 2.4},
            {"comparison": "symmetry-mean", "entity": "table", "d_xy": 0.09, "d_theta": 0.4, "d_gamma": 2.1}]
    md = compare_markdown(SimpleNamespace(distances=pd.DataFrame(rows), convention="published", excluded={}), sd_ddof=0)
    assert "the same paths and means, the same d_xy and d_theta" in md and "d_gamma differs" not in md
