"""Statistics: reference values (scipy / statsmodels / hand-computed effect sizes), the declarative
configuration, the largest indistinguishable subset, and planted / null effects over several seeds."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from cobot_analysis.averaging import mean_trajectories
from cobot_analysis.compare import compare_sets, pivot
from cobot_analysis.errors import InputError
from cobot_analysis.stats import analyses, config
from cobot_analysis.stats import tests as T
from cobot_analysis.compare import TrajectorySet
from cobot_analysis.stats.sources import build_sources, gamma_as_files_source, kruskal_rows
from cobot_analysis.stats.subsets import largest_subset, pairwise_cliques, pairwise_subset

sys.path.insert(0, str(Path(__file__).parent))
from cobot_analysis.synth.tables import pair_table  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
A = [1.1, 2.3, 2.9, 4.0, 5.2]
B = [3.0, 4.4, 5.1, 6.3, 7.7, 8.1]
C = [0.5, 0.9, 1.7, 2.2]


# ---- tests and effect sizes against references -----------------------------------------------------
def test_kruskal_matches_scipy_and_epsilon_squared_by_hand():
    r = T.kruskal({"a": A, "b": B, "c": C})
    h, p = stats.kruskal(A, B, C)
    assert r.statistic == pytest.approx(h) and r.p == pytest.approx(p)
    n = 15
    assert r.effect_size == pytest.approx(h * (n + 1) / (n * n - 1))
    assert r.n == {"a": 5, "b": 6, "c": 4}


def test_mannwhitney_rank_biserial_by_hand():
    r = T.mannwhitneyu({"a": A, "b": B})
    # U_a = number of (a, b) pairs with a > b (no ties): 4.0 > 3.0; 5.2 > 3.0, 4.4, 5.1 -> 4
    assert r.statistic == pytest.approx(4.0)
    assert r.p == pytest.approx(stats.mannwhitneyu(A, B).pvalue)
    assert r.effect_size == pytest.approx(2 * 4 / 30 - 1)  # -0.733: a tends to be smaller
    less = T.mannwhitneyu({"a": A, "b": B}, "less")
    assert less.p == pytest.approx(stats.mannwhitneyu(A, B, alternative="less").pvalue) and less.p < r.p


def test_fisher_odds_ratio_and_larger_tables():
    r = T.fisher([[8, 2], [1, 5]])
    assert r.effect_size == pytest.approx(8 * 5 / (2 * 1))
    assert r.p == pytest.approx(stats.fisher_exact([[8, 2], [1, 5]]).pvalue)
    big = T.fisher([[5, 1, 0], [1, 4, 5]])
    assert big.effect_name == "Cramer's V" and 0 < big.effect_size <= 1 and big.p < 0.05


def test_anova_ttest_wilcoxon_correlation_chisquare_binomial_by_hand():
    an = T.anova({"a": A, "b": B, "c": C})
    allv = np.array(A + B + C)
    ssb = sum(len(g) * (np.mean(g) - allv.mean()) ** 2 for g in (A, B, C))
    assert an.effect_size == pytest.approx(ssb / ((allv - allv.mean()) ** 2).sum())
    assert an.p == pytest.approx(stats.f_oneway(A, B, C).pvalue)
    tt = T.ttest({"a": A, "b": B})
    sp = math.sqrt((4 * np.var(A, ddof=1) + 5 * np.var(B, ddof=1)) / 9)
    assert tt.effect_size == pytest.approx((np.mean(A) - np.mean(B)) / sp)
    assert tt.p == pytest.approx(stats.ttest_ind(A, B, equal_var=False).pvalue)
    x, y = [1.0, 2.0, 3.0, 4.0, 5.0], [1.2, 1.9, 3.4, 3.9, 5.3]
    w = T.wilcoxon({"x": x, "y": y})
    # differences -0.2 0.1 -0.4 0.1 -0.3 -> ranks 3 1.5 5 1.5 4: W+ = 3, W- = 12
    assert w.effect_size == pytest.approx((3 - 12) / 15)
    assert T.correlation(x, y).statistic == pytest.approx(stats.pearsonr(x, y).statistic)
    ch = T.chisquare({"u": 30, "v": 10})
    assert ch.statistic == pytest.approx(10.0) and ch.effect_size == pytest.approx(math.sqrt(10 / 40))
    b = T.binomial(15, 20, 0.5)
    assert b.p == pytest.approx(stats.binomtest(15, 20).pvalue)
    assert b.effect_size == pytest.approx(2 * math.asin(math.sqrt(0.75)) - 2 * math.asin(math.sqrt(0.5)))


def test_normality_checks():
    rng = np.random.default_rng(0)
    normal, skewed = rng.normal(size=200), rng.exponential(size=200)
    assert T.normality(normal, "shapiro") > 0.05 and T.normality(skewed, "shapiro") < 1e-6
    assert T.normality(skewed, "ks") < 0.01
    assert math.isnan(T.normality([1.0, 1.0, 1.0], "ks"))


def test_holm_matches_statsmodels_and_hand():
    rows = pd.DataFrame({"family": ["f"] * 4 + ["g"], "status": "ok", "test": "kruskal",
                         "p": [0.01, 0.04, 0.03, 0.005, 0.04]})
    out = analyses.holm(rows, 0.05)
    # sorted 0.005 0.01 0.03 0.04 -> x4 x3 x2 x1 = 0.02 0.03 0.06 0.04 -> monotone 0.02 0.03 0.06 0.06
    assert out["p_holm"].tolist() == pytest.approx([0.03, 0.06, 0.06, 0.02, 0.04])
    assert out["significant"].tolist() == [True, False, False, True, True]


def test_holm_leaves_the_garbage_collector_as_it_found_it(monkeypatch):
    """holm freezes the heap around statsmodels' own gc.collect(); nothing stays frozen after it, also when the
    correction raises."""
    import gc

    rows = pd.DataFrame({"family": ["f", "f"], "status": "ok", "test": "kruskal", "p": [0.01, 0.2]})
    analyses.holm(rows, 0.05)
    assert gc.get_freeze_count() == 0
    import statsmodels.stats.multitest as multitest

    def failing(*args, **kwargs):
        assert gc.get_freeze_count() > 0  # the objects that existed before the correction are skipped
        raise RuntimeError("boom")

    monkeypatch.setattr(multitest, "multipletests", failing)
    with pytest.raises(RuntimeError, match="boom"):
        analyses.holm(rows, 0.05)
    assert gc.get_freeze_count() == 0


def test_vectorised_kruskal_matches_scipy_with_ties():
    rng = np.random.default_rng(2)
    v = rng.normal(size=(6, 3, 15))
    v[0, 1, :4] = v[0, 0, :4]  # ties
    assert kruskal_rows(v) == pytest.approx([stats.kruskal(*r).pvalue for r in v])


# ---- largest indistinguishable subset ----------------------------------------------------------------
def test_largest_subset_exact_and_greedy_find_the_planted_outliers():
    rng = np.random.default_rng(5)
    groups = {f"S{k}": rng.normal(0, 1, 40) for k in range(7)}
    groups["S2"] = groups["S2"] + 3
    groups["S5"] = groups["S5"] - 3
    exact = largest_subset(groups)
    assert sorted(exact.members) == ["S0", "S1", "S3", "S4", "S6"] and exact.p > 0.05
    assert exact.method.startswith("exact (")
    greedy = largest_subset(groups, max_exact=3)
    assert greedy.method.startswith("greedy") and sorted(greedy.members) == sorted(exact.members)
    assert stats.kruskal(*[groups[k] for k in exact.members]).pvalue == pytest.approx(exact.p)


def test_pairwise_subset_drops_the_most_atypical_median_until_every_pair_agrees():
    a = np.arange(20.0)
    groups = {"A": a, "B": a + 0.1, "C": a + 0.2, "D": a + 100}  # D differs from every other group
    res = pairwise_subset(groups)
    assert res.members == ["A", "B", "C"] and "dropped, most atypical median first: D" in res.method
    assert res.p == pytest.approx(stats.kruskal(a, a + 0.1, a + 0.2).pvalue)
    # a chain: A ~ B (Mann-Whitney p 0.14), B ~ C, but A !~ C (p 0.006): two largest sets of two
    chain = {"A": a, "B": a + 3, "C": a + 6}
    assert [c.members for c in pairwise_cliques(chain)] == [["A", "B"], ["B", "C"]]
    assert pairwise_cliques(chain)[0].p == pytest.approx(stats.kruskal(a, a + 3).pvalue)
    # A and C lie equally far from the pooled median: the first label goes first
    assert pairwise_subset(chain).members == ["B", "C"]
    # ours (Kruskal p > 0.05): not all three (p 0.017); of the two equal pairs, the first
    assert largest_subset(chain).members == ["A", "B"] and stats.kruskal(a, a + 3, a + 6).pvalue < 0.05


def _gamma_set(gammas: dict, n: int = 4) -> TrajectorySet:
    """One walking condition: a published mean ("m") and subject trials, gamma as given (NaN: marker loss)."""
    meta = pd.DataFrame([{"study": "walking-2020", "trial": k, "kind": "mean" if k == "m" else "trial", "entity": "walker",
                          "subject": None if k == "m" else k, "condition": "N1500"} for k in gammas])
    g = np.array([np.full(n, v, float) for v in gammas.values()])
    z = np.zeros_like(g)
    return TrajectorySet(meta, z, z, z, g)


def test_gamma_as_files_keeps_marker_loss_as_zero_and_wraps_each_angle():
    g = gamma_as_files_source(_gamma_set({"m": 0.5, "S01": 0.7, "S02": np.nan, "S03": -3.0}))
    got = g.set_index("subject")
    assert got.loc["S01", "d_gamma"] == pytest.approx(0.2)
    assert got.loc["S02", "d_gamma"] == pytest.approx(0.5) and got.loc["S02", "d_gamma_loss_zero"] == 0.0
    assert bool(got.loc["S02", "orientation_missing"]) and not got.loc["S01", "orientation_missing"]
    # each angle wrapped on its own (the authors' normalizeAngle), not the difference: 3 vs -3 is 6 rad apart
    g = gamma_as_files_source(_gamma_set({"m": 3.0, "S01": -3.0}))
    assert g["d_gamma"].iloc[0] == pytest.approx(6.0)
    no_mean = _gamma_set({"S01": 0.7})
    assert gamma_as_files_source(no_mean).empty  # only data with the published mean blocks


def test_walking_2020_thesis_statistics_by_the_authors_definitions(datasets, cli, tmp_path):
    """The thesis's subject figures on the published data (docs/methods.md sec. 11): the authors'
    subject-vs-mean d_gamma, its tests across subjects, and the 6-subject subset at p = 0.31."""
    ws = tmp_path / "w"
    for args in (("import-published", "walking-2020", datasets / "walking-2020"), ("average",),
                 ("compare", "--convention", "published"), ("stats", "--convention", "published")):
        code, _, err = cli(*args, "--out", ws)
        assert code == 0, err
    s = pd.read_parquet(ws / "stats-published" / "stats.parquet").set_index("id")
    assert s.loc["W1.3-pairwise", "levels"] == "S03, S04, S05, S06, S07, S08"
    assert s.loc["W1.3-pairwise", "p"] == pytest.approx(0.3172, abs=5e-4)  # the thesis: 6 subjects, p = 0.31
    assert len(s.loc["W1.3", "levels"].split(", ")) == 8 and s.loc["W1.3", "p"] == pytest.approx(0.0574, abs=5e-4)
    assert s.loc["W1.1", "p"] == pytest.approx(1.12e-6, rel=0.01)
    assert s.loc["W1.2", "p"] == pytest.approx(0.420, abs=1e-3)  # without the marker-loss rows
    assert s.loc["W1.2-files", "p"] == pytest.approx(1.94e-11, rel=0.01)  # kept as the files hold them
    assert s.loc["W1.2-files-anova", "p"] == pytest.approx(6.11e-11, rel=0.01)
    assert s.loc["W1.2-files", "n"] == 400 and s.loc["W1.2", "n"] == 275
    from cobot_analysis.compare import read_trajectory_set

    g = gamma_as_files_source(read_trajectory_set(ws / "import-published" / "trajectories.parquet", ("trajectories",)))
    assert len(g) == 400 and int(g["orientation_missing"].sum()) == 125 and int((g["d_gamma"] == 0).sum()) == 30
    assert g["d_gamma"].mean() == pytest.approx(0.6308, abs=1e-4)
    assert g.loc[~g["orientation_missing"], "d_gamma"].mean() == pytest.approx(0.7868, abs=1e-4)


# ---- configuration ---------------------------------------------------------------------------------
def _cfg(**extra):
    base = {"id": "Q", "source": "durations", "value": "duration", "group": "scenario", "test": "kruskal", "family": "f"}
    return {"study": "s", "analysis": [{**base, **extra}]}


@pytest.mark.parametrize("extra, message", [
    ({"value": "speed"}, "analysis Q: unknown column(s) ['speed'] in source 'durations'"),
    ({"test": "kruskall"}, "analysis Q: unknown test 'kruskall'"),
    ({"source": "nope"}, "analysis Q: unknown source 'nope'"),
    ({"filter": {"goal": "x"}}, "unknown column(s) ['goal']"),
    ({"colour": 1}, "unknown key(s) ['colour']"),
    ({"alternative": "bigger"}, "unknown alternative 'bigger'"),
    ({"test": "pearson"}, "pearson needs 'versus'"),
    ({"group": None, "test": "mannwhitneyu"}, "needs 'group'"),
    ({"test": "mannwhitneyu", "alternative": "less", "pairwise": True},
     "one-sided (less: group 1 < group 2) needs levels = [group 1, group 2]"),
])
def test_config_errors_are_one_line(extra, message):
    data = _cfg(**extra)
    if extra.get("group", 1) is None:
        del data["analysis"][0]["group"]
    with pytest.raises(InputError) as err:
        config.parse(data, Path("study.toml"))
    assert message in str(err.value) and "\n" not in str(err.value) and str(err.value).startswith("study.toml: ")


def test_unknown_group_level_is_rejected_before_any_test():
    cfg = config.parse(_cfg(levels=[1, 2, 5]))
    sources = {"durations": pd.DataFrame({"scenario": [1, 1, 2, 2, 3], "duration": [1.0, 2, 3, 4, 5]})}
    with pytest.raises(InputError, match=r"group level\(s\) \[5\] not found"):
        config.check_levels(cfg, sources)


@pytest.mark.parametrize("name", ["walking-2020", "pair-carriage-2022", "synthetic-pairs"])
def test_shipped_configurations_are_valid(name):
    cfg = config.load(ROOT / "pipelines" / f"{name}.toml")
    assert cfg.analyses and cfg.study


def test_small_groups_are_skipped_with_the_reason_and_normality_selects_the_test():
    df = pd.DataFrame({"scenario": [1, 1, 1, 2, 3, 3, 3], "duration": [1.0, 1.1, 0.9, 5.0, 2.0, 2.2, 2.1]})
    cfg = config.parse(_cfg(pairwise=True, test="mannwhitneyu"))
    rows = analyses.run(cfg, {"durations": df})
    assert rows.set_index("id").loc["Q[1 vs 3]", "status"] == "ok"
    skipped = rows[rows["id"].str.contains("2")]
    assert len(skipped) == 2
    assert all(s.startswith("skipped: group(s) 2 have fewer than 2 values") for s in skipped["status"])
    assert skipped["p_holm"].isna().all()  # skipped rows are outside the Holm family
    rng = np.random.default_rng(1)
    norm = pd.DataFrame({"scenario": np.repeat([1, 2], 60), "duration": rng.normal(10, 1, 120)})
    row = analyses.run(config.parse(_cfg(normality="shapiro", parametric="anova")), {"durations": norm}).iloc[0]
    assert row["test"] == "anova" and row["p"] == pytest.approx(stats.f_oneway(*[g["duration"] for _, g in norm.groupby("scenario")]).pvalue)


# ---- planted and null effects ------------------------------------------------------------------------
def _study_stats(seed, n_pairs=20, **kw):
    ts = pivot(pair_table(seed=seed, n_pairs=n_pairs, goals=9, n=20, **kw))
    d = compare_sets(ts, pivot(mean_trajectories(ts)))
    cfg = config.load(ROOT / "pipelines" / "synthetic-pairs.toml")
    out = analyses.run(cfg, build_sources(ts, d))
    return out.set_index("id")


@pytest.mark.parametrize("seed", [1, 2])
def test_planted_effects_are_detected(seed):
    s = _study_stats(seed)
    assert s.loc["Q1.1", "significant"]  # scenario 3 faster
    assert s.loc["Q1.1-pairwise[1 vs 3]", "significant"] and s.loc["Q1.1-pairwise[2 vs 3]", "significant"]
    assert not s.loc["Q1.1-pairwise[1 vs 2]", "significant"]
    assert s.loc["Q4.1-entity", "significant"] and s.loc["Q4.1-entity", "effect_size"] > 0  # table less variable
    assert all(s.loc[f"Q3[{k}]", "significant"] for k in (1, 2, 3))  # optimal for Subject 1 chosen
    assert s.loc["Q2.1", "significant"]  # table returns closer to reversed forward paths than subjects'


@pytest.mark.slow
def test_no_effect_reported_where_none_was_planted():
    """Null study: no scenario effect, random configuration choices, no pair effect. The pair effect
    (Q4.2) is checked on a balanced design (every pair makes the same choices): with random choices,
    trials in rarely chosen configurations sit close to means of few trials, which is a design
    effect and not a pair effect."""
    false = {"Q1.1": 0, "Q3": 0, "Q4.2": 0}
    seeds = range(10, 13)
    for seed in seeds:
        s = _study_stats(seed, n_pairs=12, speedup=0.0, p_optimal=0.5)
        false["Q1.1"] += bool(s.loc["Q1.1", "significant"])
        false["Q3"] += any(bool(s.loc[f"Q3[{k}]", "significant"]) for k in (1, 2, 3))
        if seed < 12:
            s = _study_stats(seed, n_pairs=12, speedup=0.0, p_optimal=1.0)
            false["Q4.2"] += any(bool(s.loc[f"Q4.2[{e}]", "significant"]) for e in ("subject1", "subject2", "table"))
    # Holm keeps the family-wise error at 5 %: at most one false alarm per question over the seeds
    assert all(v <= 1 for v in false.values()), false


def test_identical_values_are_skipped_not_nan():
    df = pd.DataFrame({"scenario": [1, 1, 2, 2, 3, 3], "duration": [2.0] * 6})
    row = analyses.run(config.parse(_cfg()), {"durations": df}).iloc[0]
    assert row["status"] == "skipped: all 6 values are identical (2); kruskal is undefined" and np.isnan(row["p_holm"])
    assert largest_subset({"a": [1.0, 1.0], "b": [1.0, 1.0]}).p == 1.0


def test_a_correlation_with_a_constant_variable_is_skipped_with_its_reason(recwarn):
    """Before: r and p NaN, said by scipy's ConstantInputWarning only (a study of one scenario, or subjects of one mass);
    now the row says which variable takes one value."""
    df = pd.DataFrame({"scenario": [3] * 6, "duration": [2.0, 3.0, 2.5, 4.0, 3.5, 1.0]})
    row = analyses.run(config.parse(_cfg(test="spearman", versus="scenario")), {"durations": df}).iloc[0]
    assert row["status"] == "skipped: scenario takes one value (3) over the 6 pairs; spearman is undefined"
    assert not [w for w in recwarn if "constant" in str(w.message).lower()]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-100, 100), min_size=2, max_size=15), st.lists(st.floats(-100, 100), min_size=2, max_size=15))
def test_rank_biserial_is_the_mean_sign_of_all_comparisons(a, b):
    """r = P(a > b) - P(a < b) over all pairs (ties count 0); bounded by [-1, 1]; antisymmetric."""
    r = T.mannwhitneyu({"a": a, "b": b}).effect_size
    diff = np.sign(np.subtract.outer(np.array(a), np.array(b)))
    assert r == pytest.approx(diff.mean(), abs=1e-12)
    assert -1 <= r <= 1 and T.mannwhitneyu({"b": b, "a": a}).effect_size == pytest.approx(-r, abs=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 4), st.integers(3, 12), st.integers(0, 10_000))
def test_vectorised_kruskal_property(k, n, seed):
    rng = np.random.default_rng(seed)
    v = np.round(rng.normal(size=(3, k, n)), 1)  # rounding makes ties common
    expected = [stats.kruskal(*row).pvalue if np.ptp(row) > 0 else np.nan for row in v]
    np.testing.assert_allclose(kruskal_rows(v), expected, rtol=1e-9, equal_nan=True)


def test_a_paired_wilcoxon_counts_the_pairs_it_tests():
    """n of a paired test is the pairs tested (docs/schemas.md, stats: 'number of values (or pairs) tested'), not the
    trials: 3 trials per subject and condition, 6 subjects, one subject without condition B -> 5 pairs of means."""
    rng = np.random.default_rng(3)
    rows = [{"subject": f"S{s}", "condition": c, "d": float(rng.normal(1.0 if c == "A" else 1.5, 0.1))}
            for s in range(6) for c in "AB" for _ in range(3) if not (s == 5 and c == "B")]
    df = pd.DataFrame(rows)
    a = config.Analysis(id="q", description="", source="t", value="d", test="wilcoxon", family="f", group="condition",
                        paired_by=["subject"], min_size=3)
    (row,) = analyses.run_analysis(a, df, 0.05)
    assert row["status"] == "ok" and row["n"] == 5, row
    assert row["n_groups"] == "A: 18; B: 15"
    assert row["note"] == "paired by subject: 5 pairs, each value the mean of 3; 1 without both levels left out"
    means = df.groupby(["subject", "condition"])["d"].mean().unstack().dropna()
    assert row["p"] == pytest.approx(stats.wilcoxon(means["A"], means["B"]).pvalue)


# ---- a study of one's own: what the row says about the values it did not test ----------------------
def test_missing_values_left_out_are_counted_per_group():
    """d_gamma of a trajectory without orientation is NaN: the row says how many values each group lost,
    so that n = 4 of 6 is not read as a design with 4 trials."""
    df = pd.DataFrame({"scenario": [1, 1, 1, 2, 2, 2], "duration": [1.0, np.nan, 1.2, 2.0, 2.1, np.nan]})
    (row,) = analyses.run_analysis(config.parse(_cfg(test="mannwhitneyu")).analyses[0], df, 0.05)
    assert row["n"] == 4 and row["n_groups"] == "1: 2; 2: 2"
    assert row["note"] == "2 missing values of duration left out (1: 1; 2: 1)"
    corr = config.parse({"study": "s", "analysis": [{"id": "r", "source": "durations", "value": "duration",
                                                     "versus": "scenario", "test": "spearman", "family": "f"}]})
    (row,) = analyses.run_analysis(corr.analyses[0], df, 0.05)
    assert row["n"] == 4 and row["note"] == "2 rows without scenario or duration left out"


def test_a_between_groups_test_on_repeated_measures_says_so():
    """Trials of one subject are not independent: a Mann-Whitney test of two conditions walked by the same
    4 subjects (6 trials each) treats 48 values as independent; the row says it. Grouped by subject (the
    trials nested in their group) or one value per subject, nothing to say."""
    rng = np.random.default_rng(0)
    df = pd.DataFrame([{"subject": f"S{s}", "condition": c, "d_xy": rng.normal(0.1, 0.02)}
                       for s in range(4) for c in "AB" for _ in range(6)])
    a = config.Analysis(id="q", description="", source="distances", value="d_xy", test="mannwhitneyu", family="f",
                        group="condition")
    (row,) = analyses.run_analysis(a, df, 0.05)
    assert row["status"] == "ok" and row["note"] == (
        "not independent: 48 values from 4 subjects (12 each), each subject in 2 groups; mannwhitneyu treats "
        "every value as independent (repeated measures)")
    (by_subject,) = analyses.run_analysis(config.Analysis(**{**a.__dict__, "group": "subject", "test": "kruskal"}), df, 0.05)
    (one_each,) = analyses.run_analysis(a, df.groupby(["subject", "condition"], as_index=False)["d_xy"].mean()
                                        .assign(subject=lambda d: d["subject"] + d["condition"]), 0.05)
    assert by_subject["note"] == "" and one_each["note"] == ""
    (unknown,) = analyses.run_analysis(a, df.assign(subject=df["subject"].where(df.index >= 2)), 0.05)
    assert unknown["note"].startswith("not independent: 48 values from 4 subjects (10-12 each), 2 without a subject, each")


def test_the_switch_to_anova_needs_every_group_checked_and_says_unequal_variances():
    """normality + parametric = anova switches only when every group is shown normal: a group of 2 values, whose
    normality cannot be checked, keeps the rank test, and the row says why. The switch is the published rule (the
    thesis's KS, then ANOVA): on a group 10 times as spread it is kept, and the row says the variances differ
    (Levene, scipy), as a declared ANOVA does."""
    rng = np.random.default_rng(2)
    normal = {1: rng.normal(10, 1, 40), 2: rng.normal(10, 1, 40)}
    df = lambda groups: pd.DataFrame([{"scenario": k, "duration": v} for k, vs in groups.items() for v in vs])  # noqa: E731
    switch = _cfg(normality="shapiro", parametric="anova")
    ok = analyses.run(config.parse(switch), {"durations": df(normal)}).iloc[0]
    assert ok["test"] == "anova"
    two = analyses.run(config.parse(switch), {"durations": df({**normal, 3: [9.0, 11.0]})}).iloc[0]
    assert two["test"] == "kruskal" and "normality not checked in group(s) 3 (fewer than 3 values, or all equal)" in two["note"]
    spread = {1: rng.normal(10, 1, 40), 2: rng.normal(10, 10, 40)}
    assert all(stats.shapiro(v).pvalue > 0.05 for v in spread.values())
    levene = stats.levene(*spread.values()).pvalue
    wide = analyses.run(config.parse(switch), {"durations": df(spread)}).iloc[0]
    assert wide["test"] == "anova" and (f"variances differ (Levene p {levene:.3g}): one-way ANOVA assumes equal variances -> "
                                        "anova") in wide["note"]
    declared = analyses.run(config.parse(_cfg(test="anova")), {"durations": df(spread)}).iloc[0]
    assert declared["test"] == "anova" and declared["note"] == (
        f"variances differ (Levene p {levene:.3g}): one-way ANOVA assumes equal variances")


def test_the_statistics_table_names_each_holm_family_and_its_tests():
    """With many questions the reader must see which p-values were corrected together: stats.md lists each family
    with its number of tests and their ids (skipped and descriptive rows are in none)."""
    df = pd.DataFrame({"scenario": np.repeat([1, 2, 3], 5), "duration": np.arange(15.0)})
    q = [{"id": f"Q{i}", "source": "durations", "value": "duration", "group": "scenario", "test": t, "family": f}
         for i, (t, f) in enumerate([("kruskal", "time"), ("anova", "time"), ("kruskal", "other"), ("describe", "time")])]
    q.append({**q[0], "id": "Qs", "filter": {"scenario": 9}})
    rows = analyses.run(config.parse({"study": "s", "analysis": q}), {"durations": df})
    md = analyses.markdown(rows, "t")
    assert "Holm families (p-values corrected together): time: 2 tests (Q0, Q1); other: 1 test (Q2)." in md


def test_rows_without_a_group_level_are_counted_and_a_group_column_left_empty_says_why():
    """start_orientation is parsed from walking-2020 codes (E4015): a lab's own condition names give none. Rows
    without a level are left out and counted; none at all: skipped naming the column, not 'no data'."""
    rng = np.random.default_rng(4)
    conds = ["N1500", "E1500", "corridor 1", "corridor 2"]
    d = pd.DataFrame({"condition": np.repeat(conds, 5), "d_xy": rng.normal(0.1, 0.02, 20), "comparison": "individual-mean"})
    d["start_orientation"] = d["condition"].map(lambda c: c[0] if c[0] in "NESO" and c[1:].isdigit() else None)
    a = config.Analysis(id="W1.5", description="", source="distances", value="d_xy", test="kruskal", family="f",
                        group="start_orientation")
    (row,) = analyses.run_analysis(a, d, 0.05)
    assert row["status"] == "ok" and row["n"] == 10 and "10 rows without start_orientation left out" in row["note"]
    (row,) = analyses.run_analysis(a, d[d["condition"].str.startswith("corridor")], 0.05)
    assert row["status"] == ("skipped: start_orientation has no value in the 10 rows of this subset (derived from "
                             "walking-2020 start-condition codes such as E4015 that the paths start at; conditions here: corridor 1, corridor 2)")
