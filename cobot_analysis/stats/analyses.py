"""Run the declared analyses of a study on its sources -> one STATS row per test.

For each analysis: filter the source, split by the ``per`` columns, collect the value column per
group level, check group sizes (too small -> a row with status "skipped: ..." and the reason),
check normality where asked (every group normal -> the ``parametric`` test instead), run the
test (stats.tests), and finally Holm-correct the p-values within each family
(statsmodels ``multipletests(method="holm")``). Descriptive rows (describe, largest_subset,
pairwise_subset) are not part of the Holm families.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd

from cobot_analysis.collector import frozen
from cobot_analysis.schema import Column, TableSchema, as_text
from cobot_analysis.stats import tests as T
from cobot_analysis.stats.config import Analysis, StudyConfig, match as _match, values_text
from cobot_analysis.stats.subsets import largest_subset, pairwise_cliques, pairwise_subset

STATS = TableSchema(
    name="stats",
    version=1,
    description="Statistical tests of a study (pipelines/<study>.toml), one row per test.",
    columns={
        "study": Column("string", "", "study of the configuration"),
        "id": Column("string", "", "question id (e.g. Q1.1), suffixed by the per-level and pair of levels"),
        "question": Column("string", "", "question id as declared"),
        "description": Column("string", "", "what is tested"),
        "family": Column("string", "", "Holm family"),
        "source": Column("string", "", "table the data come from (stats.sources)"),
        "subset": Column("string", "", "row filter applied, and the per-level"),
        "value": Column("string", "", "tested column"),
        "group": Column("string", "", "grouping column"),
        "levels": Column("string", "", "group levels compared"),
        "test": Column("string", "", "test actually run (after the normality check)"),
        "alternative": Column("string", "", "two-sided, less or greater"),
        "statistic": Column("float", "-", "test statistic (H, U, F, t, W, r, odds ratio, chi^2, share)"),
        "p": Column("float", "-", "p-value"),
        "p_holm": Column("float", "-", "Holm-corrected p within the family"),
        "significant": Column("bool", "", "p_holm < alpha"),
        "n": Column("int", "-", "number of values (or pairs) tested"),
        "n_groups": Column("string", "", "n per group, 'level: n; ...'"),
        "effect_size": Column("float", "-", "effect size (see effect_name)"),
        "effect_name": Column("string", "", "epsilon^2, rank-biserial r, odds ratio, eta^2, Cohen's d, ..."),
        "normality_p": Column("float", "-", "smallest normality p across groups (NaN if not checked)"),
        "summary": Column("string", "", "per group: median [q1, q3] and mean +- sd (or counts)"),
        "status": Column("string", "", "'ok' or 'skipped: <reason>'"),
        "note": Column("string", "", "details (e.g. the members of the largest indistinguishable subset)"),
    },
)
NOT_HOLM = ("describe", "largest_subset", "pairwise_subset")


def _summary(groups: dict) -> str:
    parts = []
    for k, v in groups.items():
        v = np.asarray(v, float)
        if not len(v):
            parts.append(f"{k}: none")
            continue
        if len(v) == 1:  # one value: no spread to give (a sample sd of 0 would claim one)
            parts.append(f"{k}: {v[0]:.3g} (n = 1)")
            continue
        q1, med, q3 = np.percentile(v, [25, 50, 75])
        parts.append(f"{k}: {med:.3g} [{q1:.3g}, {q3:.3g}], {v.mean():.3g} +- {v.std(ddof=1):.3g}")
    return "; ".join(parts)


def _chance(a: Analysis, df: pd.DataFrame) -> float:
    if a.chance is None:
        return 0.5
    if isinstance(a.chance, str):
        return float(pd.to_numeric(df[a.chance], errors="coerce").mean())
    return float(a.chance)


def _groups(a: Analysis, df: pd.DataFrame) -> dict:
    if not a.group:
        return {"all": df[a.value].to_numpy()}
    levels = a.levels if a.levels is not None else sorted(df[a.group].dropna().unique(), key=lambda v: (str(type(v)), v))
    return {as_text(lv): df.loc[_match(df[a.group], lv), a.value].to_numpy() for lv in levels}


#: who is measured: the values of one subject (or pair) are not independent of each other.
UNITS = ("subject", "pair")
#: tests that take every value as an independent observation.
INDEPENDENT = ("kruskal", "anova", "mannwhitneyu", "ttest", "pearson", "spearman")


def _span(counts: pd.Series) -> str:
    return f"{counts.min()}" if counts.min() == counts.max() else f"{counts.min()}-{counts.max()}"


def repeated_measures(a: Analysis, df: pd.DataFrame, levels, test: str) -> str:
    """Why the values ``test`` took as independent are not: several of one subject (or pair), one subject
    in several groups. "" when each value has its own subject, or the groups are the subjects."""
    if a.group in UNITS:
        return ""
    cols = [a.value, *([a.versus] if a.versus else [])]
    rows = df[df[cols].apply(pd.to_numeric, errors="coerce").notna().all(axis=1)]
    if a.group:
        rows = rows[rows[a.group].map(as_text).isin(list(levels))]
    for unit in (u for u in UNITS if u in rows and u not in a.per and rows[u].notna().any()):
        per_unit = rows.groupby(unit).size()
        if per_unit.max() < 2:
            return ""
        unknown = int(rows[unit].isna().sum())
        text = (f"{len(rows)} values from {len(per_unit)} {unit}s ({_span(per_unit)} each)"
                + (f", {unknown} without a {unit}" if unknown else ""))
        spread = rows.groupby(unit)[a.group].nunique() if a.group else pd.Series([1])
        if spread.max() > 1:
            text += (f", each {unit} in {spread.max()} groups" if spread.min() == spread.max()
                     else f", {int((spread > 1).sum())} of them in several groups")
        return f"not independent: {text}; {test} treats every value as independent (repeated measures)"
    return ""


def _note(row: dict, text: str) -> str:
    """``row``'s note with ``text`` appended ("; " between)."""
    return "; ".join(x for x in (row["note"], text) if x)


def test_needs_spread(test: str) -> bool:
    """Rank and variance tests are undefined when every value is the same."""
    return test in ("kruskal", "mannwhitneyu", "anova", "ttest", "pearson", "spearman")


def _run_one(a: Analysis, df: pd.DataFrame, groups: dict, alpha: float) -> dict:
    """One test on prepared groups -> the STATS fields it determines."""
    row = {"test": a.test, "levels": ", ".join(groups), "status": "ok", "note": "", "normality_p": math.nan}
    categorical = a.test in ("fisher", "chisquare", "binomial", "describe")
    if not categorical:
        numbers = {k: pd.to_numeric(pd.Series(v), errors="coerce") for k, v in groups.items()}
        lost = {k: int(v.isna().sum()) for k, v in numbers.items()}
        groups = {k: v.dropna().to_numpy(float) for k, v in numbers.items()}
        if sum(lost.values()) and a.test not in ("pearson", "spearman"):  # correlations count their incomplete rows below
            row["note"] = (f"{sum(lost.values())} missing values of {a.value} left out ("
                           + "; ".join(f"{k}: {n}" for k, n in lost.items() if n) + ")")
    empty = [k for k, v in groups.items() if len(v) == 0]
    if empty and a.levels is None and len(groups) - len(empty) >= 2:  # e.g. a subject without any orientation
        groups = {k: v for k, v in groups.items() if len(v)}
        row["note"] = _note(row, f"left out (no values): {', '.join(empty)}")
        row["levels"] = ", ".join(groups)
    sizes = {k: len(v) for k, v in groups.items()}
    row.update(n=int(sum(sizes.values())), n_groups="; ".join(f"{k}: {n}" for k, n in sizes.items()))
    small = [k for k, n in sizes.items() if n < a.minimum]
    if not sum(sizes.values()):
        row["status"] = "skipped: no data in this subset (the data do not support this question)"
        return row
    if small:
        row["status"] = (f"skipped: group(s) {', '.join(small)} have fewer than {a.minimum} values ({row['n_groups']})"
                         if sizes else "skipped: no data in this subset")
        return row
    lo, hi = T.N_GROUPS[a.test]
    if len(groups) < lo or (hi is not None and len(groups) > hi):
        row["status"] = f"skipped: {a.test} needs {lo}{'' if hi == lo else f'..{hi}' if hi else '+'} groups, found {len(groups)}"
        return row
    if not categorical:
        row["summary"] = _summary(groups)
        allv = np.concatenate(list(groups.values()))
        if test_needs_spread(a.test) and np.ptp(allv) == 0:
            row["status"] = f"skipped: all {len(allv)} values are identical ({allv[0]:.3g}); {a.test} is undefined"
            return row
    test = a.test
    if a.normality and not categorical:
        ps = {k: T.normality(v, a.normality) for k, v in groups.items()}
        known = [p for p in ps.values() if not np.isnan(p)]
        unchecked = [k for k, p in ps.items() if np.isnan(p)]  # a group no test can show normal is not normal
        row["normality_p"] = min(known) if known else math.nan
        normal = bool(known) and not unchecked and all(p > alpha for p in known)
        verdict = ("all groups normal" if normal else "not all groups normal" if any(p <= alpha for p in known) else
                   f"normality not checked in group(s) {', '.join(unchecked)} (fewer than 3 values, or all equal)")
        text = f"{a.normality} normality: smallest p {row['normality_p']:.3g}, {verdict}"
        if a.parametric and normal:  # the published rule (e.g. the thesis's KS, then ANOVA): kept, its assumption said
            test = a.parametric
            levene = T.equal_variances(groups) if test == "anova" else math.nan
            if levene <= alpha:  # one-way ANOVA assumes equal variances (Welch's t-test does not)
                text += f"; variances differ (Levene p {levene:.3g}): one-way ANOVA assumes equal variances"
        row["note"] = _note(row, text + (f" -> {test}" if a.parametric else ""))
    if a.test == "anova":
        levene = T.equal_variances(groups)
        if levene <= alpha:
            row["note"] = _note(row, f"variances differ (Levene p {levene:.3g}): one-way ANOVA assumes equal variances")
    row["test"] = test
    if test == "describe":
        vals = {k: pd.Series(v) for k, v in groups.items()}
        numeric = all(pd.api.types.is_numeric_dtype(v) and not pd.api.types.is_bool_dtype(v) for v in vals.values())
        allv = pd.concat(list(vals.values())).dropna() if numeric else None
        codes = numeric and len(allv) and bool((allv == allv.round()).all()) and allv.nunique() <= 10
        if numeric and not codes:  # a measurement: distribution; categories and integer codes (scenario 1-3): counts
            row["summary"] = _summary({k: v.dropna().to_numpy(float) for k, v in vals.items()})
            missing = sum(int(v.isna().sum()) for v in vals.values())
            row["note"] = f"{missing} missing values left out" if missing else row["note"]
        else:
            row["summary"] = "; ".join(f"{k}: " + ", ".join(f"{as_text(c)}: {n}" for c, n in v.value_counts().sort_index().items())
                                       for k, v in vals.items())
        return row
    if test == "largest_subset":
        res = largest_subset(groups, alpha)
        row.update(statistic=res.statistic, p=res.p, levels=", ".join(map(str, res.members)),
                   note="; ".join(x for x in (row["note"], f"{len(res.members)} of {len(groups)} groups indistinguishable "
                                  f"(Kruskal p > {alpha}): {', '.join(map(str, res.members))}; {res.method}") if x))
        return row
    if test == "pairwise_subset":
        res = pairwise_subset(groups, alpha)
        sets = "; ".join(f"{', '.join(map(str, c.members))} (Kruskal p {c.p:.3g})" for c in pairwise_cliques(groups, alpha))
        row.update(statistic=res.statistic, p=res.p, levels=", ".join(map(str, res.members)),
                   note="; ".join(x for x in (row["note"], f"{len(res.members)} of {len(groups)} groups with every pair "
                                  f"indistinguishable: {', '.join(map(str, res.members))}; {res.method}; largest such sets: "
                                  f"{sets}") if x))
        return row
    if test in ("fisher", "binomial"):
        flag = {k: pd.Series(v).astype(bool).to_numpy() for k, v in groups.items()}
        if len(flag) == 1 or a.chance is not None:
            v = np.concatenate(list(flag.values()))
            k, n = int(v.sum()), len(v)
            p0 = _chance(a, df)
            if test == "binomial":
                res = T.binomial(k, n, p0, a.alternative)
            else:
                expect = int(round(n * p0))
                res = T.fisher([[k, n - k], [expect, n - expect]], ["observed", "chance"], alternative=a.alternative)
            row["summary"] = f"{k} of {n} ({100 * k / n:.1f} %) vs chance {100 * p0:.1f} %"
        else:
            table = [[int(v.sum()), int((~v).sum())] for v in flag.values()]
            res = T.fisher(table, list(flag), alternative=a.alternative)
            row["summary"] = "; ".join(f"{k}: {t[0]} of {sum(t)}" for k, t in zip(flag, table))
    elif test == "chisquare":
        v = pd.Series(np.concatenate(list(groups.values()))).astype(str)
        cats = list(a.expected) if a.expected else sorted(v.unique())
        counts = {c: int((v == c).sum()) for c in cats}
        res = T.chisquare(counts, [a.expected[c] for c in cats] if a.expected else None)
        row["summary"] = ", ".join(f"{c}: {n} ({100 * n / max(len(v), 1):.0f} %)" for c, n in counts.items())
    elif test in ("pearson", "spearman"):
        pair = df[[a.versus, a.value]].apply(pd.to_numeric, errors="coerce").dropna()
        if len(pair) < a.minimum:
            row["status"] = f"skipped: {len(pair)} complete ({a.versus}, {a.value}) pairs, {test} needs {a.minimum}"
            return row
        constant = [c for c in (a.versus, a.value) if pair[c].nunique() == 1]
        if constant:
            row["status"] = (f"skipped: {constant[0]} takes one value ({pair[constant[0]].iloc[0]:.3g}) over the {len(pair)} "
                             f"pairs; {test} is undefined")
            return row
        res = T.correlation(pair[a.versus], pair[a.value], test, a.alternative)
        row["n"], row["summary"] = len(pair), f"r = {res.statistic:.3f} over {len(pair)} pairs"
        if len(pair) < len(df):
            row["note"] = _note(row, f"{len(df) - len(pair)} rows without {a.versus} or {a.value} left out")
    elif test == "wilcoxon":
        (k1, _), (k2, _) = groups.items()
        sub = df.assign(_g=df[a.group].map(as_text))
        sub = sub[sub["_g"].isin([k1, k2])]
        w = sub.pivot_table(index=a.paired_by, columns="_g", values=a.value, aggfunc="mean")
        units = len(w)
        w = w.dropna(subset=[k1, k2]) if {k1, k2} <= set(w.columns) else w.iloc[0:0]
        row["n"] = len(w)  # the pairs tested (n_groups keeps each group's values)
        if len(w) < a.minimum:
            row["status"] = f"skipped: {len(w)} matched pairs, wilcoxon needs {a.minimum}"
            return row
        res = T.wilcoxon({k1: w[k1].to_numpy(), k2: w[k2].to_numpy()}, a.alternative)
        counts = sub.pivot_table(index=a.paired_by, columns="_g", values=a.value, aggfunc="count").loc[w.index, [k1, k2]]
        means = f", each value the mean of {_span(counts.stack().astype(int))}" if counts.to_numpy().max() > 1 else ""
        unmatched = f"; {units - len(w)} without both levels left out" if units > len(w) else ""
        row["note"] = _note(row, f"paired by {', '.join(a.paired_by)}: {len(w)} pairs{means}{unmatched}")
    elif test in ("mannwhitneyu", "ttest"):
        res = getattr(T, test)(groups, a.alternative)
    else:
        res = getattr(T, test)(groups)
    row.update(statistic=res.statistic, p=res.p, effect_size=res.effect_size, effect_name=res.effect_name)
    if test in INDEPENDENT:
        row["note"] = _note(row, repeated_measures(a, df, groups, test))
    return row


def _filtered(a: Analysis, df: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """The rows of ``a``'s subset, and why it is empty when it is: the filter value that matched
    no row (with the values there are), or an empty source."""
    if df.empty:
        return df, f"no data in this subset: the source {a.source} is empty (the data do not support this question)"
    for col, wanted in a.filter.items():
        hit = _match(df[col], wanted)
        if not hit.any():
            present = df[col].dropna()
            there = f"values of {col} there: {values_text(present)}" if len(present) else f"{col} is empty there"
            return df[hit], f"no row with {col} = {wanted!r} ({there})"
        df = df[hit]
    return df, ""


def run_analysis(a: Analysis, df: pd.DataFrame, alpha: float) -> list[dict]:
    """All rows of one declared analysis (one per ``per`` level and, if pairwise, per pair of levels)."""
    df, empty = _filtered(a, df)
    subset = ", ".join(f"{c} = {v}" for c, v in a.filter.items()) or "all rows"
    base = {"question": a.id, "description": a.description, "family": a.family, "source": a.source,
            "value": a.value, "group": a.group or "", "alternative": a.alternative}
    per_levels = list(df.groupby(a.per, dropna=True, sort=True)) if a.per and len(df) else [((), df)]
    if empty or (a.per and not len(df)):
        per_levels = []
    rows = []
    if not per_levels:
        rows.append({**base, "id": a.id, "subset": subset, "test": a.test, "n": 0, "n_groups": "",
                     "status": f"skipped: {empty or 'no data in this subset (the data do not support this question)'}"})
    for key, part in per_levels:
        key = key if isinstance(key, tuple) else (key,)
        tag = ", ".join(f"{c} = {as_text(v)}" for c, v in zip(a.per, key))
        suffix = "".join(f"[{as_text(v)}]" for v in key)
        where = subset + (f"; {tag}" if tag else "")
        unlabelled = int(part[a.group].isna().sum()) if a.group else 0
        if unlabelled and unlabelled == len(part):
            rows.append({**base, "id": a.id + suffix, "subset": where, "test": a.test, "n": 0, "n_groups": "",
                         "status": f"skipped: {_no_levels(a.group, part)}"})
            continue
        groups = _groups(a, part)
        combos = list(itertools.combinations(groups, 2)) if a.pairwise else [tuple(groups)]
        for combo in combos:
            g = {k: groups[k] for k in combo}
            rid = a.id + suffix + (f"[{' vs '.join(combo)}]" if a.pairwise else "")
            row = _run_one(a, part, g, alpha)
            if unlabelled:
                row["note"] = _note(row, f"{unlabelled} rows without {a.group} left out")
            rows.append({**base, "id": rid, "subset": where, **row})
    return rows


#: group columns the statistics derive from others (stats.sources), and from what.
DERIVED = {"start_orientation": ("walking-2020 start-condition codes such as E4015 that the paths start at", "condition"),
           "distance_class": ("the global distance", "global_distance")}


def _no_levels(group: str, part: pd.DataFrame) -> str:
    """Why ``group`` has no level in the rows ``part``: for a derived column, from what and what is there."""
    text = f"{group} has no value in the {len(part)} rows of this subset"
    if group in DERIVED:
        what, column = DERIVED[group]
        there = values_text(part[column].dropna(), 3) if column in part and part[column].notna().any() else "none"
        text += f" (derived from {what}; {column.replace('_', ' ')}s here: {there})"
    return text


def holm(rows: pd.DataFrame, alpha: float) -> pd.DataFrame:
    """Holm-corrected p within each family (statsmodels), over the rows that ran a test.

    statsmodels' Holm ends with a full ``gc.collect()`` (statsmodels/stats/multitest.py; its removal was proposed in
    statsmodels PR #8671): 75 ms per family in a process that has imported the pipeline (164 000 objects tracked),
    against 0.02 ms with the objects that exist before the call left out of it (``collector.frozen``). The p-values
    are the same."""
    from statsmodels.stats.multitest import multipletests

    rows = rows.copy()
    rows["p_holm"] = np.nan
    tested = rows["status"].eq("ok") & ~rows["test"].isin(NOT_HOLM) & rows["p"].notna()
    with frozen():
        for _, idx in rows[tested].groupby("family").groups.items():
            rows.loc[idx, "p_holm"] = multipletests(rows.loc[idx, "p"].to_numpy(float), alpha=alpha, method="holm")[1]
    rows["significant"] = rows["p_holm"].lt(alpha)
    return rows


def run(config: StudyConfig, sources: dict, progress=None) -> pd.DataFrame:
    """Every analysis of ``config`` on ``sources`` -> STATS table (Holm-corrected)."""
    items = progress(config.analyses, "stats") if progress else config.analyses
    rows = []
    for a in items:
        rows += run_analysis(a, sources[a.source], config.alpha)
    df = pd.DataFrame(rows)
    for c, col in STATS.columns.items():
        if c not in df.columns:
            df[c] = np.nan if col.dtype in ("float", "int") else ""
    df["study"] = config.study
    df = holm(df, config.alpha)
    for c, col in STATS.columns.items():
        if col.dtype == "string":
            df[c] = df[c].fillna("").astype(str)
    df["n"] = df["n"].fillna(0).astype(int)
    return df[list(STATS.columns)]


def markdown(df: pd.DataFrame, title: str, alpha: float = 0.05) -> str:
    """The Markdown table of a study's tests."""
    lines = [f"## {title}", "",
             f"Holm-corrected p within each family; significant = p_holm < {alpha}. Effect sizes: see "
             "`stats.tests`. Skipped rows say why.", "",
             "| id | description | subset | test | n | statistic | p | p (Holm) | effect size | summary / note |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    def f(v, fmt=".3g"):
        return "" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, fmt)
    for r in df.itertuples():
        eff = f"{f(r.effect_size)} ({r.effect_name})" if r.effect_name else ""
        extra = "; ".join(x for x in (r.summary, r.note, "" if r.status == "ok" else r.status) if x)
        p_holm = f(r.p_holm) + (" *" if r.significant else "")
        lines.append(f"| {r.id} | {r.description} | {r.subset} | {r.test} | {r.n} | {f(r.statistic)} | {f(r.p)} | "
                     f"{p_holm} | {eff} | {extra.replace('|', '/')} |")
    families = holm_families(df)
    if families:
        lines += ["", f"Holm families (p-values corrected together): {'; '.join(families)}."]
    return "\n".join(lines) + "\n"


def holm_families(df: pd.DataFrame, limit: int = 12) -> list[str]:
    """Each Holm family with the number of tests corrected together and their ids (the first ``limit``)."""
    out = []
    for family, g in df[df["p_holm"].notna()].groupby("family", sort=False):
        ids = ", ".join(g["id"].head(limit)) + (", ..." if len(g) > limit else "")
        out.append(f"{family}: {len(g)} test{'' if len(g) == 1 else 's'} ({ids})")
    return out
