"""Comparison of the walking-path models against measured trajectories (docs/methods.md sec. 4-6):
distances per model and trajectory (single walkers and the coupled pair model), and the subjects'
own distances to their mean for reference. The tables and figures of these comparisons are drawn by
``cobot_analysis.reports.models``.
"""

from __future__ import annotations

import math

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.models.ioc import Target, distances


#: models of the comparison: label -> (model, weights). "fitted" is filled in by the caller.
COMPARED = {
    "unicycle": ("unicycle", "walking-2021"),
    "clothoid": ("clothoid", None),
    "Mombaur OC": ("mombaur", "mombaur-2010"),
    "improved OC (published)": ("improved", "walking-2021"),
}


def compared_models(convention) -> dict:
    """The models of the comparison that ``convention`` has (the published one has no unicycle)."""
    return {k: v for k, v in COMPARED.items() if v[0] == "clothoid" or v[0] in convention.oc}


def compare_task(task) -> tuple[list[dict], dict]:
    """Worker task: every compared model on one target (top-level, picklable): its rows, and the generated
    path of each model labelled in ``keep`` (None where its solve failed)."""
    from cobot_analysis.models import generate
    from cobot_analysis.models.presets import weights_vector

    target, models, n_intervals, angle_weight, angle, convention, keep = task
    rows, kept = [], {}
    for label, (model, weights) in models.items():
        w = weights if isinstance(weights, str | None) else dict(zip(
            ("a0", "a1", "a2", "a3", "a4", "a5", "a6", "b0", "b1", "b2", "b3"), weights_vector(weights)))
        df = None
        try:
            df = generate(model, target.start, target.goal, weights=w, n_samples=len(target.x), n_intervals=n_intervals,
                          convention=convention)
            d = distances(target, df["x"].to_numpy(), df["y"].to_numpy(), df["theta"].to_numpy(), convention)
            ok = bool(df["converged"].iloc[-1])  # continuous: a path that misses its goal is never converged
            reached = bool(df["goal_reached"].iloc[-1])
        except Exception as exc:  # noqa: BLE001 - a failed model is a flagged row, not a crash
            from cobot_analysis.errors import SolverError

            if not isinstance(exc, SolverError):
                raise
            d, ok, reached = {"d_xy": math.nan, "d_theta": math.nan, "d_gamma": math.nan}, False, False
        if label in keep:
            kept[label] = df
        rows.append({"model": label, "trial": target.trial, "condition": target.condition, "subject": target.subject,
                     "orientation": target.orientation, "global_distance": target.global_distance,
                     **d, "D": d["d_xy"] + angle_weight * d[f"d_{angle}"], "converged": ok, "goal_reached": reached})
    return rows, kept


def study_cases(means: pd.DataFrame, convention, goal, *, path=None) -> list[tuple[str, tuple, tuple]]:
    """(condition, start, goal) of every walking-study mean in ``means``, in the order of the design: the
    start and goal poses the model comparison of ``fit-ioc`` takes (``targets_from_table(...,
    unoriented=True)``), so ``generate --study`` then ``compare`` answers with the same paths
    (continuous: the measured start pose and ``goal`` on the branch of the last measured heading;
    published: the authors' endpoints, docs/methods.md sec. 11)."""
    from cobot_analysis import conventions
    from cobot_analysis.design import WALKING_CONDITIONS
    from cobot_analysis.models.ioc import targets_from_table

    conv = conventions.get(convention)
    means = walking_means(means)
    targets = targets_from_table(means, path=path, goal=goal, convention=conv, unoriented=True)
    order = {c: i for i, c in enumerate(WALKING_CONDITIONS)}
    return [(t.condition, t.start, t.goal) for t in sorted(targets, key=lambda t: order[t.condition])]


#: the columns a pair-study path carries from its table mean, so that ``compare --against`` finds that mean
PAIR_KEYS = ("study", "condition", "direction", "scenario", "configuration", "end_orientation", "entity")


def table_means(means: pd.DataFrame) -> pd.DataFrame:
    """The pair study's per-scenario table means (kind mean, entity table, a scenario: the pooled 'all'
    means left out), the means ``fit-ioc --model table`` fits and compares."""
    if "kind" in means:
        means = means[means["kind"] == "mean"]
    if not {"entity", "scenario"} <= set(means.columns):
        return means.iloc[0:0]
    return means[(means["entity"] == "table") & means["scenario"].notna()]


def pair_cases(means: pd.DataFrame, convention, *, path=None) -> tuple[list[tuple[str, tuple, tuple]], dict[str, dict]]:
    """(mean, start, goal) of every table mean of the pair study (``table_means``), as the model comparison of
    ``fit-ioc --model table`` takes them (``targets_from_table(..., unoriented=True)``, no design goal: the
    first and last measured poses of the mean, under both conventions), and per mean the trajectory columns
    its paths carry (``PAIR_KEYS``: the study, goal, direction, scenario, end configuration and orientation
    of the mean, entity table), so ``generate --study pair-carriage-2022`` then ``compare --against`` answers
    with the same paths."""
    from cobot_analysis import conventions
    from cobot_analysis.models.ioc import targets_from_table

    means = table_means(means)
    targets = targets_from_table(means, path=path, entity="table", goal=None, convention=conventions.get(convention),
                                 unoriented=True)
    first = means.groupby("trial", sort=False).first()
    keys = {t.trial: {k: first.loc[t.trial, k] for k in PAIR_KEYS if k in first.columns} for t in targets}
    return [(t.trial, t.start, t.goal) for t in targets], keys


def pair_pace(means: pd.DataFrame, durations: pd.DataFrame | None = None) -> dict[str, tuple[float, float]]:
    """mean trial -> the subjects' (travel time (s), mean speed (m/s)) of each pair-study table mean: the
    mean's own travel time where it holds one (speed = its path length / travel time); else the published
    durations (durations.parquet: mean ``duration`` and mean ``mean_velocity``, the table's mean velocity
    over each carriage, over the trials of the same scenario, goal and direction; they do not record the
    end orientation)."""
    from cobot_analysis.models import mean_speed

    out = {}
    keys = ["scenario", "condition", "direction"]
    by_keys = durations.groupby(keys)[["duration", "mean_velocity"]].mean() \
        if durations is not None and set(keys + ["duration", "mean_velocity"]) <= set(durations.columns) else None
    for trial, g in table_means(means).groupby("trial", sort=False):
        g = g.sort_values("sample")
        T = float(g["travel_time"].iloc[0]) if "travel_time" in g else math.nan
        if np.isfinite(T) and T > 0:
            out[str(trial)] = (T, mean_speed(g["x"].to_numpy(float), g["y"].to_numpy(float), T))
        elif by_keys is not None:
            k = tuple(g[c].iloc[0] for c in keys)
            if k in by_keys.index:
                out[str(trial)] = tuple(float(v) for v in by_keys.loc[k, ["duration", "mean_velocity"]])
    return out


def measured_pace(means: pd.DataFrame, trials: pd.DataFrame | None = None) -> dict[str, tuple[float, float]]:
    """condition -> (travel time (s), mean speed = path length / travel time (m/s)) of the walking means
    whose data hold a travel time; for the others (the published walking-2020 means), the subjects'
    own from their ``trials`` (``ioc.pace.measured_by_condition``: travel times or velocity rows)."""
    from cobot_analysis.models import mean_speed
    from cobot_analysis.models.ioc.pace import measured_by_condition

    out = {}
    if trials is not None and "kind" in trials:
        walking = walking_means(trials[trials["kind"] == "trial"].assign(kind="mean"))
        out.update(measured_by_condition(walking) if not walking.empty else {})
    if "travel_time" not in means:
        return out
    for _, g in walking_means(means).groupby("trial", sort=False):
        g = g.sort_values("sample")
        T = float(g["travel_time"].iloc[0])
        if np.isfinite(T) and T > 0:
            out[str(g["condition"].iloc[0])] = (T, mean_speed(g["x"].to_numpy(float), g["y"].to_numpy(float), T))
    return out


def walking_means(means: pd.DataFrame) -> pd.DataFrame:
    """The walker means (kind mean) of the walking study's conditions in ``means``: labels that are its codes and that
    the paths agree with (``design.table_codes``: "S1020", a lab's session 1 trial 020, is no code where its paths do
    not start at the code's start)."""
    from cobot_analysis.design import WALKING_CONDITIONS, table_codes

    means = means[(means["kind"] == "mean") & (means["entity"] == "walker")] if "kind" in means else means
    means = means[means["condition"].isin(WALKING_CONDITIONS)]
    return means[means["condition"].isin(list(table_codes(means)[0]))]


#: how far (m) the measured ends may lie from the walking study's design goal for it to be theirs
DESIGN_GOAL_TOLERANCE = 0.5
#: how far (rad) the circular median of the last measured headings may lie from the design goal heading pi/2
#: (docs/methods.md sec. 6: walking-2020's ends lie 0.50-0.75 off, a study ending on pi/2 rotated a quarter turn 1.53)
DESIGN_HEADING_TOLERANCE = 1.1


def end_heading(df: pd.DataFrame) -> float:
    """The circular median of the last measured heading of each trajectory of ``df`` (NaN without theta)."""
    from cobot_analysis.angles import circular_median

    if "theta" not in df or df.empty:
        return math.nan
    ends = df.sort_values("sample").groupby("trial")["theta"].last() if {"trial", "sample"} <= set(df.columns) else df["theta"].iloc[[-1]]
    return circular_median(ends)


def heading_off_design(heading: float) -> bool:
    """Whether an end heading (``end_heading``) is no walking-2020 goal heading (``DESIGN_HEADING_TOLERANCE``)."""
    from cobot_analysis.angles import angle_diff
    from cobot_analysis.design import WALKING_GOAL

    return bool(np.isfinite(heading) and abs(angle_diff(heading, WALKING_GOAL[2])) > DESIGN_HEADING_TOLERANCE)


def design_goal_offset(df: pd.DataFrame) -> tuple[str, tuple[float, float, float]] | None:
    """None when the trajectories of ``df`` end at the walking study's design goal: the median of their last
    measured positions within 0.5 m of (0, 0) (``DESIGN_GOAL_TOLERANCE``) and the circular median of their last
    headings within 1.1 rad of pi/2 (``DESIGN_HEADING_TOLERANCE``; not judged without theta); else (what differs,
    the measured end pose: the median end and that heading): a study recorded in a frame of its own."""
    from cobot_analysis.angles import wrap
    from cobot_analysis.design import WALKING_GOAL

    if not {"x", "y"} <= set(df.columns) or df.empty:
        return None
    ends = df.sort_values("sample").groupby("trial").last() if {"trial", "sample"} <= set(df.columns) else df.iloc[[-1]]
    x, y = float(np.nanmedian(ends["x"])), float(np.nanmedian(ends["y"]))
    heading = float(wrap(end_heading(df)))
    pose = (x, y, heading if np.isfinite(heading) else WALKING_GOAL[2])
    dist = math.hypot(x - WALKING_GOAL[0], y - WALKING_GOAL[1])
    if dist > DESIGN_GOAL_TOLERANCE:
        return (f"the paths end at ({x:.2f}, {y:.2f}) (median of their last positions), {dist:.2f} m from the walking "
                "study's design goal (0, 0)", pose)
    if heading_off_design(heading):
        return (f"the paths end facing {heading:.2f} rad (circular median of their last headings), over "
                f"{DESIGN_HEADING_TOLERANCE:g} rad from the walking study's design goal heading pi/2: a frame turned "
                "about the goal", pose)
    return None


def compare_models(targets: list[Target], models: dict, *, n_intervals: int = 100, angle: str = "gamma",
                   angle_weight: float = 0.5, jobs=None, scheduler=None, fit: str = "all",
                   convention: str = "continuous") -> pd.DataFrame:
    """Distances of every model in ``models`` (label -> (model, weights)) to every target, each model
    generated and compared under ``convention``, on ``generate``'s grid by default: the same paths and
    distances as ``generate --study`` (``study_cases``) then ``compare --against`` (tests/test_models_goal.py)."""
    return compare_models_keeping(targets, models, (), n_intervals=n_intervals, angle=angle, angle_weight=angle_weight,
                                  jobs=jobs, scheduler=scheduler, fit=fit, convention=convention)[0]


def compare_models_keeping(targets: list[Target], models: dict, keep: tuple[str, ...], *, n_intervals: int = 100,
                           angle: str = "gamma", angle_weight: float = 0.5, jobs=None, scheduler=None, fit: str = "all",
                           convention: str = "continuous") -> tuple[pd.DataFrame, dict[str, dict]]:
    """``compare_models``, and the paths it generated for the models labelled in ``keep``: label -> {target
    trial -> generated path, None where the solve failed} (``fit-ioc``'s figure draws them: not solved twice)."""
    from cobot_analysis.parallel import map_tasks

    tasks = [(t, models, n_intervals, angle_weight, angle, convention, keep) for t in targets]
    res = map_tasks(compare_task, tasks, jobs=jobs, scheduler=scheduler, description="model comparison")
    df = pd.DataFrame([r for rows, _ in res for r in rows])
    df.insert(1, "fit", fit)
    return df, {label: {t.trial: kept[label] for t, (_, kept) in zip(targets, res)} for label in keep}


def subject_distances(trials: list[Target], means: list[Target], angle: str = "gamma",
                      convention: str = "continuous") -> pd.DataFrame:
    """Distance of each subject trajectory to the mean of its condition (docs/methods.md sec. 4), under
    ``convention`` (published: both paths resampled by arc length)."""
    by_condition = {m.condition: m for m in means}
    rows = []
    for t in trials:
        m = by_condition.get(t.condition)
        if m is None or len(m.x) != len(t.x):
            continue
        d = distances(m, t.x, t.y, t.theta, convention)
        rows.append({"model": "subjects vs mean", "fit": "", "trial": t.trial, "condition": t.condition, "subject": t.subject,
                     "orientation": t.orientation, "global_distance": m.global_distance, **d,
                     "D": d["d_xy"] + 0.5 * d[f"d_{angle}"], "converged": True})
    return pd.DataFrame(rows)


# ---- coupled model (two carriers) ----------------------------------------------------------------
def coupled_task(task) -> tuple[dict, list[dict] | None]:
    """Worker task: the coupled model at ``w`` on one pair target, best of a 'rest' and a 'line'
    guess; returns the distance terms and the resampled paths of both carriers (None if not converged)."""
    from cobot_analysis.models.oc import resample
    from cobot_analysis.models.ioc import solve_pair_target
    from cobot_analysis.models.oc.problem import OCPSolution

    spec, w, t = task
    d, sol = solve_pair_target(spec, np.asarray(w, float), t, ("rest", "line"))
    if not d["success"]:
        return d, None
    paths = []
    for i, c in enumerate(t.carriers):
        part = OCPSolution(sol.X[:, 6 * i:6 * i + 6], sol.U[:, 3 * i:3 * i + 3], sol.T, sol.cost, True, "", "", 0, sol.primal)
        paths.append(resample(part, len(c.x)))
    return d, paths


def coupled_distances(spec, targets, weights: dict[str, np.ndarray], *, jobs=None, scheduler=None):
    """Per-carrier distances of the coupled model at each weight set (label -> 15-vector) to every
    pair target: (long table, one row per label x target x carrier; paths label -> [per target])."""
    from cobot_analysis.parallel import map_tasks

    labels = list(weights)
    tasks = [(spec, tuple(weights[lab]), t) for lab in labels for t in targets]
    res = map_tasks(coupled_task, tasks, jobs=jobs, scheduler=scheduler, description="coupled model runs")
    rows, paths = [], {lab: [] for lab in labels}
    for (_, _, t), lab, (d, p) in zip(tasks, [lab for lab in labels for _ in targets], res):
        paths[lab].append(p)
        for i, c in enumerate(t.carriers):
            k = f"_{i + 1}"
            dxy, dth, dga = (d.get(f"d_xy{k}", math.nan), d.get(f"d_theta{k}", math.nan), d.get(f"d_gamma{k}", math.nan))
            rows.append({"model": lab, "fit": "all", "trial": t.trial, "condition": t.condition, "subject": c.trial,
                         "orientation": "", "global_distance": c.global_distance, "direction": t.direction, "carrier": i + 1,
                         "d_xy": dxy, "d_theta": dth, "d_gamma": dga, "D": dxy + spec.angle_weight * dth,
                         "T": d["T"], "T_at_bound": int(d["T_at_bound"]), "converged": bool(d["success"])})
    return pd.DataFrame(rows), paths
