"""Readers of the published CoBot data (``../shared/datasets/*/README.md``) -> trajectories.

Both datasets are already time-normalised (500 samples over 0..100 % of the motion) and enter the
pipeline at the trajectory stage: they are written in the ``schema.TRAJECTORIES`` layout, with
the data-quality facts their READMEs mention detected (not assumed) and reported in the stage's
``results.md``.

walking-2020 (``<L><code>.dat``: 11 blocks x 6 rows x 500 samples; block 0 the authors' mean,
blocks 1..10 subjects 1..10; rows x, y, vx, vy, gamma, theta):
- a subject block holds one trajectory per subject and condition; it may itself be the authors'
  per-subject mean over that subject's trials (the data hold one per subject and condition), so it
  is written as ``kind='trial'``, ``n_trials=1``; block 0 as ``kind='mean'``, ``n_trials=10``.
- orientation missing = rows 4 and 5 all exactly zero -> theta = gamma = NaN, quality
  ``orientation_missing`` (positions kept).
- implausible gamma (criterion of this pipeline, documented in results.md): over the middle of the
  path (20-80 % of the samples, where the walker is under way and the tangent is well defined),
  either the median |gamma| exceeds ``GAMMA_LIMIT`` = 0.5 rad (29 deg: a person walking forward
  faces the direction of travel within a few tens of degrees; pelvis yaw oscillates by about
  +-5-10 deg), or gamma disagrees with theta minus the heading of the CoM path
  (median |wrap(theta - atan2(dy, dx) - gamma)| > ``GAMMA_CONSISTENCY`` = 0.2 rad). Flagged
  ``implausible_gamma``; values are kept, never dropped.
- time and travel_time are NaN (durations were not published); travelled_distance = |end - start|;
  theta as published (unwrapped); gamma wrapped to (-pi, pi].

pair-carriage-2022 (``dK_pJ_COLOR_D_mean.json``): mean trajectories per goal x direction x
scenario x end configuration x entity, ``kind='mean'`` with ``n_trials = nb``. Scenario 1/2/3 from
``Sujet 1`` / ``Sujet 2`` / ``Sujet 1 et 2``; the pooled ``All data`` forward means have a null
scenario and ``all`` in their trial id; returns hold only ``All data`` and are scenario 3 by design.
Trial id: ``<goal>_<direction>_<sc1|sc2|sc3|all>_<end|init><degrees>``, e.g.
``d1_p4_gris_forward_sc3_end+180``. Angles were averaged as plain numbers by the authors; a mean
whose final (forward) or initial (return) table orientation is more than
``END_ORIENTATION_TOLERANCE`` from its configuration key modulo 2 pi is flagged
``plain_angle_mean`` on its three entities. Also written: ``durations.parquet`` (DURATIONS) and
``subject_wrt_table.parquet`` (SUBJECT_WRT_TABLE, the input of the reconstruction, docs/methods.md
sec. 8).
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.angles import angle_diff, wrap
from cobot_analysis.console import track
from cobot_analysis.design import WALKING_CONDITIONS, WALKING_GOAL
from cobot_analysis.errors import InputError
from cobot_analysis.schema import LAB_EXTENT, TRAJECTORIES, Column, TableSchema

WALKING = "walking-2020"
PAIRS = "pair-carriage-2022"
DATASETS = (WALKING, PAIRS)
N_SAMPLES = 500
N_SUBJECTS = 10
GAMMA_WINDOW = (0.2, 0.8)  # fraction of the samples where gamma is judged
GAMMA_LIMIT = 0.5  # rad
GAMMA_CONSISTENCY = 0.2  # rad
END_ORIENTATION_TOLERANCE = 0.35  # rad (20 deg)
START_END_TOLERANCE = 1e-3  # m, StartAndEnd.dat row vs first/last sample of a mean
PAIR_SCENARIOS = {"Sujet 1": 1, "Sujet 2": 2, "Sujet 1 et 2": 3, "All data": None}
PAIR_ENTITIES = {"Sujet 1": "subject1", "Sujet 2": "subject2", "Table": "table"}
DURATION_FILES = {1: "time_and_vel_sub1_leader.json", 2: "time_and_vel_sub2_leader.json", 3: "time_and_vel_sub1_2_leader.json"}
PAIR_GOAL_STEMS = ("d1_p4_gris", "d1_p4_jaune", "d1_p5_gris", "d1_p5_jaune", "d1_p6_gris", "d1_p6_jaune",
                   "d2_p7_gris", "d2_p7_jaune", "d3_p7_gris")
REMEDY_DATASET = "point to the published dataset folder (see its README.md) and restore missing or damaged files"

DURATIONS = TableSchema(
    name="durations",
    version=1,
    description="Pair study: duration and mean velocity of each published trial (one per pair, goal, scenario, direction).",
    columns={
        "study": Column("string", "", "pair-carriage-2022"),
        "pair": Column("string", "", "pair id P01..P20 (order of the published files)"),
        "subject1": Column("string", "", "Subject 1 name as published"),
        "subject2": Column("string", "", "Subject 2 name as published"),
        "scenario": Column("int", "-", "1 = S1 leader, 2 = S2 leader, 3 = both know the goal (returns: 3)"),
        "condition": Column("string", "", "goal stem, e.g. d1_p4_gris"),
        "configuration": Column("string", "", "end configuration family: gris (0/pi) or jaune (+-pi/2)"),
        "direction": Column("string", "", "forward or return"),
        "duration": Column("float", "s", "carriage duration (onset to offset)"),
        "mean_velocity": Column("float", "m/s", "mean velocity of the table over the carriage"),
    },
)

SUBJECT_WRT_TABLE = TableSchema(
    name="subject_wrt_table",
    version=1,
    description="Pair study: mean pose of each subject in the table frame, scenario 3, per normalised sample (docs/methods.md sec. 8).",
    columns={
        "entity": Column("string", "", "subject1 or subject2"),
        "direction": Column("string", "", "forward or return"),
        "sample": Column("int", "-", "sample index 0..N-1"),
        "phase": Column("float", "%", "100 * sample / (N - 1)"),
        "x_rel": Column("float", "m", "position along the table's long axis"),
        "y_rel": Column("float", "m", "position across the table"),
        "theta_rel": Column("float", "rad", "orientation relative to the table's long axis"),
    },
)


# ---- helpers --------------------------------------------------------------------------------------
def _require(directory: Path, names: list[str]) -> None:
    if not directory.is_dir():
        raise InputError("dataset folder not found", path=directory, remedy=REMEDY_DATASET)
    missing = [n for n in names if not (directory / n).is_file()]
    if missing:
        more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
        raise InputError(f"dataset incomplete: {missing[0]}{more} missing ({', '.join(missing[:5])})", path=directory / missing[0],
                         remedy=REMEDY_DATASET)


def _load_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid JSON ({type(exc).__name__}: {exc})", path=path, remedy=REMEDY_DATASET) from exc


def _load_matrix(path: Path, shape: tuple[int, int]) -> np.ndarray:
    try:
        a = np.loadtxt(path, ndmin=2)
    except ValueError as exc:
        raise InputError(f"not a whitespace-separated numeric matrix ({exc})", path=path, remedy=REMEDY_DATASET) from exc
    if a.shape != shape:
        raise InputError(f"has {a.shape[0]} x {a.shape[1]} values, {shape[0]} x {shape[1]} expected", path=path, remedy=REMEDY_DATASET)
    if not np.isfinite(a).all():
        raise InputError("contains NaN or infinite values", path=path, remedy=REMEDY_DATASET)
    return a


def _in_lab(xy: np.ndarray, path: Path, where: str = "positions") -> None:
    """Positions (m) within ``LAB_EXTENT`` of the lab origin: farther ones are not in metres, or corrupt."""
    if np.abs(xy).max(initial=0.0) > LAB_EXTENT:
        raise InputError(f"{where} reach {np.abs(xy).max():g} m, beyond the lab (|x|, |y| <= {LAB_EXTENT:g} m)", path=path,
                         remedy=f"positions are in metres: {REMEDY_DATASET}")


def _array(value: Any, path: Path, where: str) -> np.ndarray:
    a = np.asarray(value, dtype=float) if isinstance(value, list) else np.empty(0)
    if a.shape != (N_SAMPLES,) or not np.isfinite(a).all():
        raise InputError(f"{where}: expected {N_SAMPLES} finite numbers", path=path, remedy=REMEDY_DATASET)
    return a


def _long(meta: pd.DataFrame, arrays: dict[str, np.ndarray]) -> pd.DataFrame:
    """Trajectory rows (one per trajectory) x (n, N) arrays -> long TRAJECTORIES table."""
    n, n_samples = next(iter(arrays.values())).shape
    df = meta.loc[meta.index.repeat(n_samples)].reset_index(drop=True)
    sample = np.tile(np.arange(n_samples), n)
    df["sample"] = sample
    df["phase"] = 100.0 * sample / (n_samples - 1)
    for name, a in arrays.items():
        df[name] = a.reshape(-1)
    for name, col in TRAJECTORIES.columns.items():
        if name not in df.columns:
            df[name] = np.nan if col.dtype == "float" else None
    dtypes = {"string": "string", "int": "Int64", "float": "float64", "bool": "bool"}
    df = df.astype({c: dtypes[TRAJECTORIES.columns[c].dtype] for c in df.columns if c in TRAJECTORIES.columns})
    return df[[c for c in TRAJECTORIES.columns if c in df.columns]]


def _flags(*pairs: tuple[np.ndarray, str]) -> np.ndarray:
    """';'-joined quality flags per row from (boolean mask, flag) pairs; 'ok' when none."""
    n = len(pairs[0][0])
    out = []
    for i in range(n):
        flags = [f for mask, f in pairs if mask[i]]
        out.append(";".join(flags) if flags else "ok")
    return np.array(out, dtype=object)


# ---- walking-2020 ---------------------------------------------------------------------------------
def gamma_checks(x: np.ndarray, y: np.ndarray, theta: np.ndarray, gamma: np.ndarray,
                 limit: float = GAMMA_LIMIT, consistency: float = GAMMA_CONSISTENCY) -> tuple[np.ndarray, np.ndarray]:
    """Implausible-gamma tests over the 20-80 % window, per row of (n, N) arrays.

    Returns (too_large, inconsistent): median |wrap(gamma)| > ``limit``, and median
    |wrap(theta - atan2(dy, dx) - gamma)| > ``consistency`` (heading from central differences).
    """
    n_samples = x.shape[-1]
    lo, hi = (int(round(f * (n_samples - 1))) for f in GAMMA_WINDOW)
    window = slice(lo, hi + 1)
    heading = np.arctan2(np.gradient(y, axis=-1), np.gradient(x, axis=-1))
    too_large = np.median(np.abs(wrap(gamma[:, window])), axis=-1) > limit
    mismatch = np.median(np.abs(angle_diff(theta[:, window] - heading[:, window], gamma[:, window])), axis=-1)
    return too_large, mismatch > consistency


def read_walking_2020(directory: str | os.PathLike, gamma_limit: float = GAMMA_LIMIT) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The 40 condition files -> (trajectories: 400 subject + 40 mean trajectories, facts for the report)."""
    directory = Path(directory)
    _require(directory, [f"{c}.dat" for c in WALKING_CONDITIONS] + ["StartAndEnd.dat"])
    blocks = np.stack([_load_matrix(directory / f"{c}.dat", (66, N_SAMPLES)).reshape(11, 6, N_SAMPLES)
                       for c in track(WALKING_CONDITIONS, "walking-2020")])  # (40, 11, 6, N)
    for c, block in zip(WALKING_CONDITIONS, blocks):
        _in_lab(block[:, :2], directory / f"{c}.dat", "x, y (rows 1-2 of each block)")
    conds = np.repeat(np.array(WALKING_CONDITIONS), 11)
    block = np.tile(np.arange(11), len(WALKING_CONDITIONS))
    b = blocks.reshape(-1, 6, N_SAMPLES)
    x, y, vx, vy, gamma, theta = (b[:, k] for k in range(6))
    missing = np.all(b[:, 4:6] == 0.0, axis=(1, 2))
    too_large, inconsistent = gamma_checks(x, y, theta, gamma, limit=gamma_limit)
    implausible = (too_large | inconsistent) & ~missing
    theta = np.where(missing[:, None], np.nan, theta)
    gamma = np.where(missing[:, None], np.nan, wrap(gamma))
    is_mean = block == 0
    subject = np.array([None] + [f"S{k:02d}" for k in range(1, 11)], dtype=object)[block]
    meta = pd.DataFrame({
        "study": WALKING,
        "trial": [f"{c}_{'mean' if k == 0 else f'S{k:02d}'}" for c, k in zip(conds, block)],
        "kind": np.where(is_mean, "mean", "trial"),
        "n_trials": np.where(is_mean, N_SUBJECTS, 1),
        "subject": subject,
        "condition": conds,
        "entity": "walker",
        "travelled_distance": np.hypot(x[:, -1] - x[:, 0], y[:, -1] - y[:, 0]),
        "quality": _flags((missing, "orientation_missing"), (implausible, "implausible_gamma")),
    })
    df = _long(meta, {"x": x, "y": y, "theta": theta, "gamma": gamma, "vx": vx, "vy": vy})

    # facts for the report
    start_end = _load_matrix(directory / "StartAndEnd.dat", (len(WALKING_CONDITIONS), 4))
    mean_se = np.stack([blocks[:, 0, 0, 0], blocks[:, 0, 1, 0], blocks[:, 0, 0, -1], blocks[:, 0, 1, -1]], axis=1)
    dist = np.abs(start_end[:, None, :] - mean_se[None, :, :]).max(axis=-1)  # row i vs condition j
    match = dist.argmin(axis=1)
    subj = ~is_mean
    plain_mean_xy = np.abs(blocks[:, 1:, :2].mean(axis=1) - blocks[:, 0, :2]).max()
    facts = {
        "n_subject": int(subj.sum()), "n_mean": int(is_mean.sum()),
        "orientation_missing_subject": int((missing & subj).sum()),
        "orientation_missing_mean": int((missing & is_mean).sum()),
        "orientation_missing_means": sorted(conds[missing & is_mean].tolist()),
        "orientation_missing_per_subject": {f"S{k:02d}": int((missing & (block == k)).sum()) for k in range(1, 11)},
        "implausible_per_subject": {f"S{k:02d}": int((implausible & (block == k)).sum()) for k in range(1, 11)},
        "implausible_too_large": int((too_large & ~missing & subj).sum()),
        "implausible_inconsistent": int((inconsistent & ~missing & subj).sum()),
        "implausible_subject": int((implausible & subj).sum()),
        "implausible_mean": int((implausible & is_mean).sum()),
        "implausible_means": sorted(conds[implausible & is_mean].tolist()),
        "end_heading_off": int((np.abs(angle_diff(theta[:, -1], WALKING_GOAL[2])) > GAMMA_LIMIT)[subj & ~missing].sum()),
        "with_orientation_subject": int((~missing & subj).sum()),
        "gamma_limit": gamma_limit,
        "median_abs_gamma_subject": float(np.nanmedian(np.abs(gamma[subj & ~missing][:, 100:401]))),
        "mean_abs_gamma_subject": float(np.nanmean(np.abs(gamma[subj & ~missing]))),
        "start_end_order_ok": bool((match == np.arange(len(match))).all() and (dist.min(axis=1) < START_END_TOLERANCE).all()),
        "start_end_max_error": float(dist[np.arange(len(match)), np.arange(len(match))].max()),
        "start_end_next_best": float(np.sort(dist, axis=1)[:, 1].min()),
        "start_end_mismatches": [(WALKING_CONDITIONS[i], WALKING_CONDITIONS[j]) for i, j in enumerate(match) if i != j],
        "mean_xy_is_plain_mean": float(plain_mean_xy),
    }
    return df, facts


_KEY = re.compile(r"^Orientation_Table_(End|Init)\s*:\s*(-?[0-9.]+(?:e-?\d+)?)$")


def _orientation_key(key: str, path: Path) -> tuple[str, float]:
    m = _KEY.match(key.strip())
    if not m:
        raise InputError(f"unexpected orientation key {key!r}", path=path, remedy=REMEDY_DATASET)
    return m.group(1).lower(), float(m.group(2))


def _pair_files() -> list[str]:
    return [f"{g}_{d}_mean.json" for g in PAIR_GOAL_STEMS for d in (1, 2)]


def read_pair_carriage_2022(directory: str | os.PathLike) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame, dict[str, Any]]:
    """-> (trajectories of the published means, durations, subject_wrt_table, facts for the report)."""
    directory = Path(directory)
    _require(directory, _pair_files() + list(DURATION_FILES.values()) + ["start_and_end.json", "subject1_wrt_table.dat",
                                                                         "subject2_wrt_table.dat"])
    rows: list[dict[str, Any]] = []
    arrays: dict[str, list[np.ndarray]] = {"x": [], "y": [], "theta": [], "gamma": []}
    weighted_xy_error = 0.0
    all_data_angle_offsets: list[tuple[str, str, str, float]] = []
    for goal in track(PAIR_GOAL_STEMS, "pair-carriage-2022"):
        family = goal.rsplit("_", 1)[1]
        for d, direction in ((1, "forward"), (2, "return")):
            path = directory / f"{goal}_{d}_mean.json"
            doc = _load_json(path)
            if not isinstance(doc, dict) or not isinstance(doc.get("Trajectoires_Moyennes"), dict):
                raise InputError("no 'Trajectoires_Moyennes' object", path=path, remedy=REMEDY_DATASET)
            means = doc["Trajectoires_Moyennes"]
            if set(means) != set(PAIR_ENTITIES):
                raise InputError(f"entities {sorted(means)} instead of {sorted(PAIR_ENTITIES)}", path=path, remedy=REMEDY_DATASET)
            for ent_key, entity in PAIR_ENTITIES.items():
                for scen_key, by_key in means[ent_key].items():
                    if scen_key not in PAIR_SCENARIOS:
                        raise InputError(f"unknown scenario {scen_key!r}", path=path, remedy=REMEDY_DATASET)
                    scenario = PAIR_SCENARIOS[scen_key] if direction == "forward" else 3
                    for key, leaf in by_key.items():
                        which, angle = _orientation_key(key, path)
                        where = f"{ent_key} / {scen_key} / {key}"
                        try:
                            nb = int(leaf["nb"])
                            x, y = _array(leaf["x"], path, where + " / x"), _array(leaf["y"], path, where + " / y")
                            _in_lab(np.stack([x, y]), path, where + " / x, y")
                            theta = _array(leaf["Orientation_Globale"], path, where + " / Orientation_Globale")
                            gamma = _array(leaf["Orientation_Locale"], path, where + " / Orientation_Locale")
                        except (KeyError, TypeError, ValueError) as exc:
                            raise InputError(f"{where}: missing or bad field ({exc})", path=path, remedy=REMEDY_DATASET) from exc
                        scen_tag = "all" if direction == "forward" and scenario is None else f"sc{scenario}"
                        rows.append({
                            "study": PAIRS, "trial": f"{goal}_{direction}_{scen_tag}_{which}{np.degrees(angle):+.0f}",
                            "kind": "mean", "n_trials": nb, "condition": goal, "direction": direction, "scenario": scenario,
                            "configuration": family, "end_orientation": angle, "entity": entity, "source_scenario": scen_key,
                            "travelled_distance": float(np.hypot(x[-1] - x[0], y[-1] - y[0])),
                            "table_angle_error": float(abs(angle_diff(theta[-1 if direction == "forward" else 0], angle))),
                        })
                        for name, a in (("x", x), ("y", y), ("theta", theta), ("gamma", wrap(gamma))):
                            arrays[name].append(a)
                # pooled "All data" vs the nb-weighted mean of the scenario means (forward files)
                if direction == "forward" and "All data" in means[ent_key]:
                    for key, pooled in means[ent_key]["All data"].items():
                        parts = [means[ent_key][s][key] for s in ("Sujet 1", "Sujet 2", "Sujet 1 et 2") if key in means[ent_key].get(s, {})]
                        if not parts:
                            continue
                        w = np.array([p["nb"] for p in parts], dtype=float)
                        for name in ("x", "y"):
                            pm = np.average([p[name] for p in parts], axis=0, weights=w)
                            weighted_xy_error = max(weighted_xy_error, float(np.abs(pm - np.asarray(pooled[name])).max()))
                        pt = np.average([p["Orientation_Globale"] for p in parts], axis=0, weights=w)
                        off = float(np.abs(angle_diff(pt, np.asarray(pooled["Orientation_Globale"]))).max())
                        if off > 1e-6:
                            all_data_angle_offsets.append((f"{goal}_{direction}", ent_key, key, off))
    meta = pd.DataFrame(rows)
    # a mean whose table ends (forward) / starts (return) away from its configuration: all 3 entities flagged
    mean_id = meta["trial"]
    bad_ids = set(mean_id[(meta["entity"] == "table") & (meta["table_angle_error"] > END_ORIENTATION_TOLERANCE)])
    plain = mean_id.isin(bad_ids).to_numpy()
    meta["quality"] = _flags((plain, "plain_angle_mean"))
    facts = _pair_facts(meta, bad_ids, weighted_xy_error, all_data_angle_offsets)
    traj = _long(meta.drop(columns=["source_scenario", "table_angle_error"]), {k: np.stack(v) for k, v in arrays.items()})
    durations = read_pair_durations(directory)
    facts.update(_duration_facts(durations))
    facts.update(_start_end_facts(directory, meta, {k: np.stack(v) for k, v in arrays.items()}))
    return traj, durations, read_subject_wrt_table(directory), facts


def read_pair_durations(directory: str | os.PathLike) -> pd.DataFrame:
    """The three ``time_and_vel_*.json`` files -> DURATIONS table (pairs numbered P01.. in file order)."""
    directory = Path(directory)
    rows = []
    pair_ids: dict[str, str] = {}
    for scenario, name in DURATION_FILES.items():
        path = directory / name
        doc = _load_json(path)
        if not isinstance(doc, dict):
            raise InputError("expected an object keyed by pair", path=path, remedy=REMEDY_DATASET)
        for pair_key, goals in doc.items():
            m = re.match(r"^Sujet1_(.+)&Sujet2_(.+)$", pair_key)
            if not m or not isinstance(goals, dict):
                raise InputError(f"unexpected pair key {pair_key!r}", path=path, remedy=REMEDY_DATASET)
            pair = pair_ids.setdefault(pair_key, f"P{len(pair_ids) + 1:02d}")
            for stem, v in goals.items():
                goal, _, d = stem.rpartition("_")
                if goal not in PAIR_GOAL_STEMS or d not in ("1", "2"):
                    raise InputError(f"unexpected goal {stem!r} for pair {pair_key!r}", path=path, remedy=REMEDY_DATASET)
                try:
                    duration, velocity = float(v["Duration (s)"]), float(v["Mean_velocity (m.s^-1)"])
                except (KeyError, TypeError, ValueError) as exc:
                    raise InputError(f"{pair_key} / {stem}: missing or bad duration/velocity ({exc})", path=path, remedy=REMEDY_DATASET) from exc
                rows.append({"study": PAIRS, "pair": pair, "subject1": m.group(1), "subject2": m.group(2),
                             "scenario": 3 if d == "2" else scenario, "condition": goal, "configuration": goal.rsplit("_", 1)[1],
                             "direction": "forward" if d == "1" else "return", "duration": duration, "mean_velocity": velocity})
    df = pd.DataFrame(rows)
    return df.astype({"study": "string", "pair": "string", "subject1": "string", "subject2": "string", "scenario": "Int64", "condition": "string",
                      "configuration": "string", "direction": "string"})


def read_subject_wrt_table(directory: str | os.PathLike) -> pd.DataFrame:
    """``subject{1,2}_wrt_table.dat`` (rows x_fwd x_ret y_fwd y_ret theta_fwd theta_ret) -> SUBJECT_WRT_TABLE."""
    directory = Path(directory)
    parts = []
    for k in (1, 2):
        a = _load_matrix(directory / f"subject{k}_wrt_table.dat", (6, N_SAMPLES))
        for j, direction in enumerate(("forward", "return")):
            parts.append(pd.DataFrame({
                "entity": f"subject{k}", "direction": direction, "sample": np.arange(N_SAMPLES),
                "phase": 100.0 * np.arange(N_SAMPLES) / (N_SAMPLES - 1),
                "x_rel": a[j], "y_rel": a[2 + j], "theta_rel": a[4 + j]}))
    return pd.concat(parts, ignore_index=True).astype({"entity": "string", "direction": "string"})


def _pair_facts(meta: pd.DataFrame, bad_ids: set[str], weighted_xy_error: float,
                all_data_angle_offsets: list[tuple[str, str, str, float]]) -> dict[str, Any]:
    table = meta[meta["entity"] == "table"]
    fwd = table[table["direction"] == "forward"]
    ret = table[table["direction"] == "return"]
    counts = {f"forward_sc{s}": int(fwd.loc[fwd["scenario"] == s, "n_trials"].sum()) for s in (1, 2, 3)}
    return {
        **counts,
        "forward_all": int(fwd.loc[fwd["scenario"].isna(), "n_trials"].sum()),
        "return_all": int(ret["n_trials"].sum()),
        "n_means": {f"forward_sc{s}": int((fwd["scenario"] == s).sum()) for s in (1, 2, 3)}
        | {"forward_all": int(fwd["scenario"].isna().sum()), "return": len(ret)},
        "n_trajectories": len(meta),
        "plain_angle_means": sorted(bad_ids),
        "all_data_weighted_xy_error": weighted_xy_error,
        "all_data_angle_offsets": all_data_angle_offsets,
    }


def _duration_facts(durations: pd.DataFrame) -> dict[str, Any]:
    fwd = durations[durations["direction"] == "forward"]
    step = np.abs(durations["duration"] / 0.005 - np.round(durations["duration"] / 0.005)).max()
    return {
        "durations_pairs": int(durations["pair"].nunique()),
        "durations_forward": {int(s): int(n) for s, n in fwd.groupby("scenario").size().items()},
        "durations_return": int((durations["direction"] == "return").sum()),
        "durations_on_200hz_grid": bool(step < 1e-6),
    }


def _start_end_facts(directory: Path, meta: pd.DataFrame, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    """start_and_end.json leaves vs the first and last samples of the matching means."""
    path = directory / "start_and_end.json"
    doc = _load_json(path)
    index = {(r.condition, r.direction, r.source_scenario, r.entity, round(r.end_orientation, 9)): i
             for i, r in enumerate(meta.itertuples())}
    checked = matched = 0
    worst = 0.0
    for stem, by_entity in doc.items():
        goal, _, d = stem.rpartition("_")
        direction = "forward" if d == "1" else "return"
        for ent_key, sub in by_entity.items():
            entity = PAIR_ENTITIES.get(ent_key)
            leaves = sub.items() if direction == "forward" else [("All data", sub)]
            for scen_key, by_key in leaves:
                for key, leaf in by_key.items():
                    _, angle = _orientation_key(key, path)
                    i = index.get((goal, direction, scen_key, entity, round(angle, 9)))
                    checked += 1
                    if i is None:
                        continue
                    got = np.array([[arrays["x"][i][0], arrays["y"][i][0]], [arrays["x"][i][-1], arrays["y"][i][-1]]])
                    err = float(np.abs(np.asarray(leaf, dtype=float)[:, :2] - got).max())
                    worst = max(worst, err)
                    matched += err < 1e-9
    return {"start_end_checked": checked, "start_end_matched": int(matched), "start_end_worst": worst}
