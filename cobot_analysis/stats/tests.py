"""Statistical tests with their effect sizes, as used in docs/methods.md sec. 4 (scipy underneath).

Every test returns a ``TestResult`` (statistic, p, n per group, effect size and its name). The
effect sizes:
- Kruskal-Wallis: epsilon^2 = H (n + 1) / (n^2 - 1)                         (Tomczak & Tomczak 2014)
- Mann-Whitney U: rank-biserial r = 2 U_1 / (n_1 n_2) - 1, > 0 when group 1 tends to be larger
- Wilcoxon signed-rank: matched-pairs rank-biserial r = (W+ - W-) / (W+ + W-)
- one-way ANOVA: eta^2 = SS_between / SS_total
- t-test (Welch): Cohen's d with the pooled standard deviation
- Pearson / Spearman: r (rho) itself
- Fisher's exact test: odds ratio (2 x 2; conditional MLE is not used: sample OR (a d) / (b c));
  Cramer's V for larger tables
- chi-square goodness of fit: Cohen's w = sqrt(chi^2 / n)
- binomial test: Cohen's h = 2 asin(sqrt(p_obs)) - 2 asin(sqrt(p_0))
Normality: Shapiro-Wilk or Kolmogorov-Smirnov against a normal with the sample's mean and sd; equal
variances: Levene's test (scipy's default, centred on the median: Brown-Forsythe).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: smallest group size each test accepts (smaller groups are reported as skipped).
MIN_SIZE = {"kruskal": 2, "mannwhitneyu": 2, "anova": 2, "ttest": 2, "wilcoxon": 2, "pearson": 3, "spearman": 3,
            "fisher": 1, "chisquare": 1, "binomial": 1, "largest_subset": 2, "pairwise_subset": 2,
            "describe": 1}
#: number of groups each test needs: (min, max); None = no limit.
N_GROUPS = {"kruskal": (2, None), "anova": (2, None), "mannwhitneyu": (2, 2), "ttest": (2, 2), "wilcoxon": (2, 2),
            "pearson": (1, 1), "spearman": (1, 1), "fisher": (1, None), "chisquare": (1, 1), "binomial": (1, 1),
            "largest_subset": (2, None), "pairwise_subset": (2, None), "describe": (1, None)}
TESTS = tuple(MIN_SIZE)


@dataclass
class TestResult:
    test: str
    statistic: float = math.nan
    p: float = math.nan
    n: dict = field(default_factory=dict)
    effect_size: float = math.nan
    effect_name: str = ""
    note: str = ""


def kruskal(groups: dict) -> TestResult:
    from scipy import stats

    values = [np.asarray(v, float) for v in groups.values()]
    h, p = stats.kruskal(*values)
    n = sum(len(v) for v in values)
    return TestResult("kruskal", float(h), float(p), {k: len(v) for k, v in groups.items()},
                      float(h * (n + 1) / (n ** 2 - 1)), "epsilon^2")


def mannwhitneyu(groups: dict, alternative: str = "two-sided") -> TestResult:
    from scipy import stats

    (k1, a), (k2, b) = groups.items()
    a, b = np.asarray(a, float), np.asarray(b, float)
    res = stats.mannwhitneyu(a, b, alternative=alternative)
    r = 2 * res.statistic / (len(a) * len(b)) - 1
    return TestResult("mannwhitneyu", float(res.statistic), float(res.pvalue), {k1: len(a), k2: len(b)}, float(r), "rank-biserial r")


def wilcoxon(groups: dict, alternative: str = "two-sided") -> TestResult:
    """Paired: the two groups are aligned sample by sample (the caller pairs them)."""
    from scipy import stats

    (k1, a), (k2, b) = groups.items()
    d = np.asarray(a, float) - np.asarray(b, float)
    res = stats.wilcoxon(d, alternative=alternative)
    nz = d[d != 0]
    ranks = stats.rankdata(np.abs(nz))
    w_plus, w_minus = ranks[nz > 0].sum(), ranks[nz < 0].sum()
    r = (w_plus - w_minus) / (w_plus + w_minus) if len(nz) else math.nan
    return TestResult("wilcoxon", float(res.statistic), float(res.pvalue), {k1: len(a), k2: len(b)}, float(r), "matched rank-biserial r")


def anova(groups: dict) -> TestResult:
    from scipy import stats

    values = [np.asarray(v, float) for v in groups.values()]
    f, p = stats.f_oneway(*values)
    allv = np.concatenate(values)
    ss_total = ((allv - allv.mean()) ** 2).sum()
    ss_between = sum(len(v) * (v.mean() - allv.mean()) ** 2 for v in values)
    return TestResult("anova", float(f), float(p), {k: len(v) for k, v in groups.items()},
                      float(ss_between / ss_total) if ss_total > 0 else math.nan, "eta^2")


def ttest(groups: dict, alternative: str = "two-sided") -> TestResult:
    """Welch's t-test (unequal variances); Cohen's d with the pooled sd."""
    from scipy import stats

    (k1, a), (k2, b) = groups.items()
    a, b = np.asarray(a, float), np.asarray(b, float)
    res = stats.ttest_ind(a, b, equal_var=False, alternative=alternative)
    sp = math.sqrt(((len(a) - 1) * a.var(ddof=1) + (len(b) - 1) * b.var(ddof=1)) / (len(a) + len(b) - 2))
    d = (a.mean() - b.mean()) / sp if sp > 0 else math.nan
    return TestResult("ttest", float(res.statistic), float(res.pvalue), {k1: len(a), k2: len(b)}, float(d), "Cohen's d")


def correlation(x, y, method: str = "pearson", alternative: str = "two-sided") -> TestResult:
    from scipy import stats

    x, y = np.asarray(x, float), np.asarray(y, float)
    fn = stats.pearsonr if method == "pearson" else stats.spearmanr
    res = fn(x, y, alternative=alternative)
    r = float(res.statistic)
    return TestResult(method, r, float(res.pvalue), {"pairs": len(x)}, r, "r" if method == "pearson" else "rho")


def fisher(table, row_labels=None, col_labels=None, alternative: str = "two-sided") -> TestResult:
    """Fisher's exact test of a contingency table (rows = groups, columns = categories)."""
    from scipy import stats

    t = np.asarray(table, dtype=int)
    n = {str(k): int(v) for k, v in zip(row_labels or range(t.shape[0]), t.sum(axis=1))}
    if t.shape == (2, 2):
        res = stats.fisher_exact(t, alternative=alternative)
        a, b, c, d = t.ravel()
        odds = (a * d) / (b * c) if b * c else math.inf if a * d else math.nan
        return TestResult("fisher", float(res.statistic), float(res.pvalue), n, float(odds), "odds ratio")
    res = stats.fisher_exact(t)
    chi2 = stats.chi2_contingency(t, correction=False).statistic if (t.sum(0) > 0).all() and (t.sum(1) > 0).all() else math.nan
    v = math.sqrt(chi2 / (t.sum() * (min(t.shape) - 1))) if min(t.shape) > 1 else math.nan
    return TestResult("fisher", float(res.statistic), float(res.pvalue), n, float(v), "Cramer's V")


def chisquare(counts, expected_share=None) -> TestResult:
    """Goodness of fit of category counts to expected shares (default: uniform)."""
    from scipy import stats

    obs = np.asarray(list(counts.values()), float)
    share = np.full(len(obs), 1 / len(obs)) if expected_share is None else np.asarray(expected_share, float)
    res = stats.chisquare(obs, share / share.sum() * obs.sum())
    return TestResult("chisquare", float(res.statistic), float(res.pvalue), {str(k): int(v) for k, v in counts.items()},
                      float(math.sqrt(res.statistic / obs.sum())), "Cohen's w")


def binomial(k: int, n: int, p0: float = 0.5, alternative: str = "two-sided") -> TestResult:
    from scipy import stats

    res = stats.binomtest(int(k), int(n), p0, alternative=alternative)
    h = 2 * math.asin(math.sqrt(k / n)) - 2 * math.asin(math.sqrt(p0))
    return TestResult("binomial", float(k / n), float(res.pvalue), {"true": int(k), "false": int(n - k)}, float(h), "Cohen's h")


def normality(values, method: str = "shapiro") -> float:
    """p-value of a normality test: Shapiro-Wilk, or Kolmogorov-Smirnov against N(mean, sd)."""
    from scipy import stats

    v = np.asarray(values, float)
    if len(v) < 3 or np.ptp(v) == 0:
        return math.nan
    if method == "shapiro":
        return float(stats.shapiro(v).pvalue)
    if method == "ks":
        return float(stats.kstest(v, "norm", args=(v.mean(), v.std(ddof=1))).pvalue)
    raise ValueError(f"unknown normality test {method!r}")


def equal_variances(groups: dict) -> float:
    """p-value of Levene's test (centred on the median) that the groups have equal variances; NaN when a
    group has fewer than 2 values or every value is the same."""
    from scipy import stats

    values = [np.asarray(v, float) for v in groups.values()]
    if any(len(v) < 2 for v in values) or np.ptp(np.concatenate(values)) == 0:
        return math.nan
    return float(stats.levene(*values).pvalue)
