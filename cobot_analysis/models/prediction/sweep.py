"""The prediction sweep: trajectories x (N0, N_OC) settings x predictors (docs/methods.md sec. 7).

Each trajectory is one task (all settings and predictors), run on a local process pool or a Dask
cluster through ``parallel.map_tasks``. Finished results are saved at once, per trajectory and
setting, in a work directory (``WS/.predict-work/``, see ``WorkDir``), so an interrupted sweep
resumes where it stopped and a sweep that adds a setting computes only that setting; the stage
merges them into its tables at the end.

Convention (``SweepConfig.convention``, docs/methods.md sec. 11): how the OC predictor is set up
(``OCPredictor``), the default table weights (``PredictionRule.table_weights``) and the sd of the
summaries (``Comparison.sd_ddof``); every output table carries its name.

Sampling period. N0 and N_OC count samples; one OC node per sample, ``T_OC`` = the sample period
(continuous convention; the published one makes every sample a node of 0.1 s).
The trajectories are time-normalised (N samples over the movement), so ``T_OC = D / (N - 1)`` with
the duration ``D`` = the trial's travel time when known, else an assumed duration
``D = path length / nominal speed`` (default 1.0 m/s; the published walking-2020 data hold no
durations). With ``t_oc`` given, the trajectory is first resampled (linear interpolation of x, y
and unwrapped theta) every ``t_oc`` seconds over its duration and N0, N_OC count those samples.

Orientation. Where theta is tracked, the OC cost holds g1 (ctheta - theta)^2 and delta_theta is
reported. ``orientation="auto"`` (default) tracks it unless the trajectory's quality flags say it is
missing or implausible (``orientation_missing``, ``implausible_gamma``): those trajectories are
predicted from positions only (the OC tracks the direction of travel, see ``OCPredictor``; baselines predict no theta) and get
no delta_theta. ``"track"`` tracks every measured theta, ``"ignore"`` none.

Windows compared between predictors. A window enters a trajectory's metrics only if every
predictor of the sweep predicted it (so the OC predictor and the baselines are compared on the same
windows); windows skipped for NaN positions and failed OC solves are counted per predictor.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.conventions import CONTINUOUS, Convention
from cobot_analysis.errors import InputError
from cobot_analysis.models.prediction.errors import summarise, window_errors
from cobot_analysis.models.prediction.base import check_setting
from cobot_analysis.models.prediction.goal import check_candidates, check_goal
from cobot_analysis.models.prediction.predictor import PREDICTORS, make_predictor
from cobot_analysis.schema import Column, TableSchema

DEFAULT_SETTINGS = ((25, 100), (50, 100), (75, 100), (50, 200))
NOMINAL_SPEED = 1.0  # m/s: assumed mean walking speed when a trajectory's duration is unknown
TABLE_ENTITIES = ("table",)
ORIENTATION_MODES = ("auto", "track", "ignore")
#: quality flags (schema ``trajectories``) that make the measured orientation unusable in "auto" mode
ORIENTATION_FLAGS = ("orientation_missing", "implausible_gamma")

_ID = {
    "convention": Column("string", "", "published or continuous (docs/methods.md sec. 11)"),
    "study": Column("string", "", "study name"),
    "trial": Column("string", "", "trial identifier"),
    "entity": Column("string", "", "walker, subject1, subject2 or table"),
}
PREDICTIONS = TableSchema(
    name="predictions",
    version=2,
    description="Prediction metrics (docs/methods.md sec. 7) per trajectory x (N0, N_OC) setting x predictor, over the "
                "windows every predictor predicted.",
    columns={
        **_ID,
        "kind": Column("string", "", "'trial' or 'mean'"),
        "condition": Column("string", "", "start condition (walking) or goal (pairs)"),
        "subject": Column("string", "", "subject id (walking study)", required=False),
        "start_orientation": Column("string", "", "walking: start orientation letter N/E/S/O; else empty"),
        "global_distance": Column("float", "m", "straight-line distance start -> end of the trajectory"),
        "n0": Column("int", "-", "N0: measured past samples tracked by a window"),
        "n_oc": Column("int", "-", "N_OC: samples of the OC window (past + future)"),
        "predictor": Column("string", "", "oc (receding-horizon OC), cv (constant velocity), ctrv (constant turn rate and velocity), "
                                          "goal / goal-inferred (goal-aware OC, docs/methods.md sec. 7.1)"),
        "weights": Column("string", "", "OC cost weights (preset or file); empty for baselines"),
        "t_oc": Column("float", "s", "seconds per OC node: the sample period (continuous) or 0.1 s (published)"),
        "sample_period": Column("float", "s", "sample period of the (resampled) trajectory: duration / (N - 1) or --t-oc"),
        "duration": Column("float", "s", "trajectory duration used for T_OC"),
        "duration_source": Column("string", "", "'travel_time' (measured) or 'nominal_speed' (path length / nominal speed)"),
        "orientation": Column("bool", "", "the trajectory has a measured orientation"),
        "theta_tracked": Column("bool", "", "the orientation was given to the predictors (else positions only, delta_theta NaN)"),
        "n_samples": Column("int", "-", "samples of the (resampled) trajectory"),
        "n_windows": Column("int", "-", "N_hum = N - N0 + 1 windows"),
        "n_used": Column("int", "-", "windows every predictor predicted (behind the metrics)"),
        "n_skipped": Column("int", "-", "windows skipped: NaN position in the measured past"),
        "n_failed": Column("int", "-", "windows without a prediction from this predictor (solver failure)"),
        "n_full": Column("int", "-", "used windows with the whole horizon inside the recording (behind ADE/FDE)"),
        "delta_xy": Column("float", "m", "mean over windows of the mean position error over k .. k+N_k-1"),
        "delta_theta": Column("float", "rad", "same with the wrapped orientation error"),
        "d_pred": Column("float", "m", "mean over windows of ||x*_k - x*_{k+N_OC-N0}||"),
        "ade": Column("float", "m", "average displacement error over the future samples of full-horizon windows"),
        "fde": Column("float", "m", "final displacement error (sample k + N_OC - N0) of full-horizon windows"),
    },
)
PREDICTION_WINDOWS = TableSchema(
    name="prediction_windows",
    version=2,
    description="Per-window prediction errors: one row per trajectory x setting x predictor x window k.",
    columns={
        **_ID,
        "n0": Column("int", "-", "N0"),
        "n_oc": Column("int", "-", "N_OC"),
        "predictor": Column("string", "", "oc, cv or ctrv"),
        "k": Column("int", "-", "sample at which the prediction is made (0-based)"),
        "phase": Column("float", "%", "100 k / (N - 1)"),
        "used": Column("bool", "", "every predictor predicted this window"),
        "error_xy": Column("float", "m", "(1/N_k) sum_i ||c_i - x*_i|| over k .. k+N_k-1"),
        "error_theta": Column("float", "rad", "(1/N_k) sum_i |wrap(ctheta_i - theta*_i)|"),
        "reach": Column("float", "m", "||x*_k - x*_{k+N_OC-N0}||"),
        "ade": Column("float", "m", "mean future error over a full horizon (NaN if cut by the end)"),
        "fde": Column("float", "m", "error at k + N_OC - N0 (NaN if cut by the end)"),
    },
)


@dataclass(frozen=True)
class SweepConfig:
    """What is swept and how (the stage parameters)."""

    settings: tuple[tuple[int, int], ...] = DEFAULT_SETTINGS
    predictors: tuple[str, ...] = ("oc", "cv", "ctrv")  # the goal-aware predictors on request (they need goals)
    weights: str | None = None  # OC weights: preset or weights file; None = walking-2021, table-2022 for tables
    g0: float = 10.0
    g1: float = 10.0
    t_oc: float | None = None
    nominal_speed: float = NOMINAL_SPEED
    orientation: str = "auto"  # track theta: "auto" (unless flagged), "track" (wherever present), "ignore"
    convention: Convention = CONTINUOUS  # docs/methods.md sec. 11
    goal: tuple[float, float, float] | None = None  # goal of the goal predictor; None: each trajectory's design goal
    candidates: tuple[tuple[float, float], ...] | None = None  # goal-inferred's candidates; None: the study's goals
    turn_weight: float | None = None  # a3 of the goal plans where the weights leave it undetermined (goal.identify_turn_weight)

    def __post_init__(self) -> None:
        for n0, n_oc in self.settings:
            check_setting(n0, n_oc)
        unknown = [p for p in self.predictors if p not in PREDICTORS]
        if unknown or not self.predictors:
            raise InputError(f"--predictors: unknown predictor(s) {', '.join(unknown) or '(none given)'}",
                             remedy=f"use some of {', '.join(PREDICTORS)}")
        if {"goal", "goal-inferred"} & set(self.predictors) and self.convention.name != "continuous":
            raise InputError("--predictors: goal and goal-inferred are defined under the continuous convention only",
                             remedy="pass --convention continuous or leave them out of --predictors")
        if self.goal is not None:
            check_goal(self.goal)
        if self.candidates is not None:
            check_candidates(self.candidates)
        if self.t_oc is not None and not self.t_oc > 0:
            raise InputError(f"T_OC must be positive (got {self.t_oc})", remedy="pass a positive --t-oc")
        if self.orientation not in ORIENTATION_MODES:
            raise InputError(f"unknown orientation mode {self.orientation!r}", remedy=f"use one of {', '.join(ORIENTATION_MODES)}")
        if not self.nominal_speed > 0:
            raise InputError(f"nominal speed must be positive (got {self.nominal_speed})", remedy="pass a positive --v-nominal")

    def weights_for(self, entity: str) -> str:
        """``weights``, else walking-2021 for walkers and the convention's table preset for tables."""
        return self.weights or (self.convention.prediction.table_weights if entity in TABLE_ENTITIES else "walking-2021")

    def params(self) -> dict:
        """The configuration as JSON-ready parameters, the convention by its name."""
        params = {**asdict(self), "convention": self.convention.name}
        if self.turn_weight is None:  # absent when unused: stages without it stay current
            del params["turn_weight"]
        return params


@dataclass
class Trajectory:
    """One recorded trajectory ready for prediction: poses every ``dt`` seconds."""

    study: str
    trial: str
    entity: str
    poses: np.ndarray  # (N, 3): x, y, theta (theta NaN where unknown)
    dt: float
    duration: float
    duration_source: str
    track_theta: bool = True  # the predictors see the measured orientation
    meta: dict = field(default_factory=dict)  # kind, condition, subject, start_orientation, global_distance
    goal: tuple[float, float, float] | None = None  # the design goal (goal-aware predictors), see goal.design_goal

    @property
    def seen(self) -> np.ndarray:
        """The poses the predictors see: theta NaN unless it is tracked."""
        if self.track_theta:
            return self.poses
        seen = self.poses.copy()
        seen[:, 2] = np.nan
        return seen

    @property
    def label(self) -> str:
        return f"{self.study}/{self.trial}/{self.entity}"

    @property
    def end(self) -> np.ndarray | None:
        """The last measured position (None where no position is finite)."""
        finite = self.poses[np.isfinite(self.poses[:, :2]).all(axis=1), :2]
        return finite[-1] if len(finite) else None

    def digest(self) -> str:
        h = hashlib.sha256(json.dumps([self.label, self.dt, self.track_theta, self.meta], sort_keys=True, default=str).encode())
        h.update(np.ascontiguousarray(self.poses).tobytes())
        return h.hexdigest()[:20]


# ---- input ------------------------------------------------------------------------------------
def path_length(xy: np.ndarray) -> float:
    """Length of the polyline through the finite positions (m)."""
    xy = xy[np.isfinite(xy).all(axis=1)]
    return float(np.hypot(*np.diff(xy, axis=0).T).sum()) if len(xy) > 1 else 0.0


def resample(poses: np.ndarray, duration: float, t_oc: float) -> np.ndarray:
    """Poses every ``t_oc`` s over ``duration`` (linear interpolation; NaN stays NaN nearby)."""
    src = np.linspace(0.0, duration, len(poses))
    dst = np.arange(0.0, duration + 1e-9 * duration, t_oc)
    out = np.empty((len(dst), 3))
    for j in range(3):
        v = poses[:, j]
        out[:, j] = np.interp(dst, src, v)  # a NaN neighbour makes the interpolated sample NaN
    return out


def trajectories_from_table(df: pd.DataFrame, config: SweepConfig, path: str | os.PathLike | None = None) -> list[Trajectory]:
    """Split a trajectories table (schema ``trajectories``) into ``Trajectory`` objects.

    Raises ``InputError`` for an empty selection, a wrong unit of time (negative travel time) or a
    trajectory shorter than the largest N0.
    """
    from cobot_analysis.design import table_codes
    from cobot_analysis.models.comparison import end_heading
    from cobot_analysis.models.prediction.goal import design_goal

    if df.empty:
        raise InputError("no trajectory to predict (empty selection)", path=path, remedy="check --only-study / --entity / --kind")
    n0_max = max(n0 for n0, _ in config.settings)
    df = df.copy(deep=False)
    df.attrs = {}  # the table's metadata: pandas would deep-copy it at every slice of every group below
    headings = {study: end_heading(g) for study, g in df.groupby("study", observed=True) if str(study).startswith("walking")}
    codes = {study: table_codes(g[g["entity"] == "walker"])[0] for study, g in df.groupby("study", observed=True)}
    out = []
    for (study, trial, entity), g in df.groupby(["study", "trial", "entity"], sort=True, observed=True):
        g = g.sort_values("sample")
        poses = g[["x", "y", "theta"]].to_numpy(dtype=float)
        label = f"{study}/{trial}/{entity}"
        travel = g["travel_time"].to_numpy(dtype=float)
        travel = travel[np.isfinite(travel)]
        if travel.size and travel[0] > 0:
            duration, source = float(travel[0]), "travel_time"
        elif travel.size:
            raise InputError(f"trajectory {label} has a non-positive travel time ({travel[0]} s)", path=path,
                             remedy="re-run the stage that wrote the trajectories")
        else:
            duration, source = path_length(poses[:, :2]) / config.nominal_speed, "nominal_speed"
        if config.t_oc is not None and duration > 0:
            poses = resample(poses, duration, config.t_oc)
        if len(poses) < n0_max:
            raise InputError(f"trajectory {label} has {len(poses)} samples, fewer than N0 = {n0_max}", path=path,
                             remedy="lower N0 in --settings (or a smaller --t-oc), or leave the trajectory out")
        dt = config.t_oc if config.t_oc is not None else duration / (len(poses) - 1)
        if not dt > 0 and np.isfinite(poses[:, :2]).all(axis=1).sum() < 2:
            dt = float("nan")  # no position at all: every window will be skipped (see predictable_windows)
        elif not dt > 0:
            raise InputError(f"trajectory {label} does not move (zero duration)", path=path,
                             remedy="leave it out or give its travel time")
        first = g.iloc[0]
        condition = str(first.get("condition") or "")
        code = codes[study].get(condition) if entity == "walker" else None  # a walking-2020 code its study's paths agree with
        orientation = code.orientation if code else ""
        finite = poses[np.isfinite(poses[:, :2]).all(axis=1), :2]  # the measured positions
        dist = first.get("travelled_distance")
        if dist is None or not np.isfinite(dist):
            dist = float(np.hypot(*(finite[-1] - finite[0]))) if len(finite) else float("nan")
        subject = first.get("subject")
        meta = {"kind": str(first.get("kind") or ""), "condition": condition,
                "subject": None if subject is None or pd.isna(subject) else str(subject),
                "start_orientation": orientation, "global_distance": float(dist)}
        flags = set(str(first.get("quality") or "").split(";"))
        has_theta = bool(np.isfinite(poses[:, 2]).any())
        track = has_theta and (config.orientation == "track" or (config.orientation == "auto" and not flags & set(ORIENTATION_FLAGS)))
        goal = design_goal(str(study), {"condition": condition, "direction": first.get("direction"),
                                        "end_orientation": first.get("end_orientation")}, finite[-1] if len(finite) else None,
                           headings.get(study, math.nan))
        out.append(Trajectory(str(study), str(trial), str(entity), poses, float(dt), float(duration), source, track, meta, goal))
        for name in {"goal", "goal-inferred"} & set(config.predictors):
            predictor_options(name, out[-1], config)  # a goal it cannot know is refused here, before any solve
    return out


def predictable_windows(traj: Trajectory, n0: int) -> int:
    """Windows of ``traj`` whose measured past (N0 samples) has finite positions."""
    finite = np.isfinite(traj.poses[:, :2]).all(axis=1).astype(int)
    return int((np.convolve(finite, np.ones(n0, dtype=int), mode="valid") == n0).sum())


# ---- one trajectory ---------------------------------------------------------------------------
def predictor_options(name: str, traj: Trajectory, config: SweepConfig) -> dict:
    """``make_predictor`` options of ``name`` for ``traj``: weights, tracking weights (oc), the design
    goal (goal) or the study's candidate goals (goal-inferred)."""
    from cobot_analysis.models.prediction.goal import design_goal, study_candidates, turn_weight_undetermined

    if name in ("goal", "goal-inferred") and config.turn_weight is not None and turn_weight_undetermined(config.weights_for(traj.entity)):
        return {**predictor_options(name, traj, replace(config, turn_weight=None)), "turn_weight": config.turn_weight}
    if name == "oc":
        return {"weights": config.weights_for(traj.entity), "g0": config.g0, "g1": config.g1}
    if name == "goal":
        if config.goal is not None:
            return {"weights": config.weights_for(traj.entity), "goal": config.goal}
        if traj.goal is None:
            raise InputError(f"trajectory {traj.label} has no design goal for the goal-aware predictor (its study's design "
                             "gives none, or it ends over 0.5 m from the walking goal (0, 0) or its study's walkers end "
                             "facing over 1.1 rad off pi/2: a frame of its own)",
                             remedy="give its goal with --goal x,y[,theta], or leave 'goal' out of --predictors")
        return {"weights": config.weights_for(traj.entity), "goal": traj.goal}
    if name == "goal-inferred":
        if config.candidates is None and traj.study.startswith("walking") and design_goal(traj.study, traj.meta, traj.end) is None:
            raise InputError(f"trajectory {traj.label} ends over 0.5 m from the walking goal (0, 0), the walking study's "
                             "only candidate goal: a frame of its own", remedy="give its goals with --candidates x,y;x,y")
        cands = config.candidates if config.candidates is not None else study_candidates(traj.study)
        return {"weights": config.weights_for(traj.entity), "candidates": cands}
    return {}


def predict_trajectory(traj: Trajectory, config: SweepConfig) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Every setting and predictor on one trajectory: (metrics rows, per-window rows).

    A prediction depends on the measured past (N0 samples) only, N_OC - N0 being how far it is
    extrapolated (the OC predictor coasts beyond its past, see ``OCPredictor``). So each predictor
    runs once per N0, with the longest horizon of the settings sharing that N0, and each setting
    takes the first N_OC - N0 + 1 samples of those predictions: (50,100) and (50,200) cost one pass.
    """
    return setting_rows(traj, config, trajectory_runs(traj, config))


def trajectory_runs(traj: Trajectory, config: SweepConfig, whole_path_n0: int | None = None) -> dict:
    """Each predictor run once per N0 of ``config`` over the longest horizon of the settings sharing it
    (``predict_trajectory``): ``{(N0, name): (predictions, skipped, failed, options, predictor)}``.
    ``whole_path_n0``: that N0 is run at least as far as the recording goes (H = N - N0), so the horizon
    sweep (``horizons.horizon_rows``) reads the same predictions as the settings."""
    longest: dict[int, int] = {}
    for n0, n_oc in config.settings:
        longest[n0] = max(n_oc, longest.get(n0, 0))
    if whole_path_n0 is not None:
        longest[whole_path_n0] = max(len(traj.poses), longest.get(whole_path_n0, 0))
    runs = {}
    for n0, n_oc in longest.items():
        for name in config.predictors:
            options = predictor_options(name, traj, config)
            predictor = make_predictor(name, n0, n_oc, traj.dt, convention=config.convention, **options)
            runs[n0, name] = (predictor.predict_offline(traj.seen), predictor.skipped, predictor.failed, options, predictor)
    return runs


def setting_rows(traj: Trajectory, config: SweepConfig, runs: dict) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(metrics rows, per-window rows) of every setting of ``config`` from ``trajectory_runs``; the per-window
    rows of all settings and predictors built as one table (columns concatenated)."""
    rows, parts = [], []
    n = len(traj.poses)
    has_theta = bool(np.isfinite(traj.poses[:, 2]).any())
    conv = config.convention
    node_dt = conv.prediction.node_dt or traj.dt  # seconds per OC node
    for n0, n_oc in config.settings:
        results = {}
        for name in config.predictors:
            predictions, skipped, failed, options, _ = runs[n0, name]
            results[name] = (window_errors(traj.poses, predictions[:, : n_oc - n0 + 1], n0), skipped, failed, options)
        common = np.logical_and.reduce([err.valid for err, *_ in results.values()])
        k = np.arange(n0 - 1, n)
        phase = 100.0 * k / (n - 1)
        for name, (err, skipped, failed, options) in results.items():
            m = summarise(err, common)
            rows.append({"convention": conv.name, "study": traj.study, "trial": traj.trial, "entity": traj.entity, **traj.meta,
                         "n0": n0, "n_oc": n_oc, "predictor": name, "weights": options.get("weights", ""),
                         "t_oc": node_dt, "sample_period": traj.dt, "duration": traj.duration, "duration_source": traj.duration_source,
                         "orientation": has_theta, "theta_tracked": traj.track_theta, "n_samples": n, "n_windows": m.n_windows, "n_used": m.n_used,
                         "n_skipped": skipped, "n_failed": failed, "n_full": m.n_full, "delta_xy": m.delta_xy,
                         "delta_theta": m.delta_theta if traj.track_theta else float("nan"), "d_pred": m.d_pred,
                         "ade": m.ade, "fde": m.fde})
            parts.append((n0, n_oc, name, k, phase, common, err))
    sizes = [len(p[3]) for p in parts]

    def column(i: int) -> np.ndarray:
        return np.concatenate([p[i] for p in parts])

    def errors(field: str) -> np.ndarray:
        return np.concatenate([getattr(p[6], field) for p in parts])

    windows = pd.DataFrame({
        "convention": conv.name, "study": traj.study, "trial": traj.trial, "entity": traj.entity,
        "n0": np.repeat([p[0] for p in parts], sizes), "n_oc": np.repeat([p[1] for p in parts], sizes),
        "predictor": np.repeat(np.array([p[2] for p in parts], dtype=object), sizes), "k": column(3), "phase": column(4), "used": column(5),
        "error_xy": errors("error_xy"), "error_theta": errors("error_theta") if traj.track_theta else np.nan, "reach": errors("reach"),
        "ade": errors("ade"), "fde": errors("fde")})
    return pd.DataFrame(rows), windows


def sweep_task(item: tuple) -> tuple:
    """Task of the parallel sweep (top level so that process pools and Dask can pickle it):
    ``(trajectory, config, work[, horizons])`` -> ``(trajectory, metrics, windows[, horizon rows])``.

    ``horizons`` = (N0, horizon list): also the horizon sweep's rows (``horizons.horizon_rows``) from the
    same predictions (``trajectory_runs``). The task saves its result in the work directory itself when it
    can reach it (local pool, a Dask cluster on this machine or a shared file system), so that every
    finished trajectory survives an interruption; the caller saves it otherwise.
    """
    traj, config, work, *rest = item
    horizons = rest[0] if rest else None
    if horizons is None:
        metrics, windows = predict_trajectory(traj, config)
        extra = ()
    else:
        from cobot_analysis.models.prediction.horizons import horizon_rows

        runs = trajectory_runs(traj, config, horizons[0])
        metrics, windows = setting_rows(traj, config, runs)
        extra = (horizon_rows(traj, config, horizons[0], horizons[1], runs),)
    if work is not None:
        try:
            work.save(traj, config, metrics, windows)
            if extra:
                work.save_horizons(traj, config, horizons, *extra[0])
        except OSError:
            pass
    return (traj, metrics, windows, *extra)


# ---- the resumable sweep ----------------------------------------------------------------------
def code_digest() -> str:
    """Hash of the modules that determine a prediction (a change invalidates the work directory)."""
    from cobot_analysis import __version__
    from cobot_analysis.models import dynamics, presets
    from cobot_analysis.models.oc import problem
    from cobot_analysis.models.prediction import base, baselines, errors, goal, predictor

    h = hashlib.sha256(__version__.encode())
    for mod in (base, baselines, dynamics, problem, predictor, goal, errors, presets):
        h.update(Path(mod.__file__).read_bytes())
    return h.hexdigest()[:12]


class WorkDir:
    """Finished (trajectory, setting) results of sweeps: ``<root>/<key>.{metrics,windows}.parquet``.

    The key hashes the trajectory, the setting, every other sweep parameter and the prediction
    code, so a finished result is reused by any later sweep that needs exactly it (e.g. after an
    interruption, or when a setting is added) and never when something that changes it changed.
    """

    def __init__(self, root: Path):
        self.root = Path(root)
        self._code = code_digest()

    def key(self, traj: Trajectory, config: SweepConfig, setting: tuple[int, int]) -> str:
        # the whole convention, not its name: a convention changed in any element gets other keys
        params = {**asdict(config), "settings": list(setting), "code": self._code, "trajectory": traj.digest()}
        return hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()[:24]

    def _paths(self, key: str) -> tuple[Path, Path]:
        return self.root / f"{key}.metrics.parquet", self.root / f"{key}.windows.parquet"

    def missing(self, traj: Trajectory, config: SweepConfig) -> tuple[tuple[int, int], ...]:
        """The settings of ``config`` not yet finished for ``traj``."""
        return tuple(s for s in config.settings if not self._paths(self.key(traj, config, s))[0].is_file())

    def save(self, traj: Trajectory, config: SweepConfig, metrics: pd.DataFrame, windows: pd.DataFrame) -> None:
        """Per setting; windows first, metrics last: the metrics file marks the result finished."""
        self.root.mkdir(parents=True, exist_ok=True)
        for n0, n_oc in config.settings:
            m, w = self._paths(self.key(traj, config, (n0, n_oc)))
            for df, path in ((windows, w), (metrics, m)):
                part = df[(df["n0"] == n0) & (df["n_oc"] == n_oc)]
                tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
                part.to_parquet(tmp, index=False)
                os.replace(tmp, path)

    def load(self, traj: Trajectory, config: SweepConfig) -> tuple[pd.DataFrame, pd.DataFrame]:
        parts = [self._paths(self.key(traj, config, s)) for s in config.settings]
        return (pd.concat([pd.read_parquet(m) for m, _ in parts], ignore_index=True),
                pd.concat([pd.read_parquet(w) for _, w in parts], ignore_index=True))

    def _horizon_paths(self, traj: Trajectory, config: SweepConfig, horizons: tuple) -> tuple[Path, Path]:
        n0, hs = horizons
        key = self.key(traj, config, ("horizons", int(n0), *map(int, hs)))  # settings replaced: the horizons at N0
        return self.root / f"{key}.horizons.parquet", self.root / f"{key}.inference.parquet"

    def horizons_missing(self, traj: Trajectory, config: SweepConfig, horizons: tuple) -> bool:
        return not self._horizon_paths(traj, config, horizons)[0].is_file()

    def save_horizons(self, traj: Trajectory, config: SweepConfig, horizons: tuple, errors: pd.DataFrame,
                      inference: pd.DataFrame) -> None:
        """The horizon sweep's rows of ``traj`` (``horizons.horizon_rows``); the errors file, written last, marks them finished."""
        self.root.mkdir(parents=True, exist_ok=True)
        e, i = self._horizon_paths(traj, config, horizons)
        for df, path in ((inference, i), (errors, e)):
            tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
            df.to_parquet(tmp, index=False)
            os.replace(tmp, path)

    def load_horizons(self, traj: Trajectory, config: SweepConfig, horizons: tuple) -> tuple[pd.DataFrame, pd.DataFrame]:
        e, i = self._horizon_paths(traj, config, horizons)
        return pd.read_parquet(e), pd.read_parquet(i)

    def clear(self) -> None:
        shutil.rmtree(self.root, ignore_errors=True)


def run_sweep(trajectories: list[Trajectory], config: SweepConfig, work: WorkDir, *, jobs: int | None = None,
              scheduler: str | None = None, horizons: tuple | None = None) -> tuple[pd.DataFrame, pd.DataFrame, int]:
    """Predict every (trajectory, setting) not yet in ``work``; return (metrics, windows, number of
    trajectories resumed, i.e. with every setting already finished). ``horizons`` = (N0, horizon list):
    the horizon sweep too, from the same predictions, kept in ``work`` (``horizon_tables`` reads it)."""
    from dataclasses import replace

    from cobot_analysis.parallel import map_tasks

    todo = []
    for t in trajectories:
        missing = work.missing(t, config)
        if horizons is not None and work.horizons_missing(t, config, horizons):
            todo.append((t, config, work, horizons))  # one run serves every setting and the horizons
        elif missing:
            todo.append((t, replace(config, settings=missing), work))

    def keep(result) -> str:  # runs here as each trajectory arrives: save it unless its task did
        traj, metrics, windows, *extra = result
        partial = replace(config, settings=tuple(dict.fromkeys(zip(metrics["n0"], metrics["n_oc"]))))
        if work.missing(traj, partial):
            work.save(traj, partial, metrics, windows)
        if extra and work.horizons_missing(traj, config, horizons):
            work.save_horizons(traj, config, horizons, *extra[0])
        return traj.trial

    if todo:
        map_tasks(sweep_task, todo, jobs=jobs, scheduler=scheduler, description="predict", status=keep)
    parts = [work.load(t, config) for t in trajectories]
    metrics = pd.concat([p[0] for p in parts], ignore_index=True)
    windows = pd.concat([p[1] for p in parts], ignore_index=True)
    for col in ("convention", "study", "trial", "entity", "predictor"):
        windows[col] = windows[col].astype("category")
    return metrics, windows, len(trajectories) - len(todo)


def horizon_tables(trajectories: list[Trajectory], config: SweepConfig, work: WorkDir, horizons: tuple) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The horizon sweep's (errors, goal inference) of ``trajectories``, from ``work`` (``run_sweep(..., horizons=...)``)."""
    from cobot_analysis.models.prediction.horizons import GOAL_INFERENCE

    parts = [work.load_horizons(t, config, horizons) for t in trajectories]
    errors = pd.concat([p[0] for p in parts], ignore_index=True)
    infer = [p[1] for p in parts if len(p[1])]
    inference = pd.concat(infer, ignore_index=True) if infer else pd.DataFrame(columns=list(GOAL_INFERENCE.columns))
    return errors, inference


# ---- summaries --------------------------------------------------------------------------------
METRICS = ("delta_xy", "delta_theta", "d_pred", "ade", "fde")

PREDICTION_SUMMARY = TableSchema(
    name="prediction_summary",
    version=2,
    description="Per setting and predictor: mean and sd over trajectories of each metric, and its Pearson "
                "correlation with the global distance.",
    columns={
        "convention": _ID["convention"],
        "n0": Column("int", "-", "N0"),
        "n_oc": Column("int", "-", "N_OC"),
        "predictor": Column("string", "", "oc, cv or ctrv"),
        "metric": Column("string", "", "delta_xy, delta_theta, d_pred, ade or fde"),
        "unit": Column("string", "", "m or rad"),
        "n": Column("int", "-", "trajectories with a value"),
        "mean": Column("float", "", "mean over trajectories (unit in column unit)"),
        "sd": Column("float", "", "standard deviation over trajectories: sample (ddof 1, continuous) or population "
                                  "(ddof 0, published)"),
        "pearson_r": Column("float", "-", "Pearson r of the metric with the global distance"),
        "pearson_p": Column("float", "-", "two-sided p of the Pearson correlation"),
    },
)
PREDICTION_COMPARISON = TableSchema(
    name="prediction_comparison",
    version=2,
    description="OC predictor vs a baseline on the same windows: paired Wilcoxon signed-rank test over trajectories "
                "of delta_xy, overall and per start orientation.",
    columns={
        "convention": _ID["convention"],
        "n0": Column("int", "-", "N0"),
        "n_oc": Column("int", "-", "N_OC"),
        "baseline": Column("string", "", "cv or ctrv"),
        "group": Column("string", "", "'all', a start orientation (N, E, S, O), 'theta tracked', 'positions only' or "
                                      "a third of the path ('phase 0-33 %', ...)"),
        "n": Column("int", "-", "paired trajectories"),
        "oc_median": Column("float", "m", "median delta_xy of the OC predictor"),
        "baseline_median": Column("float", "m", "median delta_xy of the baseline"),
        "median_difference": Column("float", "m", "median of (OC - baseline) delta_xy; < 0: OC better"),
        "oc_wins": Column("float", "-", "share of trajectories where the OC delta_xy is smaller"),
        "oc_wins_windows": Column("float", "-", "share of used windows where the OC window error is smaller"),
        "wilcoxon_w": Column("float", "-", "Wilcoxon signed-rank statistic"),
        "wilcoxon_p": Column("float", "-", "two-sided p"),
        "effect_r": Column("float", "-", "matched-pairs rank-biserial correlation (> 0: OC better)"),
    },
)


def units(metric: str) -> str:
    return "rad" if metric == "delta_theta" else "m"


def summary_table(metrics: pd.DataFrame, convention: Convention = CONTINUOUS) -> pd.DataFrame:
    """Mean +- sd over trajectories per setting, predictor and metric (sd with the convention's
    ``sd_ddof``: sqrt(sum (v - mean)^2 / (n - ddof))); Pearson r with the global distance."""
    from scipy import stats

    ddof = convention.comparison.sd_ddof
    rows = []
    for (n0, n_oc, pred), g in metrics.groupby(["n0", "n_oc", "predictor"], sort=True):
        for metric in METRICS:
            ok = g[np.isfinite(g[metric]) & np.isfinite(g["global_distance"])]
            r = p = float("nan")
            if len(ok) > 2 and ok[metric].std() > 0 and ok["global_distance"].std() > 0:
                r, p = stats.pearsonr(ok[metric], ok["global_distance"])
            v = g[metric].dropna()
            rows.append({"convention": convention.name, "n0": n0, "n_oc": n_oc, "predictor": pred, "metric": metric, "unit": units(metric),
                         "n": len(v), "mean": v.mean() if len(v) else np.nan, "sd": v.std(ddof=ddof) if len(v) > ddof else np.nan,
                         "pearson_r": float(r), "pearson_p": float(p)})
    return pd.DataFrame(rows)


PHASES = ((0.0, 100 / 3), (100 / 3, 200 / 3), (200 / 3, 100.0))  # start, middle, end of the path (%)


def paired_row(oc: pd.Series, base: pd.Series, windows_won: float) -> dict:
    """Paired comparison of per-trajectory errors (OC vs baseline): medians, share won, Wilcoxon
    signed-rank test and the matched-pairs rank-biserial correlation r (> 0: OC smaller)."""
    from scipy import stats

    ok = oc.notna() & base.notna()
    oc, base = oc[ok], base[ok]
    diff = (oc - base).to_numpy()
    w = p = r = float("nan")
    nz = diff[diff != 0]
    if len(nz):
        res = stats.wilcoxon(oc, base)
        w, p = float(res.statistic), float(res.pvalue)
        ranks = stats.rankdata(np.abs(nz))
        r = float((ranks[nz < 0].sum() - ranks[nz > 0].sum()) / ranks.sum())
    return {"n": int(len(diff)), "oc_median": float(oc.median()), "baseline_median": float(base.median()),
            "median_difference": float(np.median(diff)) if len(diff) else float("nan"),
            "oc_wins": float((diff < 0).mean()) if len(diff) else float("nan"), "oc_wins_windows": windows_won,
            "wilcoxon_w": w, "wilcoxon_p": p, "effect_r": r}


def compare_table(metrics: pd.DataFrame, windows: pd.DataFrame, convention: Convention = CONTINUOUS) -> pd.DataFrame:
    """OC vs each baseline on delta_xy over the same windows, paired by trajectory (Wilcoxon):
    all trajectories, per start orientation, theta tracked or not, and per third of the path
    (there the per-trajectory error is the mean window error over the windows of that third)."""
    if "oc" not in set(metrics["predictor"]):
        return pd.DataFrame(columns=list(PREDICTION_COMPARISON.columns))
    traj_keys = ["study", "trial", "entity"]
    keys = traj_keys + ["n0", "n_oc"]
    wide = metrics.pivot_table(index=keys, columns="predictor", values="delta_xy").reset_index()
    info = metrics.drop_duplicates(keys).set_index(keys)[["start_orientation", "theta_tracked"]]
    wide = wide.join(info, on=keys)
    used = windows[windows["used"]]
    wwide = used.pivot_table(index=keys + ["k", "phase"], columns="predictor", values="error_xy", observed=True).reset_index()
    rows = []
    for baseline in [p for p in ("cv", "ctrv") if p in wide.columns]:
        for (n0, n_oc), g in wide.groupby(["n0", "n_oc"], sort=True):
            wg = wwide[(wwide["n0"] == n0) & (wwide["n_oc"] == n_oc)]
            groups = [("all", g)] + [(o, gg) for o, gg in g.groupby("start_orientation", sort=True) if o]
            if g["theta_tracked"].nunique() > 1:
                groups += [("theta tracked", g[g["theta_tracked"]]), ("positions only", g[~g["theta_tracked"]])]
            for name, gg in groups:
                ww = wg.merge(gg[traj_keys], on=traj_keys)
                won = float((ww["oc"] < ww[baseline]).mean()) if len(ww) else float("nan")
                rows.append({"convention": convention.name, "n0": n0, "n_oc": n_oc, "baseline": baseline, "group": name,
                             **paired_row(gg["oc"], gg[baseline], won)})
            for lo, hi in PHASES:
                ww = wg[(wg["phase"] >= lo) & ((wg["phase"] < hi) | (hi == 100.0))]
                per = ww.groupby(traj_keys, observed=True)[["oc", baseline]].mean()
                won = float((ww["oc"] < ww[baseline]).mean()) if len(ww) else float("nan")
                rows.append({"convention": convention.name, "n0": n0, "n_oc": n_oc, "baseline": baseline, "group": f"phase {lo:.0f}-{hi:.0f} %",
                             **paired_row(per["oc"], per[baseline], won)})
    return pd.DataFrame(rows, columns=list(PREDICTION_COMPARISON.columns))


def trajectory_horizons(traj, config, n0: int, horizons=None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Horizon errors of every predictor of ``config`` on one trajectory, and the goal inference rows
    (``horizons.horizon_rows`` of its own run; default horizons: ``horizons.HORIZONS``)."""
    from cobot_analysis.models.prediction.horizons import HORIZONS, horizon_rows

    return horizon_rows(traj, config, n0, HORIZONS if horizons is None else horizons, trajectory_runs(traj, replace(config, settings=()), n0))


def _horizons_task(item):
    traj, config, n0, horizons = item
    return trajectory_horizons(traj, config, n0, horizons)


def horizon_sweep(trajectories, config, n0: int = 50, horizons=None, *, jobs: int | None = None,
                  scheduler: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The horizon sweep on its own: ``trajectory_horizons`` over ``trajectories`` in parallel (``parallel.map_tasks``):
    (errors, inference). The predict stage gets the same rows from its sweep's runs (``run_sweep(..., horizons=...)``)."""
    from cobot_analysis.models.prediction.base import check_setting
    from cobot_analysis.models.prediction.horizons import GOAL_INFERENCE, HORIZONS
    from cobot_analysis.parallel import map_tasks

    check_setting(n0, n0 + 1)
    config = replace(config, settings=((n0, n0 + 1),))
    results = map_tasks(_horizons_task, [(t, config, n0, tuple(HORIZONS if horizons is None else horizons)) for t in trajectories], jobs=jobs, scheduler=scheduler,
                        description="horizons")
    errors = pd.concat([r[0] for r in results], ignore_index=True)
    infer = [r[1] for r in results if len(r[1])]
    inference = pd.concat(infer, ignore_index=True) if infer else pd.DataFrame(columns=list(GOAL_INFERENCE.columns))
    return errors, inference
