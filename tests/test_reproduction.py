"""The reproduction table of docs/results.md (reports/reproduction.py): our values read from a
workspace per convention, the 15 % verdict, and the measured accounts."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from cobot_analysis.reports import reproduction as rep


def _distances(ws, stage: str, d_theta: list[float]) -> None:
    (ws / stage).mkdir(parents=True)
    n = len(d_theta)
    pd.DataFrame({"model": ["table OC (published)"] * n, "d_xy": np.linspace(0.1, 0.2, n),
                  "d_theta": d_theta}).to_parquet(ws / stage / "distances.parquet")


def test_verdict_is_the_relative_difference_to_the_papers_mean():
    assert rep.verdict((0.1, 0.05), (0.114, 0.0, 3)) == "yes"
    assert rep.verdict((0.1, 0.05), (0.116, 0.0, 3)) == "no (+16%)"
    assert rep.verdict((0.1, None), None) == "–"


def test_table_reads_each_convention_from_its_own_stage(tmp_path):
    _distances(tmp_path, "fit-ioc-published", [0.2, 0.4, 6.0])
    _distances(tmp_path, "fit-ioc", [0.1, 0.3])
    lines = rep.table(tmp_path, "pair-carriage-2022", rep.accounts(tmp_path, "pair-carriage-2022"))
    row = next(line for line in lines if "d_theta (means" in line).split(" | ")
    pub = np.array([0.2, 0.4, 6.0])
    assert row[2] == f"{pub.mean():.4f} ± {pub.std(ddof=0):.4f} (n = 3)"  # published: population sd
    assert row[3] == f"0.2000 ± {np.std([0.1, 0.3], ddof=1):.4f} (n = 2)"  # continuous: sample sd
    assert row[4] == f"no ({(pub.mean() - 0.36) / 0.36:+.0%})"
    assert "1 of 3 means above pi (up to 6.00); without them 0.300, median of all 0.400" in row[5]
    assert "not run" in next(line for line in lines if "table prediction" in line)


@pytest.mark.parametrize("study", ["walking-2020", "pair-carriage-2022"])
def test_every_figure_has_a_paper_value_and_a_source(study):
    for fig in rep.FIGURES[study]:
        assert fig.paper[0] != 0 and fig.note and fig.kind in ("mean", "value", "members", "pearson")
        assert fig.unit in (("m", "rad") if fig.kind == "mean" else ("-", "r", "subjects"))


def test_bound_verdict_and_negative_paper_values():
    assert rep.verdict((1e-5, None), (2e-11, float("nan"), 400), "<") == "yes"
    assert rep.verdict((1e-5, None), (0.42, float("nan"), 275), "<") == "no (4.2e+04 x the bound)"
    assert rep.verdict((-0.81, None), (-0.70, float("nan"), 37)) == "yes"  # 14 % from -0.81
    assert rep.verdict((-0.81, None), (-0.39, float("nan"), 37)) == "no (+52%)"


def _stats(ws, stage: str, rows: list[dict]) -> None:
    (ws / stage).mkdir(parents=True)
    pd.DataFrame([{"status": "ok", "note": "", **r} for r in rows]).to_parquet(ws / stage / "stats.parquet")


def test_statistics_rows_read_one_stats_row_per_convention(tmp_path):
    _stats(tmp_path, "stats-published", [
        {"id": "W1.2", "p": 0.42, "n": 275, "levels": "", "n_groups": ""},
        {"id": "W1.3-pairwise", "p": 0.317, "n": 400, "levels": "S03, S04, S05, S06, S07, S08",
         "n_groups": "; ".join(f"S{k:02d}: 40" for k in range(1, 11))}])
    _stats(tmp_path, "stats", [{"id": "W1.2", "p": 0.405, "n": 275, "levels": "", "n_groups": ""}])
    lines = rep.table(tmp_path, "walking-2020")
    row = next(line for line in lines if "Kruskal-Wallis across the 10 subjects" in line).split(" | ")
    assert row[1:5] == ["<1e-05", "0.42 (n = 275)", "0.405 (n = 275)", "no (4.2e+04 x the bound)"]
    size = next(line for line in lines if "indistinguishable subjects (d_xy): subjects" in line).split(" | ")
    assert size[2:5] == ["6 of 10", "not run", "yes"]
    p = next(line for line in lines if "indistinguishable subjects (d_xy): Kruskal" in line).split(" | ")
    assert p[2] == "0.317 (n = 400)" and p[4] == "yes"


def test_pearson_rows_and_their_switches(tmp_path):
    conds = [f"{o}{p}" for p in rep.AUTHORS_START_GOAL for o in "NESO"]
    gd = np.array([rep.AUTHORS_START_GOAL[c[1:]] for c in conds]) * 1.1 + 0.05  # measured = listed, rescaled
    d_xy = 0.02 * gd + 0.01 * np.sin(np.arange(40))
    (tmp_path / "fit-ioc-published").mkdir()
    pd.DataFrame({"model": "improved OC (published)", "condition": conds, "global_distance": gd, "d_xy": d_xy,
                  "d_gamma": np.r_[-0.05 * gd[:37], [np.nan] * 3]}).to_parquet(tmp_path / "fit-ioc-published" / "distances.parquet")
    lines = rep.table(tmp_path, "walking-2020", rep.accounts(tmp_path, "walking-2020"))
    row = next(line for line in lines if "Pearson r of d_xy" in line).split(" | ")
    r = stats.pearsonr(gd, d_xy)[0]
    assert row[2] == f"r = {r:.3f} (n = 40)" and row[3] == "not run"
    # a linear rescaling of the distance leaves r unchanged: the listed distances give the same r
    assert f"listed start-goal distances r = {r:.3f}" in row[5]
    g = next(line for line in lines if "Pearson r of d_gamma" in line).split(" | ")
    assert g[2] == "r = -1.000 (n = 37)" and g[4] == "no (-23%)"


def test_walking_2020_subject_figures_on_the_published_data(datasets, cli, tmp_path):
    for args in (("import-published", "walking-2020", datasets / "walking-2020"), ("average",), ("compare",),
                 ("compare", "--convention", "published"), ("stats",), ("stats", "--convention", "published")):
        code, _, err = cli(*args, "--out", tmp_path)
        assert code == 0, err
    acc = rep.accounts(tmp_path, "walking-2020")
    lines = {line.split(" | ")[0][2:]: line.split(" | ") for line in rep.table(tmp_path, "walking-2020", acc)[2:]}
    gamma = next(v for k, v in lines.items() if k.startswith(rep.SUBJECTS_GAMMA.what))
    assert gamma[2].startswith("0.7873 ± 0.2384 (n = 275)") and gamma[3].startswith("0.7941 ± 0.1997 (n = 275)")  # continuous: gamma from the paths (measured_gamma "path")
    assert "0.6308 over 400 (+30%)" in gamma[5] and "0.5409 (+12%)" in gamma[5]
    kw = next(v for k, v in lines.items() if k.startswith(rep.SUBJECTS_KRUSKAL.what))
    assert "Kruskal p = 1.9e-11, one-way ANOVA (the authors' public script's test) p = 6.1e-11" in kw[5]
    assert "40 of S02's 40" in kw[5]  # the subject whose marker was lost in every trajectory
    size = next(v for k, v in lines.items() if k.startswith(rep.SUBSET_SIZE.what))
    assert size[2:5] == ["6 of 10", "5 of 10", "yes"]
    assert "published: 6 subjects at p = 0.317, ours 8 at p = 0.0574" in size[5]
