"""The analyses of a study's trajectories (docs/methods.md sec. 2.9, 3, 4, 8): mean trajectories,
distances between trajectories, the statistics of the study's questions, and the subjects
reconstructed from the table. Each function takes the documented trajectories table (a DataFrame
as ``schema.TRAJECTORIES`` / ``averaging.MEANS`` describe, or the path of such a Parquet file) and
returns a result holding its tables; nothing is written."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from cobot_analysis import registry
from cobot_analysis.compare import TrajectorySet
from cobot_analysis.errors import InputError
from cobot_analysis.metrics import analysis as headline
from cobot_analysis.metrics.records import Metrics, collect

Trajectories = "pd.DataFrame | str | os.PathLike | TrajectorySet"


def trajectory_set(table: Any, what: tuple[str, ...] = ("trajectories", "means", "generated_trajectories")) -> TrajectorySet:
    """A trajectories table (DataFrame, or the path of a Parquet file a stage wrote) as a ``TrajectorySet``
    (one row of metadata and N samples of x, y, theta, gamma per trajectory); ``what``: the tables a path
    may hold. A DataFrame of your own is checked as a file is: its ``kind`` values (``trial``, ``mean``, ``model``)
    and its positions in metres (within the lab's ``io.plausibility.LAB_EXTENT``, 100 m: not millimetres).

        >>> from cobot_analysis.api import trajectory_set
        >>> from cobot_analysis.synth.tables import walking_table
        >>> ts = trajectory_set(walking_table(n_subjects=2, n_conditions=1, n_trials=1))
        >>> len(ts), ts.n_samples, ts.x.shape
        (2, 40, (2, 40))
        >>> walk = walking_table(n_subjects=1, n_conditions=1, n_trials=1)
        >>> trajectory_set(walk.drop(columns="kind"))
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: trajectory table lacks column 'kind'; add it: 'trial' for a recording, 'mean' for a mean trajectory (docs/schemas.md, trajectories)
        >>> trajectory_set(walk.assign(kind="recording"))
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: trajectory table has kind 'recording'; use 'trial' for a recording, 'mean' for a mean trajectory, 'model' for a generated path (docs/schemas.md, trajectories)
        >>> trajectory_set(walk.assign(x=1000 * walk["x"], y=1000 * walk["y"]))
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: column 'y': 35 value(s) outside [-100, 100] m (e.g. -900; millimetres?); give y in m (lengths in metres, not millimetres; NaN for an unknown value), or re-run the stage that wrote it
        >>> trajectory_set([walk])
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: trajectories must be a DataFrame or the path of a Parquet file, not a list; pass the table (docs/api.md, "The one input type")
    """
    from cobot_analysis.api.options import table_of
    from cobot_analysis.compare import pivot, read_trajectory_set
    import pyarrow as pa

    from cobot_analysis.schema import TRAJECTORIES, check_values

    if isinstance(table, TrajectorySet):
        return table
    table = table_of(table, "trajectories", "trajectories", "means", "generated")
    if isinstance(table, pd.DataFrame):
        if "kind" not in table.columns:  # every analysis selects on it (a file a stage wrote always has it)
            raise InputError("trajectory table lacks column 'kind'",
                             remedy="add it: 'trial' for a recording, 'mean' for a mean trajectory (docs/schemas.md, trajectories)")
        kinds = sorted(set(table["kind"].dropna().astype(str)) - {"trial", "mean", "model"})
        if kinds:  # else the analyses select nothing: a silent empty result
            raise InputError(f"trajectory table has kind {', '.join(map(repr, kinds))}",
                             remedy="use 'trial' for a recording, 'mean' for a mean trajectory, 'model' for a generated path "
                                    "(docs/schemas.md, trajectories)")
        # the checks of a table read from a file (schema.check_values: numbers, no +-inf, positions within the lab, so
        # not millimetres, wrapped angles within pi and measured headings within schema.TURNS turns, so not degrees; a
        # model's path may turn any number of times: generated paths are checked as generate's table)
        from cobot_analysis.models.outputs import GENERATED

        schema = GENERATED if table["kind"].eq("model").any() else TRAJECTORIES
        check_values(pa.Table.from_pandas(table[[c for c in table.columns if c in TRAJECTORIES.columns]], preserve_index=False),
                     schema)
        return pivot(table)
    return read_trajectory_set(Path(table), what)


def study_of(ts: Any) -> str:
    """The study of a set, or of a trajectories table (as ``trajectory_set`` takes it; ``a+b`` when it mixes studies).

        >>> from cobot_analysis.api import study_of, trajectory_set
        >>> from cobot_analysis.synth.tables import walking_table
        >>> walk = walking_table(n_subjects=1, n_conditions=1, n_trials=1)
        >>> study_of(trajectory_set(walk)), study_of(walk)
        ('synthetic-walking', 'synthetic-walking')
    """
    if not isinstance(ts, TrajectorySet):  # a DataFrame was an AttributeError ('DataFrame' object has no attribute 'meta')
        ts = trajectory_set(ts)
    studies = sorted(ts.meta["study"].dropna().astype(str).unique())
    return studies[0] if len(studies) == 1 else "+".join(studies)


def check_by(by: str | list[str] | None, columns, path=None, option: str = "--by") -> list[str] | None:
    """The grouping columns asked for (``--by``; ``option``: the option named in messages), a list or one
    comma-separated string, refused when one is not a column of the trajectories.

        >>> from cobot_analysis.api import check_by
        >>> check_by(["condition"], ["trial", "condition"]), check_by("condition", ["trial", "condition"])
        (['condition'], ['condition'])
        >>> check_by(["speed"], ["trial", "condition"])
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --by names unknown column(s) ['speed']; use columns of the trajectories: trial, condition
    """
    from cobot_analysis.api.options import name_list

    by = name_list(by, option, example="condition,entity")
    if not by:
        return None
    bad = [c for c in by if c not in columns]
    if bad:
        raise InputError(f"{option} names unknown column(s) {bad}", path=path, remedy=f"use columns of the trajectories: {', '.join(columns)}")
    return by


# ---- average ------------------------------------------------------------------------------------
@dataclass
class AverageResult:
    """Mean trajectories (``averaging.MEANS``): one per group, with counts, sd and the 95 % band."""

    means: pd.DataFrame
    groups: list[str]
    source: str  # how the means were made
    study: str
    n_averaged: int  # trajectories averaged (0: published means carried over)
    truncated: int = 0  # of them, flagged truncated
    spread: list[str] = field(default_factory=list)  # means whose trials do not share a frame (flagged frames_differ)
    unequal: tuple[int, str, int, int] = (0, "", 0, 0)  # means whose subjects or pairs weigh unequally (averaging.unequal_units)
    weigh: str = "trials"  # each trajectory alike, or each subject (pair) alike: the mean of their means (averaging.WEIGHTS)
    units: tuple[str, int, int, int, int] = ("", 0, 0, 0, 0)  # weigh="subjects": unit column, fewest/most units per mean, fewest/most trajectories per unit

    def summary(self) -> str:
        return f"{self.means.drop_duplicates(['trial', 'entity']).shape[0]} means"

    def metrics(self, *, stage: str = "average") -> Metrics:
        """Headline numbers (``metrics.analysis.average``): means and trials behind them per entity, spread; the
        numbers the ``average`` stage writes to ``metrics.json``.

            >>> from cobot_analysis.api import average
            >>> from cobot_analysis.synth.tables import walking_table
            >>> numbers = average(walking_table(n_subjects=3, n_conditions=2, n_trials=2)).metrics()
            >>> numbers.stage, numbers.study, numbers[0]
            ('average', 'synthetic-walking', Metric(name='average.means', value=2, unit='count', stage='average', convention=None))
            >>> numbers.as_dict()["average.walker.trials"]   # 3 subjects x 2 trials behind each of the 2 means
            12
        """
        return collect(stage, headline.average, self.means)

    def figures(self) -> dict[str, Any]:
        """Matplotlib figures by name (``fig.savefig(...)`` writes one): ``means``, one panel per mean (every entity
        of it; titled by its groups' values, e.g. the condition) with orientation arrows (``reports.figures.paths``).

            >>> from cobot_analysis.api import average
            >>> from cobot_analysis.synth.tables import walking_table
            >>> figures = average(walking_table(n_subjects=2, n_conditions=2, n_trials=1)).figures()
            >>> [(name, type(fig).__name__, [ax.get_title() for ax in fig.axes]) for name, fig in figures.items()]
            [('means', 'Figure', ['E1500', 'N1500'])]
        """
        from cobot_analysis.reports.figures import paths

        keys = [k for k in self.groups if k in self.means and k not in ("study", "entity")]
        panels = []
        for _, t in self.means.sort_values("sample").groupby(keys or ["trial"], sort=True, dropna=False):
            values = [t[k].iloc[0] for k in keys if t[k].notna().any()]
            title = " ".join(f"{v:.3g}" if isinstance(v, float) else str(v) for v in values) or str(t["trial"].iloc[0])
            panels.append({"title": title, "means": [
                (g["x"].to_numpy(), g["y"].to_numpy(), g["theta"].to_numpy() if g["theta"].notna().any() else None, entity)
                for entity, g in t.groupby("entity", sort=True)]})
        return {"means": paths(panels, title=f"{self.study}: mean trajectories")}


def average(trajectories: Any, *, by: str | list[str] | None = None, max_spread: float | None = None,
            weigh: str = "trials") -> AverageResult:
    """Mean trajectory per condition (sample-wise mean of positions; circular mean of angles, trajectories
    without orientation left out of the angle means only), with counts, sd and the 95 % band
    (docs/methods.md sec. 2.9). ``by``: grouping columns (default: the study's design,
    ``compare.default_groups``; a list, or one comma-separated string). A grouping column missing for some
    trials is refused (the means would pool unrelated trials). ``max_spread`` (m, default 1): a mean whose
    trials' start or end points spread more is flagged ``frames_differ``. ``weigh``: ``trials`` (default, the
    published method) weighs every trajectory alike; ``subjects`` takes the mean of each subject's mean (the pair's,
    in the pair study) with the sd between them, so a subject with more trials in a condition weighs no more
    (``averaging.mean_trajectories``). A table holding only published means (pair-carriage-2022) is carried over.

        >>> from cobot_analysis.api import average
        >>> from cobot_analysis.synth.tables import walking_table
        >>> result = average(walking_table(n_subjects=3, n_conditions=2, n_trials=2))
        >>> result.groups, result.n_averaged
        (['study', 'condition', 'entity'], 12)
        >>> print(result.means.drop_duplicates("trial")[["condition", "n_trials"]].to_string(index=False))
        condition  n_trials
            E1500         6
            N1500         6
    """
    from cobot_analysis.api.options import at_least, one_of, table_of
    from cobot_analysis.averaging import (MAX_FRAME_SPREAD, MEANS, WEIGHTS, check_groups, check_units, mean_trajectories,
                                          spread_warnings, unequal_units, unit_counts)
    from cobot_analysis.compare import default_groups
    from cobot_analysis.schema import TRAJECTORIES, read_table

    at_least(max_spread, "--max-spread", strict=False, example="1.0")
    one_of(weigh, "--weigh", WEIGHTS)
    trajectories = table_of(trajectories, "trajectories", "trajectories") if not isinstance(trajectories, TrajectorySet) else trajectories
    ts = trajectory_set(trajectories, ("trajectories",))
    path = None if isinstance(trajectories, (pd.DataFrame, TrajectorySet)) else Path(trajectories)
    groups = check_by(by, list(ts.meta.columns), path) or default_groups(ts.meta)
    trials = ts.subset(ts.meta["kind"].eq("trial").to_numpy())
    if len(trials):
        check_groups(trials.meta, groups, path)
        units = unit_counts(trials, groups, check_units(trials.meta, groups, path)) if weigh == "subjects" else ("", 0, 0, 0, 0)
        spread = MAX_FRAME_SPREAD if max_spread is None else max_spread
        means = mean_trajectories(trials, groups, max_spread=spread, weigh=weigh)
        cut = 0
        if "quality" in trials.meta.columns:
            cut = int(trials.meta["quality"].fillna("").str.split(";").map(lambda f: "truncated" in f).sum())
        return AverageResult(means, groups, f"recomputed from {len(trials)} trajectories", study_of(ts), len(trials), cut,
                             spread_warnings(trials, groups, spread), unequal_units(trials, groups), weigh, units)
    if weigh != "trials":
        raise InputError("--weigh subjects: the table holds no per-trial trajectories, only published means, carried over as they are",
                         path=path, remedy="omit --weigh (the published means had one trajectory per subject)")
    long = trajectories.copy() if isinstance(trajectories, pd.DataFrame) else read_table(path, TRAJECTORIES)
    long.attrs = {}
    means = long[long["kind"].eq("mean")].copy()
    means["n_theta"] = np.where(means.groupby(["study", "trial", "entity"])["theta"].transform(lambda v: v.notna().all()),
                                means["n_trials"], 0)
    for c in MEANS.columns:
        if c not in means.columns:
            means[c] = np.nan
    return AverageResult(means, groups, "published means carried over (no per-trial data)", study_of(ts), 0)


# ---- compare ------------------------------------------------------------------------------------
@dataclass
class CompareResult:
    """Distances between trajectories (``compare.DISTANCES``): one row per compared pair."""

    distances: pd.DataFrame
    groups: list[str]
    convention: str
    excluded: dict = field(default_factory=dict)  # trials not compared with their mean, by reason (compare.excluded_means)

    def summary(self) -> str:
        """The count of compared pairs, and of the trials left out of the comparison with their mean, by reason."""
        from cobot_analysis.compare import EXCLUDED_REASONS

        left = [f"{n} trial(s) {EXCLUDED_REASONS[k]}" for k, n in self.excluded.items() if n and k in EXCLUDED_REASONS]
        return f"{len(self.distances)} compared pairs" + (f"; not compared with their mean: {', '.join(left)}" if left else "")

    def metrics(self, *, stage: str | None = None) -> Metrics:
        """Headline numbers (``metrics.analysis.compare``): d_xy, d_theta, d_gamma mean and sd per comparison
        and entity; ``stage`` defaults to ``compare`` (``compare-published`` under the published convention).

            >>> from cobot_analysis.api import average, compare
            >>> from cobot_analysis.synth.tables import walking_table
            >>> walks = walking_table(n_subjects=3, n_conditions=2, n_trials=2)
            >>> numbers = compare(walks, average(walks).means, convention="published").metrics()
            >>> numbers.stage, numbers.convention, numbers.as_dict()["compare.individual-mean.walker.n"]
            ('compare-published', 'published', 12)
        """
        return collect(stage or registry.directory("compare", self.convention), headline.compare, self.distances)

    def figures(self) -> dict[str, Any]:
        """Matplotlib figures by name: ``d_xy``, ``d_theta``, ``d_gamma``, box plots of each distance per
        comparison and entity (``reports.figures.boxplots``; a distance with no finite value is left out)."""
        from cobot_analysis.reports.figures import boxplots

        figs = {}
        for d, unit in (("d_xy", "m"), ("d_theta", "rad"), ("d_gamma", "rad")):
            if d in self.distances and self.distances[d].notna().any():
                groups = {f"{c}\n{e}": g[d] for (c, e), g in self.distances.groupby(["comparison", "entity"], sort=True)}
                figs[d] = boxplots(groups, f"{d} ({unit})", f"{d} per comparison ({self.convention} convention)",
                                   xlabel="comparison, entity")
        return figs


def compare(trajectories: Any, means: Any, *, against: Any = None, comparison: str = "against",
            any_vs_any: str | list[str] | None = None, by: str | list[str] | None = None,
            convention: str = "continuous") -> CompareResult:
    """Distances d_xy, d_theta, d_gamma (docs/methods.md sec. 3): every trial vs the mean of its group,
    between scenarios, forward vs reversed return, recomputed vs published means, ``against`` (e.g. model
    paths, ``kind == "model"``) vs the means of the same group, and every two trials that agree on
    ``any_vs_any``. ``convention``: ``continuous`` (pointwise on time-normalised samples) or ``published``
    (arc-length resampling first, the authors' scripts; docs/methods.md sec. 11).

        >>> from cobot_analysis.api import average, compare
        >>> from cobot_analysis.synth.tables import walking_table
        >>> walks = walking_table(n_subjects=3, n_conditions=2, n_trials=2)
        >>> d = compare(walks, average(walks).means).distances
        >>> d["comparison"].unique().tolist(), len(d)
        (['individual-mean'], 12)

    Model paths (``generate``, under the comparison's convention) against the means of their condition:

        >>> from cobot_analysis.api import generate, walking_cases
        >>> cases = [c for c in walking_cases("continuous") if c[0] in ("N1500", "E1500")]
        >>> paths = generate("clothoid", cases=cases, study="synthetic-walking", jobs=1).generated
        >>> m = compare(walks, average(walks).means, against=paths, comparison="model").distances.query("comparison == 'model'")
        >>> sorted(m["condition"]), bool(m["d_xy"].between(0.0, 0.5).all())
        (['E1500', 'N1500'], True)
    """
    from cobot_analysis import conventions
    from cobot_analysis.api.options import table_of
    from cobot_analysis.compare import WALKING_GROUPS, against_set, against_vs_mean, any_vs_any as any_any, compare_sets
    from cobot_analysis.compare import default_groups, excluded_means
    from cobot_analysis.models.outputs import GENERATED
    from cobot_analysis.schema import table_metadata

    conv = conventions.get(convention)
    if not isinstance(means, TrajectorySet):
        means = table_of(means, "means", "means")
    if against is not None and not isinstance(against, TrajectorySet):
        against = table_of(against, "against", "generated")
    ts = trajectory_set(trajectories, ("trajectories",))
    mts = trajectory_set(means, ("means",))
    stored = table_metadata(Path(means)).get("grouping") if not isinstance(means, (pd.DataFrame, TrajectorySet)) else None
    groups = check_by(by, list(ts.meta.columns)) or stored or default_groups(ts.meta)
    same = check_by(any_vs_any, list(ts.meta.columns), option="--any-vs-any")
    if mts.n_samples != ts.n_samples:
        raise InputError(f"the means have {mts.n_samples} samples per trajectory, the trajectories {ts.n_samples}",
                         remedy="average the same trajectories (preprocess --samples gives every trajectory the same N)")
    other = None
    if against is not None:
        if isinstance(against, TrajectorySet):
            raise InputError("--against must be a trajectory table (generate's generated table, or its Parquet file)",
                             remedy="pass the DataFrame or the Parquet file that generate wrote")
        if isinstance(against, pd.DataFrame):  # against_set reads a file: the table goes through a temporary one
            import tempfile

            against_name = "the against table"  # its name in messages
            with tempfile.TemporaryDirectory() as tmp:
                file = Path(tmp) / "against.parquet"
                table = against.copy()
                table.attrs = {}
                table.to_parquet(file)
                try:
                    other = against_set(file, mts.n_samples, conv, GENERATED, name=against_name)
                except InputError as exc:
                    raise InputError(str(exc).replace(str(file), against_name)) from None
            against = against_name
        else:
            other = against_set(Path(against), mts.n_samples, conv, GENERATED)
    if (ts.meta["kind"] == "model").all():
        raise InputError("the trajectories are generated paths (kind = model), not trials",
                         remedy="pass the model paths as `against` (compare --against generated.parquet) and the measured "
                                "trajectories as `trajectories`")
    ts, mts = ts.compared_as(conv.comparison), mts.compared_as(conv.comparison)
    if other is not None:
        other.angle_difference = conv.comparison.angle_difference
    trials = ts.subset(ts.meta["kind"].eq("trial").to_numpy())
    parts = [compare_sets(trials, mts, by=groups)]
    published = ts.subset(ts.meta["kind"].eq("mean").to_numpy())
    if len(published) and len(trials):  # our means vs the authors' means of the same condition
        keys = [c for c in groups if c in WALKING_GROUPS or c in ("direction", "scenario", "end_orientation")]
        parts.append(any_any(mts, same=keys, comparison="mean-published", other=published))
    if same:
        parts.append(any_any(trials, same=["study", *same]))
    if other is not None:
        parts.append(against_vs_mean(other, mts, groups, comparison, against))
    d = pd.concat([p for p in parts if len(p)] or parts[:1], ignore_index=True)
    d["convention"] = conv.name
    return CompareResult(d, groups, conv.name, excluded_means(trials, mts, groups) if len(trials) else {})


# ---- statistics ---------------------------------------------------------------------------------
@dataclass
class StatisticsResult:
    """One row per question of the configuration (``stats.analyses.STATS``): test, n, statistic, p, Holm p,
    effect size, or why it was skipped."""

    table: pd.DataFrame
    config: Any
    config_path: Path | None
    study: str
    unmatched: list[str] = field(default_factory=list)  # filter values that match no row (a typo?)
    waiting: dict = field(default_factory=dict)  # why -> questions whose rows these data cannot have yet
    declared: bool = True  # False: no questions declared, the default descriptive ones (cobot_analysis.study)

    def summary(self) -> str:
        """"T tests run (and S descriptive summaries), K skipped ...": a ``describe`` row is no test (no p)."""
        ok = self.table["status"].eq("ok")
        described = int((ok & self.table["test"].eq("describe")).sum())
        also = f" (and {described} descriptive summar{'y' if described == 1 else 'ies'})" if described else ""
        tests = int(ok.sum()) - described
        return (f"{tests} test{'' if tests == 1 else 's'} run{also}, {int((~ok).sum())} skipped (reason in the table); "
                f"{int(self.table['significant'].sum())} significant after Holm within each family.")

    def metrics(self, *, stage: str = "stats") -> Metrics:
        """Headline numbers (``metrics.analysis.statistics``): per question the test, n, statistic, p, Holm p,
        effect size, or why it was skipped (``stage``: ``stats-published`` for the published convention's)."""
        return collect(stage, headline.statistics, self.table)


def statistics(trajectories: Any, distances: pd.DataFrame | str | os.PathLike, *, config: Any = None,
               durations: Any = None, anthropometrics: Any = None, progress=None) -> StatisticsResult:
    """Every statistical question of a study (Kruskal-Wallis, Mann-Whitney, Fisher, ANOVA, Pearson, ...,
    with effect sizes and Holm correction within each family; docs/methods.md sec. 4). ``config``: a study
    file (``cobot_analysis.study``, docs/statistics.md) as a path, the same document as a dict, a loaded
    ``Study`` or ``StudyConfig``; None or a file without questions: the default descriptive questions (each
    distance and travel time by each factor, and the tests the design allows). ``distances``: the table of
    ``compare``; ``durations`` (published pair study: ``import_published(...).durations``, or its
    durations.parquet) and ``anthropometrics`` (as ``--anthropometrics``: the directory of subjects.csv (id,
    weight, height) and pairs.csv (id, subject1, subject2), or its table per pair: pair, weight_diff,
    height_diff, ``stats.sources.read_anthropometrics``) feed the questions that use them.

        >>> from cobot_analysis.api import average, compare, statistics
        >>> from cobot_analysis.synth.tables import walking_table
        >>> walks = walking_table(n_subjects=3, n_conditions=2, n_trials=3, subject_effect=0.2)
        >>> distances = compare(walks, average(walks).means).distances
        >>> question = {"id": "W1.1", "description": "d_xy across subjects", "source": "distances",
        ...             "filter": {"comparison": "individual-mean"}, "value": "d_xy", "group": "subject",
        ...             "test": "kruskal", "family": "study"}
        >>> result = statistics(walks, distances, config={"study": "synthetic-walking", "analysis": [question]})
        >>> row = result.table.iloc[0]
        >>> row["test"], int(row["n"]), row["levels"], bool(row["p"] < 0.05)   # the planted subject effect
        ('kruskal', 18, 'S01, S02, S03', True)
        >>> statistics(walks, distances, config={"study": "walking-2020", "analysis": [question]})
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: study file of study 'walking-2020', but the trajectories are of study 'synthetic-walking'; set study = "synthetic-walking" in it, or pass the study file of the data
        >>> statistics(walks, walks)   # the trajectories passed as the distances
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: the distances table lacks column(s) ['comparison', 'global_distance', 'd_xy']; pass the distances of compare (compare(...).distances, or compare/distances.parquet)
    """
    from cobot_analysis import study as st
    from cobot_analysis.stats import analyses
    from cobot_analysis.stats import config as cfg
    from cobot_analysis.stats.sources import build_sources

    if isinstance(config, dict):
        config = st.parse(config)  # a document in memory: its messages name no file
    ts = trajectory_set(trajectories, ("trajectories",))
    name = study_of(ts)
    path = None
    if isinstance(config, cfg.StudyConfig):
        cfg.check_study(config, name)
        study = st.Study(name, name, [], [], config, config.path, config.alpha)
    elif isinstance(config, st.Study):  # a dict or a loaded study file: of the data's study, as a path is checked
        if config.name and config.name != name:
            raise InputError(f"study file of study {config.name!r}, but the trajectories are of study {name!r}", path=config.path,
                             remedy=f'set study = "{name}" in it, or pass the study file of the data')
        study = config
    else:
        study = st.resolve(Path("."), name, Path(config)) if config is not None else st.Study(name, name, [], [], None)
    path = study.path
    distances = distances_table(distances)
    durations, anthropometrics = _durations(durations), _anthropometrics(anthropometrics)
    sources = build_sources(ts, distances, durations, anthropometrics, study.alpha)
    questions = st.questions(study, sources)
    cfg.check_levels(questions, sources)
    unmatched, waiting = cfg.awaited(questions, sources)
    table = analyses.run(questions, sources, progress=progress)
    table["study"] = name
    return StatisticsResult(table, questions, path, name, list(unmatched), waiting, study.declared)


def distances_table(distances: Any) -> pd.DataFrame:
    """The distances of ``compare`` (a DataFrame, ``compare``'s result, or the path of its distances.parquet) as
    ``statistics`` reads them: refused when a column it needs is missing, or when they hold no row and ``compare``
    did not say why (its result's ``excluded``, recorded in the file: every trial left out, e.g. means whose trials
    do not share a frame); else every distance question would be skipped on a table that lost its rows.

        >>> from cobot_analysis.api import average, compare, distances_table
        >>> from cobot_analysis.synth.tables import walking_table
        >>> walks = walking_table(n_subjects=2, n_conditions=1, n_trials=1)
        >>> result = compare(walks, average(walks).means)
        >>> len(distances_table(result.distances)), len(distances_table(result))
        (2, 2)
        >>> distances_table(result.distances.iloc[:0])
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: the distances table has no rows and does not say why; re-run compare on these trajectories and their means (cobot-analysis compare --force with the same --out) and pass what it writes
    """
    from cobot_analysis.api.options import table_of
    from cobot_analysis.compare import DISTANCES
    from cobot_analysis.schema import read_table

    excluded = getattr(distances, "excluded", None)  # compare's result: the trials it left out, by reason
    distances = table_of(distances, "distances", "distances")
    path = None
    if not isinstance(distances, pd.DataFrame):
        path = Path(distances)
        distances = read_table(path, DISTANCES)
        excluded = distances.attrs["cobot_analysis"].get("excluded")
    missing = [c for c in ("comparison", "trial", "entity", "global_distance", "d_xy") if c not in distances.columns]
    if missing:
        raise InputError(f"the distances table lacks column(s) {missing}", path=path,
                         remedy="pass the distances of compare (compare(...).distances, or compare/distances.parquet)")
    if distances.empty and not any((excluded or {}).values()):
        raise InputError("the distances table has no rows and does not say why", path=path,
                         remedy="re-run compare on these trajectories and their means (cobot-analysis compare --force with "
                                "the same --out) and pass what it writes")
    distances = distances.copy()
    distances.attrs = {}
    return distances


def _durations(durations: Any) -> pd.DataFrame | None:
    """The published pair study's durations: a DataFrame, the import's result, or its durations.parquet."""
    from cobot_analysis.api.options import table_of

    if durations is None:
        return None
    durations = table_of(durations, "durations", "durations")
    if not isinstance(durations, pd.DataFrame):
        from cobot_analysis.io.published import DURATIONS
        from cobot_analysis.schema import read_table

        durations = read_table(Path(durations), DURATIONS)
    if not {"duration", "duration_s"} & set(durations.columns):
        raise InputError("the durations table lacks a duration column",
                         remedy="pass import_published('pair-carriage-2022', ...).durations (or its durations.parquet)")
    return durations


def _anthropometrics(anthropometrics: Any) -> pd.DataFrame | None:
    """Per pair |weight_1 - weight_2| and |height_1 - height_2|: the table, or read from the directory of
    subjects.csv and pairs.csv (``stats.sources.read_anthropometrics``)."""
    from cobot_analysis.stats.sources import read_anthropometrics

    if anthropometrics is None:
        return None
    remedy = ("pass the directory of subjects.csv (id, weight, height) and pairs.csv (id, subject1, subject2), or a table "
              "per pair: pair, weight_diff (kg), height_diff (m)")
    if not isinstance(anthropometrics, pd.DataFrame):
        directory = Path(anthropometrics)
        anthropometrics = read_anthropometrics(directory)
        if anthropometrics is None:
            raise InputError("no subjects.csv and pairs.csv here", path=directory, remedy=remedy)
    missing = [c for c in ("pair", "weight_diff", "height_diff") if c not in anthropometrics.columns]
    if missing:
        raise InputError(f"the anthropometrics table lacks column(s) {missing}", remedy=remedy)
    return anthropometrics


# ---- reconstruct --------------------------------------------------------------------------------
@dataclass
class ReconstructResult:
    """Subjects rebuilt from the table trajectory, vs the measured ones (``reconstruct.RECONSTRUCTION``)."""

    reconstruction: pd.DataFrame
    scenario: int

    def summary(self) -> str:
        return f"{len(self.reconstruction)} reconstructions"

    def metrics(self, *, stage: str = "reconstruct") -> Metrics:
        """Headline numbers (``metrics.analysis.reconstruct``): accuracy of the rebuilt subjects."""
        return collect(stage, headline.reconstruct, self.reconstruction)


def reconstruct(trajectories: Any, *, relative_pose: Any = None, scenario: int = 3, progress=None) -> ReconstructResult:
    """Each subject rebuilt from the table pose and the subject's mean pose in the table frame
    (docs/methods.md sec. 8), compared with the measured trajectory: from the scenario-``scenario`` trials
    themselves and, when given, from a published relative pose: ``import_published(...).subject_wrt_table``
    (a DataFrame, or the ``subject_wrt_table.parquet`` the stage wrote), the dataset's directory (its
    ``subject1_wrt_table.dat`` and ``subject2_wrt_table.dat``, as ``--wrt-table``), or the mapping of
    ``reconstruct.read_wrt_table``.

        >>> from cobot_analysis.api import reconstruct
        >>> from cobot_analysis.synth.tables import pair_table
        >>> rec = reconstruct(pair_table(n_pairs=2, goals=1)).reconstruction
        >>> sorted(rec["entity"].unique()), sorted(rec["relative_pose"].unique()), len(rec)
        (['subject1', 'subject2'], ['trials'], 16)
        >>> bool(rec["d_xy"].between(0.0, 0.5).all())   # m: a subject stays beside the table
        True
    """
    import cobot_analysis.reconstruct as rc
    from cobot_analysis.api.options import table_of

    if relative_pose is not None and not isinstance(relative_pose, dict):
        relative_pose = table_of(relative_pose, "relative_pose", "subject_wrt_table")
        if not isinstance(relative_pose, pd.DataFrame) and Path(relative_pose).is_dir():  # the dataset's .dat files (--wrt-table)
            relative_pose = rc.read_wrt_table(relative_pose)
        elif not isinstance(relative_pose, pd.DataFrame):
            from cobot_analysis.io.published import SUBJECT_WRT_TABLE
            from cobot_analysis.schema import read_table

            relative_pose = read_table(Path(relative_pose), SUBJECT_WRT_TABLE)
    if isinstance(relative_pose, pd.DataFrame):
        missing = [c for c in ("entity", "direction", "sample", "x_rel", "y_rel", "theta_rel") if c not in relative_pose.columns]
        if missing:
            raise InputError(f"the relative pose lacks column(s) {missing}",
                             remedy="pass import_published('pair-carriage-2022', ...).subject_wrt_table")
        relative_pose = rc.relative_pose_table(relative_pose)
    ts = trajectory_set(trajectories, ("trajectories",))
    if not ts.meta["entity"].eq("table").any():
        raise InputError("no table trajectories to reconstruct the subjects from", remedy="use pair-study trajectories")
    parts = []
    from_trials = rc.relative_pose(ts, scenario, "trial")
    if from_trials:
        parts.append(rc.accuracy(ts, from_trials, "trials", scenario, progress=progress))
    if relative_pose:
        parts.append(rc.accuracy(ts, relative_pose, "published", scenario, progress=progress))
    if not parts:
        parts.append(rc.accuracy(ts, rc.relative_pose(ts, scenario, "mean"), "means", scenario, progress=progress))
    rec = pd.concat(parts, ignore_index=True)
    if rec.empty:
        raise InputError(f"no scenario-{scenario} trajectory has both a table and a subject",
                         remedy="check --scenario and the entities of the trajectories")
    return ReconstructResult(rec, scenario)
