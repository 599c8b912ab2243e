"""Trajectory prediction (docs/methods.md sec. 7): every trajectory predicted at every sample from its
recent past, by the receding-horizon OC predictor and the baselines (constant velocity, CTRV), and the
predictions assessed. Returns the result's tables; nothing is written."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cobot_analysis.lazy import pandas as pd

from cobot_analysis import registry
from cobot_analysis.api.options import at_least, name_list, table_of
from cobot_analysis.errors import InputError
from cobot_analysis.metrics import prediction as headline
from cobot_analysis.metrics.records import Metrics, collect

DEFAULT_SETTINGS = "25:100,50:100,75:100,50:200"


def parse_settings(text: str | list) -> tuple[tuple[int, int], ...]:
    """``"25:100,50:100"`` (or a list of ``"N0:N_OC"`` or of (N0, N_OC)) -> ((25, 100), (50, 100)).

        >>> parse_settings("25:100, 50:200"), parse_settings([(25, 100), "50:200"])
        (((25, 100), (50, 200)), ((25, 100), (50, 200)))
    """
    if not isinstance(text, str):
        try:
            text = ",".join(p if isinstance(p, str) else ":".join(str(v) for v in p) for p in text)
        except TypeError:
            raise InputError(f"bad settings {text!r}", remedy="write settings as N0:N_OC pairs, e.g. 25:100,50:100") from None
    out = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        try:
            n0, n_oc = (int(v) for v in part.split(":"))
        except ValueError:
            raise InputError(f"bad setting {part!r}", remedy="write settings as N0:N_OC pairs, e.g. 25:100,50:100") from None
        out.append((n0, n_oc))
    if not out:
        raise InputError("no (N0, N_OC) setting given", remedy="pass e.g. --settings 50:100")
    return tuple(out)


@dataclass
class PredictionResult:
    """The predictions assessed: per trajectory x setting x predictor (``predictions``), per window
    (``windows``), summaries per setting (``summary``) and the OC predictor vs the baselines on the same
    windows (``comparison``)."""

    config: Any  # models.prediction.sweep.SweepConfig
    trajectories: list
    predictions: pd.DataFrame
    windows: pd.DataFrame
    summary_table: pd.DataFrame
    comparison: pd.DataFrame
    unpredictable: list[str] = field(default_factory=list)
    resumed: int = 0
    horizon_errors: pd.DataFrame | None = None  # the horizon sweep (assess(..., horizons=...)), schema horizon_errors
    goal_inference: pd.DataFrame | None = None  # and its goal inference rows, schema goal_inference

    def summary(self) -> str:
        n = len(self.trajectories)
        c = self.config
        first = self.predictions.drop_duplicates(["study", "trial", "entity", "n0", "n_oc"])
        return (f"{n} {'trajectory' if n == 1 else 'trajectories'} x {len(c.settings)} setting{'s' if len(c.settings) != 1 else ''} x "
                f"{len(c.predictors)} predictor{'s' if len(c.predictors) != 1 else ''}, {int(first['n_windows'].sum())} windows per predictor")

    def metrics(self, *, stage: str | None = None) -> Metrics:
        """Headline numbers (``metrics.prediction.predict``): per setting and predictor, each error's mean, sd and
        r with the global distance, windows used and failed; OC vs each baseline. ``stage``: ``predict`` (or
        ``predict-<label>``; ``-published`` under the published convention)."""
        return collect(stage or registry.directory("predict", self.config.convention.name), headline.predict,
                       self.predictions, self.summary_table, self.comparison)

    def figures(self) -> dict[str, Any]:
        """Matplotlib figures by name, those the stage writes (``reports.prediction.figures``): every prediction
        of the median trajectory (``prediction_overlay``), the predictions at six samples (``prediction_at_k``),
        the error against the global distance (``prediction_error_vs_distance``)."""
        from cobot_analysis.reports import prediction as report

        example = report.example_trajectory(self.predictions, self.trajectories, self.config)
        return report.figures(self.predictions, example, self.config)


def prediction_config(*, settings: str = DEFAULT_SETTINGS, predictors: str = "oc,cv,ctrv", weights: str | None = None,
                      convention: str | None = None, g0: float = 10.0, g1: float = 10.0, t_oc: float | None = None,
                      orientation: str = "auto", v_nominal: float = 1.0, goal=None, candidates: str | None = None):
    """The sweep's configuration (``SweepConfig``) from the command line's options; the convention defaults to
    the one the weights were made under (``presets.weights_convention``; continuous when unknown). ``goal``
    (x, y, theta) and ``candidates`` ("x,y;x,y") for the goal-aware predictors (docs/methods.md sec. 7.1).

        >>> from cobot_analysis.api.prediction import prediction_config
        >>> c = prediction_config(settings="10:20", predictors="cv,ctrv")
        >>> c.settings, c.predictors, c.convention.name   # the default weights are the papers': published
        (((10, 20),), ('cv', 'ctrv'), 'published')
        >>> prediction_config(predictors="oc,kalman")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --predictors: unknown predictor(s) kalman; use some of oc, cv, ctrv, goal, goal-inferred
    """
    from cobot_analysis import conventions
    from cobot_analysis.models.presets import load_weights, weights_convention
    from cobot_analysis.models.prediction.goal import check_goal, parse_candidates
    from cobot_analysis.models.prediction.sweep import SweepConfig

    conv = conventions.get(convention if convention is not None else weights_convention(weights) or "continuous")
    at_least(g0, "--g0", strict=False, example="10")
    at_least(g1, "--g1", strict=False, example="10")
    config = SweepConfig(settings=parse_settings(settings), predictors=tuple(name_list(predictors, "--predictors", example="oc,cv") or ()),
                         weights=weights, g0=g0, g1=g1, t_oc=t_oc, nominal_speed=v_nominal, orientation=orientation,
                         convention=conv, goal=None if goal is None else check_goal(goal),
                         candidates=None if candidates is None else parse_candidates(candidates))
    if "oc" in config.predictors:
        for name in {config.weights_for(e) for e in ("walker", "table")}:
            load_weights(name, "improved")  # unknown preset / bad file: one-line error before any work
    return config


def with_turn_weight(config, df: pd.DataFrame, *, studies: list[str] | None = None, entities: list[str] | None = None):
    """``config`` with the goal plans' turning weight a3 identified (``goal.identify_turn_weight``) on the mean
    paths of ``df`` (``kind == "mean"``, the selected studies and entities) whose weights leave a3
    undetermined (``goal.turn_weight_undetermined``); ``config`` itself when no goal predictor is swept, the
    weights determine a3 or ``df`` holds no such mean (docs/methods.md sec. 7.1). With ``config.goal``
    (``--goal``) the mean paths are continued to that goal, as the predictor plans.

        >>> from cobot_analysis.api import average
        >>> from cobot_analysis.api.prediction import prediction_config, with_turn_weight
        >>> from cobot_analysis.synth.tables import walking_table
        >>> means = average(walking_table(n_subjects=2, n_conditions=2, n_trials=2)).means
        >>> c = prediction_config(settings="20:40", predictors="goal,cv", weights="walking-2021", convention="continuous",
        ...                       goal=(0.0, 0.0, 1.5708))
        >>> c.turn_weight is None, 1e-6 < with_turn_weight(c, means).turn_weight < 1e3   # a3 on its bound -> identified
        (True, True)
    """
    from dataclasses import replace

    from cobot_analysis.models.prediction.goal import identify_turn_weight, turn_weight_undetermined
    from cobot_analysis.models.prediction.sweep import trajectories_from_table

    if not {"goal", "goal-inferred"} & set(config.predictors):
        return config
    means = df[df["kind"] == "mean"] if "kind" in df else df.iloc[:0]
    if studies:
        means = means[means["study"].isin(studies)]
    if entities:
        means = means[means["entity"].isin(entities)]
    undetermined = [e for e in means["entity"].unique() if turn_weight_undetermined(config.weights_for(str(e)))]
    means = means[means["entity"].isin(undetermined)]
    if means.empty:
        return config
    n0 = config.settings[0][0]
    trajs = trajectories_from_table(means, replace(config, settings=((n0, n0 + 1),)))
    if config.goal is not None:  # --goal: the goal the predictor plans to (sweep.plan_options), the means' too
        trajs = [replace(t, goal=tuple(config.goal)) for t in trajs]
    trajs = [t for t in trajs if t.goal is not None]
    if not trajs:
        return config
    weights = {config.weights_for(t.entity) for t in trajs}
    if len(weights) > 1:
        raise InputError("the goal plans' a3 is identified for one set of weights; these mean paths use " + ", ".join(sorted(weights)),
                         remedy="select one entity kind (--entity) or pass --weights")
    return replace(config, turn_weight=identify_turn_weight(trajs, weights.pop(), n0))


def stratified(trajectories: list, k: int) -> list:
    """A stratified sample: ``k`` trajectories of each condition (study, entity, condition), in the order
    of ``trajectories``. The condition of rank r (in that order) with n trajectories gives its numbers
    (r + j n / k) mod n, j = 0..k-1 (rounded down): evenly spaced, from an offset that moves on with the
    condition, so that subjects and repetitions take turns across conditions.

        >>> from cobot_analysis.api.prediction import prediction_config, stratified
        >>> from cobot_analysis.models.prediction.sweep import trajectories_from_table
        >>> from cobot_analysis.synth.tables import walking_table
        >>> walks = trajectories_from_table(walking_table(n_subjects=2, n_conditions=3, n_trials=2, n=30),
        ...                                 prediction_config(settings="10:20", predictors="cv"))
        >>> [t.trial for t in stratified(walks, 1)]   # one of each condition, each from the next position
        ['S00_E1500_0', 'S00_N1500_1', 'S01_S1500_0']
    """
    groups: dict[tuple, list] = {}
    for t in trajectories:
        groups.setdefault((t.study, t.entity, t.meta.get("condition", "")), []).append(t)
    chosen = set()
    for rank, members in enumerate(groups.values()):
        n, m = len(members), min(k, len(members))
        chosen.update(id(members[(rank + j * n // m) % n]) for j in range(m))
    return [t for t in trajectories if id(t) in chosen]


def select(df: pd.DataFrame, config, *, studies: list[str] | None = None, entities: list[str] | None = None, kind: str = "all",
           limit: int | None = None, every: int = 1, path=None, per_condition: int | None = None) -> tuple[list, list[str]]:
    """The trajectories to predict (``studies``, ``entities``, ``kind``, ``per_condition`` of each condition
    (``stratified``), every ``every``-th, the first ``limit``) and the labels of those left out for lack of
    N0 consecutive finite positions.

        >>> from cobot_analysis.api.prediction import prediction_config, select
        >>> from cobot_analysis.synth.tables import walking_table
        >>> trajs, left_out = select(walking_table(n_subjects=2, n_conditions=2, n_trials=1),
        ...                          prediction_config(settings="10:20", predictors="cv"), limit=3)
        >>> [t.label for t in trajs], left_out
        (['synthetic-walking/S00_E1500_0/walker', 'synthetic-walking/S00_N1500_0/walker', 'synthetic-walking/S01_E1500_0/walker'], [])
        >>> select(walking_table(n_subjects=2, n_conditions=2, n_trials=1), prediction_config(settings="10:20"), limit=0)
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --limit must be >= 1, got 0; e.g. --limit 10
    """
    from cobot_analysis.models.prediction.sweep import predictable_windows, trajectories_from_table

    if kind not in ("trial", "mean", "all"):
        raise InputError(f"unknown --kind {kind!r}", remedy="use trial, mean or all")
    at_least(limit, "--limit", low=1, strict=False, example="10")
    at_least(every, "--every", low=1, strict=False, example="5")
    at_least(per_condition, "--per-condition", low=1, strict=False, example="2")
    studies = name_list(studies, "--only-study", example="walking-2020")
    entities = name_list(entities, "--entity", example="walker")
    if studies:
        df = df[df["study"].isin(studies)]
    if entities:
        df = df[df["entity"].isin(entities)]
    if kind != "all":
        df = df[df["kind"] == kind]
    trajs = trajectories_from_table(df, config, path)
    if per_condition:
        trajs = stratified(trajs, per_condition)
    trajs = trajs[::every]
    if limit:
        trajs = trajs[:limit]
    n0_min = min(n0 for n0, _ in config.settings)
    unpredictable = [t.label for t in trajs if not predictable_windows(t, n0_min)]
    trajs = [t for t in trajs if predictable_windows(t, n0_min)]
    if not trajs:
        raise InputError(f"no window can be predicted: no trajectory has {n0_min} consecutive samples with finite positions",
                         path=path, remedy="check the trajectories (gaps left by preprocess) or lower N0")
    return trajs, unpredictable


def predict(trajectories: pd.DataFrame | str | os.PathLike, *, settings: str = DEFAULT_SETTINGS, predictors: str = "oc,cv,ctrv",
            weights: str | None = None, convention: str | None = None, g0: float = 10.0, g1: float = 10.0,
            t_oc: float | None = None, orientation: str = "auto", v_nominal: float = 1.0, studies: list[str] | None = None,
            entities: list[str] | None = None, kind: str = "all", limit: int | None = None, every: int = 1,
            per_condition: int | None = None, goal=None, candidates: str | None = None, horizons: str | None = None,
            work: str | os.PathLike | None = None, jobs: int | None = None, scheduler: str | None = None) -> PredictionResult:
    """Predict every trajectory at every sample k from its last N0 samples over N_OC - N0 samples ahead, for
    each (N0, N_OC) of ``settings`` and each predictor (``oc``: receding-horizon OC; ``cv``: constant
    velocity; ``ctrv``: constant turn rate and velocity), and assess the predictions: delta_xy,
    delta_theta, d_pred (docs/methods.md sec. 7), ADE / FDE. ``work``: a directory that keeps finished
    (trajectory, setting) results, so an interrupted run resumes. The convention defaults to the one the
    weights were made under (``published`` for the presets; docs/methods.md sec. 11). The goal-aware
    predictors (sec. 7.1), as ``predict --goal --candidates --horizons``: ``goal`` (x, y, theta) the goal
    of ``goal`` (default each trajectory's design goal; refused when the model does not reach it),
    ``candidates`` ("x,y;x,y") the goals ``goal-inferred`` chooses among, ``horizons`` ("5,50,all") the
    horizon sweep at the first setting's N0 (sec. 7.2; ``horizon_errors``, ``goal_inference``).

    One synthetic walk of 40 samples, N0 = 10, N_OC = 20: N - N0 + 1 = 31 windows per predictor.

        >>> from cobot_analysis.api import predict
        >>> from cobot_analysis.synth.tables import walking_table
        >>> walk = walking_table(n_subjects=1, n_conditions=1, n_trials=1, missing_theta=0)
        >>> r = predict(walk, settings="10:20", predictors="oc,cv", convention="continuous", jobs=1)
        >>> r.summary()
        '1 trajectory x 1 setting x 2 predictors, 31 windows per predictor'
        >>> p = r.predictions.set_index("predictor")
        >>> int(p.loc["oc", "n_failed"]), bool(p.loc["oc", "delta_xy"] < 0.01)   # m, a near-straight walk
        (0, True)
        >>> sorted(r.summary_table["metric"].unique())
        ['ade', 'd_pred', 'delta_theta', 'delta_xy', 'fde']
        >>> numbers = r.metrics()   # the headline numbers: what the predict stage writes to metrics.json
        >>> numbers.stage, numbers.convention, numbers.as_dict()["predict.10:20.oc.windows_used"]
        ('predict', 'continuous', 31)
        >>> sorted(r.figures())     # matplotlib Figures by name, as the stage writes them
        ['prediction_at_k', 'prediction_error_vs_distance', 'prediction_overlay']

    List options as a list or as the command line's comma-separated text: ``predictors=["oc", "cv"]``,
    ``entities="walker"``.

        >>> predict(walk, settings=["10:20"], predictors=["cv"], entities="walker", jobs=1).summary()
        '1 trajectory x 1 setting x 1 predictor, 31 windows per predictor'

    The goal-aware predictor to a given goal, with the horizon sweep at N0 = 10:

        >>> g = predict(walk, settings="10:20", predictors="goal,cv", convention="continuous", goal=(0.0, 0.0, 1.5708),
        ...             horizons="5,all", jobs=1)
        >>> sorted(g.predictions["predictor"]), sorted(g.horizon_errors["horizon"].unique().tolist())   # -1: the whole path
        (['cv', 'goal'], [-1, 5])
    """
    import tempfile

    from cobot_analysis.schema import TRAJECTORIES, read_table

    from cobot_analysis.models.prediction.horizons import parse_horizons

    config = prediction_config(settings=settings, predictors=predictors, weights=weights, convention=convention, g0=g0, g1=g1,
                               t_oc=t_oc, orientation=orientation, v_nominal=v_nominal, goal=goal, candidates=candidates)
    horizon_list = None if horizons is None else parse_horizons(horizons)
    studies, entities = name_list(studies, "--only-study", example="walking-2020"), name_list(entities, "--entity", example="walker")
    trajectories = table_of(trajectories, "trajectories", "trajectories", "means")
    path = None
    if not isinstance(trajectories, pd.DataFrame):
        path = Path(trajectories)
        trajectories = read_table(path, TRAJECTORIES)
    trajs, unpredictable = select(trajectories, config, studies=studies, entities=entities, kind=kind, limit=limit, every=every,
                                  path=path, per_condition=per_condition)
    config = with_turn_weight(config, trajectories, studies=studies, entities=entities)
    if config.goal is not None and "goal" in config.predictors:
        from cobot_analysis.models.prediction.goal import check_reachable

        check_reachable(trajs, config.goal, min(n0 for n0, _ in config.settings), config.weights_for)
    sweep = None if horizon_list is None else (config.settings[0][0], horizon_list)  # the horizon sweep at the first N0
    if work is not None:
        return assess(trajs, config, work, unpredictable=unpredictable, jobs=jobs, scheduler=scheduler, horizons=sweep)
    with tempfile.TemporaryDirectory() as tmp:
        return assess(trajs, config, tmp, unpredictable=unpredictable, jobs=jobs, scheduler=scheduler, horizons=sweep)


def assess(trajs: list, config, work: str | os.PathLike, *, unpredictable: list[str] = (), jobs: int | None = None,
           scheduler: str | None = None, horizons: tuple | None = None) -> PredictionResult:
    """Predict the selected trajectories (``select``) with ``config`` and assess the predictions; finished
    (trajectory, setting) results are kept in ``work`` and reused. ``horizons`` = (N0, horizon list): the
    horizon sweep (docs/methods.md sec. 7.2) too, from the same predictions (``horizon_errors``, ``goal_inference``).

        >>> import tempfile
        >>> from cobot_analysis.api.prediction import assess, prediction_config, select
        >>> from cobot_analysis.synth.tables import walking_table
        >>> config = prediction_config(settings="10:20", predictors="cv")
        >>> trajs, _ = select(walking_table(n_subjects=1, n_conditions=1, n_trials=1), config)
        >>> with tempfile.TemporaryDirectory() as work:
        ...     first = assess(trajs, config, work, jobs=1)
        ...     again = assess(trajs, config, work, jobs=1)
        >>> first.resumed, again.resumed, again.predictions["delta_xy"].equals(first.predictions["delta_xy"])
        (0, 1, True)
    """
    from cobot_analysis.models.prediction.sweep import WorkDir, compare_table, horizon_tables, run_sweep, summary_table

    work = WorkDir(Path(work))
    metrics, windows, resumed = run_sweep(trajs, config, work, jobs=jobs, scheduler=scheduler, horizons=horizons)
    errors, inference = horizon_tables(trajs, config, work, horizons) if horizons is not None else (None, None)
    return PredictionResult(config, trajs, metrics, windows, summary_table(metrics, config.convention),
                            compare_table(metrics, windows, config.convention), list(unpredictable), resumed, errors, inference)
