"""Declarative statistics: the ``[[analysis]]`` tables of a study file (``cobot_analysis.study``;
docs/statistics.md has one complete example per test) list the questions of a study.

    study = "pair-carriage-2022"
    alpha = 0.05

    [[analysis]]
    id = "Q1.1"
    description = "Travel time by scenario (forward carriages)"
    source = "durations"            # a table of stats.sources.SOURCE_COLUMNS
    filter = { direction = "forward" }   # column = value or [values]
    value = "duration"              # the tested column
    group = "scenario"              # grouping column (omit for one-sample tests)
    test = "kruskal"                # see stats.tests.TESTS
    family = "Q1"                   # Holm correction across the rows of a family

Optional keys: ``per`` (columns: one test per level, e.g. per entity), ``pairwise`` (every pair
of group levels), ``levels`` (the group levels to use, in order), ``alternative`` (two-sided,
less, greater: "group 1 < group 2" for less), ``normality`` (shapiro | ks) with ``parametric``
(anova | ttest: used instead of the test when every group passes normality), ``paired_by``
(columns aligning the two groups of a wilcoxon test), ``versus`` (x column of a correlation),
``expected`` (chisquare: level -> share), ``chance`` (fisher / binomial: a column holding each
row's chance of success, or a number), ``min_size`` (override the test's minimum group size).

The whole file is validated before anything is computed: a file that is not UTF-8 TOML, values of
the wrong type, unknown keys, sources, columns or tests raise ``InputError`` with one line naming
the question; so does a configuration of another study than the data's (``check_study``).
"""

from __future__ import annotations

import difflib
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cobot_analysis.errors import InputError
from cobot_analysis.schema import as_text
from cobot_analysis.stats.sources import SOURCE_COLUMNS
from cobot_analysis.stats.tests import MIN_SIZE, N_GROUPS, TESTS

ALTERNATIVES = ("two-sided", "less", "greater")
KEYS = {"id", "description", "source", "filter", "value", "group", "test", "family", "per", "pairwise", "levels",
        "alternative", "normality", "parametric", "paired_by", "versus", "expected", "chance", "min_size"}
_TEXT, _NUMBER, _SCALAR = (str,), (int, float), (str, int, float, bool)
#: what each key may hold: a type tuple, or "names" (a string or a list of strings), "scalars" (a value or a list).
TYPES: dict[str, object] = {
    "id": _TEXT + _NUMBER, "description": _TEXT, "source": _TEXT, "value": _TEXT, "group": _TEXT, "test": _TEXT,
    "family": _TEXT + _NUMBER, "per": "names", "pairwise": (bool,), "levels": (list,), "alternative": _TEXT,
    "normality": _TEXT, "parametric": _TEXT, "paired_by": "names", "versus": _TEXT, "expected": (dict,),
    "chance": _TEXT + _NUMBER, "min_size": (int,), "filter": (dict,),
}


def _kind(v) -> str:
    return {bool: "true/false", int: "a number", float: "a number", str: "a string", list: "a list",
            dict: "a table"}.get(type(v), type(v).__name__)


def _type_error(key: str, value) -> str | None:
    """Why ``value`` cannot be the value of ``key`` (None when it can)."""
    want = TYPES[key]
    if want == "names":
        ok = isinstance(value, str) or (isinstance(value, list) and all(isinstance(v, str) for v in value))
        return None if ok else f"{key} must be a column name or a list of them, not {_kind(value)} {value!r}"
    if isinstance(value, bool) and bool not in want:  # TOML true is not a number here
        return f"{key} must be {' or '.join(sorted({_kind(t()) for t in want}))}, not {value!r}"
    if not isinstance(value, want):
        return f"{key} must be {' or '.join(sorted({_kind(t()) for t in want}))}, not {_kind(value)} {value!r}"
    if key == "filter":
        for col, v in value.items():
            values = v if isinstance(v, list) else [v]
            if not values or not all(isinstance(x, _SCALAR) for x in values):
                return f"filter {col} must be a value or a list of values, not {v!r}"
    if key == "expected" and not all(isinstance(v, _NUMBER) and not isinstance(v, bool) for v in value.values()):
        return f"expected must map each category to a number, not {value!r}"
    if key == "min_size" and value < 1:
        return f"min_size must be >= 1, not {value}"
    return None


@dataclass
class Analysis:
    id: str
    description: str
    source: str
    value: str
    test: str
    family: str
    group: str | None = None
    filter: dict[str, Any] = field(default_factory=dict)
    per: list[str] = field(default_factory=list)
    pairwise: bool = False
    levels: list | None = None
    alternative: str = "two-sided"
    normality: str | None = None
    parametric: str | None = None
    paired_by: list[str] = field(default_factory=list)
    versus: str | None = None
    expected: dict | None = None
    chance: str | float | None = None
    min_size: int | None = None

    @property
    def columns(self) -> list[str]:
        cols = [self.value, *self.filter, *self.per, *self.paired_by]
        cols += [c for c in (self.group, self.versus) if c]
        if isinstance(self.chance, str):
            cols.append(self.chance)
        return cols

    @property
    def minimum(self) -> int:
        return self.min_size if self.min_size is not None else MIN_SIZE[self.test]


@dataclass
class StudyConfig:
    study: str
    alpha: float
    analyses: list[Analysis]
    path: Path | None = None


def parse(data: dict, path: Path | None = None, require: bool = True) -> StudyConfig:
    """Validate a parsed TOML document (see module doc) -> ``StudyConfig``; ``require``: at least one
    ``[[analysis]]`` (a study file, ``cobot_analysis.study``, may have none)."""
    def fail(msg: str, remedy: str = "fix the stats configuration") -> InputError:
        return InputError(msg, path=path, remedy=remedy)

    if not isinstance(data.get("analysis", []), list) or (require and not data.get("analysis")):
        raise fail("no [[analysis]] entries", "declare at least one [[analysis]] table (docs/statistics.md)")
    alpha = data.get("alpha", 0.05)
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float)):
        raise fail(f"alpha must be a number, not {_kind(alpha)} {alpha!r}", "e.g. alpha = 0.05")
    if not 0 < alpha < 1:
        raise fail(f"alpha must be in (0, 1), got {alpha}", "e.g. alpha = 0.05")
    if not isinstance(data.get("study", ""), str):
        raise fail(f"study must be a string, not {data['study']!r}", 'e.g. study = "walking-2020"')
    alpha = float(alpha)
    out, seen = [], set()
    for n, raw in enumerate(data.get("analysis", []), 1):
        if not isinstance(raw, dict):
            raise fail(f"analysis #{n} is not a table", "declare each analysis as an [[analysis]] table")
        qid = str(raw.get("id", f"#{n}"))
        unknown = set(raw) - KEYS
        if unknown:
            raise fail(f"analysis {qid}: unknown key(s) {sorted(unknown)}", f"use only {sorted(KEYS)}")
        for key, value in raw.items():
            problem = _type_error(key, value)
            if problem:
                raise fail(f"analysis {qid}: {problem}")
        for key in ("id", "source", "value", "test", "family"):
            if key not in raw:
                raise fail(f"analysis {qid}: missing key {key!r}")
        if qid in seen:
            raise fail(f"analysis {qid}: duplicate id")
        seen.add(qid)
        if raw["source"] not in SOURCE_COLUMNS:
            raise fail(f"analysis {qid}: unknown source {raw['source']!r}", f"use one of {sorted(SOURCE_COLUMNS)}")
        for key in ("test", "parametric"):
            if key in raw and raw[key] not in TESTS:
                raise fail(f"analysis {qid}: unknown test {raw[key]!r}", f"use one of {list(TESTS)}")
        per = raw.get("per", [])
        paired = raw.get("paired_by", [])
        a = Analysis(id=qid, description=str(raw.get("description", "")), source=raw["source"], value=raw["value"],
                     test=raw["test"], family=str(raw["family"]), group=raw.get("group"), filter=dict(raw.get("filter", {})),
                     per=[per] if isinstance(per, str) else list(per), pairwise=bool(raw.get("pairwise", False)),
                     levels=raw.get("levels"), alternative=raw.get("alternative", "two-sided"),
                     normality=raw.get("normality"), parametric=raw.get("parametric"),
                     paired_by=[paired] if isinstance(paired, str) else list(paired), versus=raw.get("versus"),
                     expected=raw.get("expected"), chance=raw.get("chance"), min_size=raw.get("min_size"))
        if a.alternative not in ALTERNATIVES:
            raise fail(f"analysis {qid}: unknown alternative {a.alternative!r}", f"use one of {list(ALTERNATIVES)}")
        if a.normality not in (None, "shapiro", "ks"):
            raise fail(f"analysis {qid}: unknown normality test {a.normality!r}", "use shapiro or ks")
        bad = [c for c in a.columns if c not in SOURCE_COLUMNS[a.source]]
        if bad:
            raise fail(f"analysis {qid}: unknown column(s) {bad} in source {a.source!r}",
                       f"columns of {a.source}: {', '.join(SOURCE_COLUMNS[a.source])}")
        lo, hi = N_GROUPS[a.test]
        if a.test in ("pearson", "spearman") and not a.versus:
            raise fail(f"analysis {qid}: {a.test} needs 'versus' (the x column)")
        if lo >= 2 and not a.group:
            raise fail(f"analysis {qid}: {a.test} compares groups and needs 'group'")
        if hi == 2 and not a.pairwise and a.levels is not None and len(a.levels) != 2:
            raise fail(f"analysis {qid}: {a.test} compares exactly two groups; give two 'levels' or pairwise = true")
        if a.alternative != "two-sided" and (lo, hi) == (2, 2) and a.levels is None:  # else group 1 is the first in sort order
            sign = "<" if a.alternative == "less" else ">"
            raise fail(f"analysis {qid}: one-sided ({a.alternative}: group 1 {sign} group 2) needs levels = [group 1, group 2]",
                       'name the two levels in that order, e.g. levels = ["model", "individual-mean"]')
        if a.test == "wilcoxon" and not a.paired_by:
            raise fail(f"analysis {qid}: wilcoxon is paired and needs 'paired_by'")
        out.append(a)
    return StudyConfig(str(data.get("study", "")), alpha, out, path)


def load(path: str | Path) -> StudyConfig:
    """Read and validate ``pipelines/<study>.toml``."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise InputError("stats configuration not found", path=path, remedy="pass --config pipelines/<study>.toml") from None
    except OSError as exc:
        raise InputError(f"cannot read the stats configuration ({exc.strerror or type(exc).__name__})", path=path,
                         remedy="pass a TOML file, e.g. --config pipelines/walking-2020.toml") from None
    except UnicodeDecodeError:
        raise InputError("not a text file (a stats configuration is UTF-8 TOML)", path=path,
                         remedy="pass a TOML file, e.g. --config pipelines/walking-2020.toml") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML ({exc})", path=path, remedy="fix the syntax") from None
    return parse(data, path)


def check_study(config: StudyConfig, study: str) -> None:
    """The data must be of the configuration's study (a configuration without ``study`` is not checked)."""
    if config.study and config.study != study:
        raise InputError(f"configuration for study {config.study!r}, but the trajectories are of study {study!r}",
                         path=config.path, remedy=f'pass the study file of the data\'s study, or set study = "{study}" in this one')


def filter_problems(config: StudyConfig, sources: dict) -> list[str]:
    """Filter values that match no row of their whole source column (a typo, or data not there yet),
    with the values that exist: one text per analysis and column."""
    out = []
    for a in config.analyses:
        df = sources[a.source]
        for col, wanted in a.filter.items():
            present = df[col].dropna()
            if len(present) and not match(df[col], wanted).any():
                out.append(f"{a.id}: {col} = {wanted!r} (values of {a.source}.{col}: {values_text(present)})")
    return out


#: comparisons ``compare`` writes by itself; any other value of ``comparison`` comes from
#: ``compare --against TABLE --comparison NAME`` (e.g. model rows, after a model stage).
OWN_COMPARISONS = ("individual-mean", "any-any", "symmetry", "symmetry-mean", "scenario-scenario",
                   "scenario-scenario-mean", "mean-published")


def awaited(config: StudyConfig, sources: dict) -> tuple[list[str], dict[str, list[str]]]:
    """``filter_problems`` split into the unexpected ones (a typo: to warn about) and the questions
    whose rows these data cannot have yet, by why: ``comparison = "model"`` before
    ``compare --against TABLE --comparison model``, ``"mean-published"`` without published means; a value
    close to one of ``OWN_COMPARISONS`` ("individual-maen") is a typo.
    Returns (unexpected texts, {why: [question ids]})."""
    wait: dict[str, list[str]] = {}
    other = []
    for a in config.analyses:
        for text in filter_problems(StudyConfig(config.study, config.alpha, [a]), sources):
            wanted = a.filter.get("comparison") if text.startswith(f"{a.id}: comparison = ") else None
            names = [str(v) for v in (wanted if isinstance(wanted, list) else [wanted])] if wanted is not None else []
            typo = [n for n in names if n not in OWN_COMPARISONS and difflib.get_close_matches(n, OWN_COMPARISONS, 1, 0.8)]
            if names and not typo and all(n == "mean-published" or n not in OWN_COMPARISONS for n in names):
                why = ("the data hold no published means to compare ours with" if names == ["mean-published"] else
                       f"no {'/'.join(names)} rows yet (`compare --against TABLE --comparison {names[0]}` adds them)")
                wait.setdefault(why, []).append(a.id)
            else:
                other.append(text)
    return other, wait


def values_text(series, limit: int = 12) -> str:
    vals = sorted({as_text(v) for v in series})
    return ", ".join(vals[:limit]) + (f", ... ({len(vals)} values)" if len(vals) > limit else "")


def match(series, wanted):
    """Rows whose value is ``wanted`` (or in the list ``wanted``); numbers compare as numbers."""
    import pandas as pd

    values = wanted if isinstance(wanted, list) else [wanted]
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return pd.to_numeric(series, errors="coerce").isin([float(v) for v in values])
    if all(isinstance(v, bool) for v in values):
        return series.isin(values)
    return series.astype(str).isin([str(v) for v in values])


def check_levels(config: StudyConfig, sources: dict) -> None:
    """Second validation step, once the sources exist but before any test: the declared group
    levels must occur in the analysis' subset when that subset has data (an empty subset is
    reported as skipped instead: the data do not support the question)."""
    for a in config.analyses:
        df = sources[a.source]
        for col, wanted in a.filter.items():
            df = df[match(df[col], wanted)]
        if df.empty:
            continue
        if a.group and a.levels is not None:
            present = sorted({str(v) for v in df[a.group].dropna().unique()})
            wanted = a.filter.get(a.group, [])
            expected = {str(v) for v in (wanted if isinstance(wanted, list) else [wanted])}
            # a level also named in the filter is declared data that may be absent (e.g. model rows
            # before a model was compared), and so is a level the source holds outside this subset (e.g.
            # forward trials whose means had one trial each, not compared with them): their tests are
            # skipped with the reason instead; a level found nowhere is a typo
            whole = sources[a.source][a.group] if a.group in sources[a.source] else df[a.group]
            absent = [lv for lv in a.levels if not match(df[a.group], lv).any() and str(lv) not in expected
                      and not match(whole, lv).any()]
            if absent:
                raise InputError(f"analysis {a.id}: group level(s) {absent} not found in column {a.group!r} "
                                 f"(found {present})", path=config.path, remedy="fix 'levels'")
