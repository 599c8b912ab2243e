"""The tables the declared analyses run on ("sources"), derived from the workspace outputs.

Each source is a DataFrame with the columns listed in ``SOURCE_COLUMNS`` (checked before any
test runs). A question of ``pipelines/*.toml`` names a source, filters its rows, and tests a value
column across groups:

- ``trials``: one row per trajectory (trial level): metadata, travel time, travelled distance.
- ``durations``: one row per trial: travel time of the carriage (pair study: from durations.parquet
  when the workspace has one, e.g. the published data, else from the table trajectories).
- ``pair_durations``: the mean duration per pair, direction and scenario (pair-level tests).
- ``distances``: distances.parquet plus ``carrier`` (subject / table / walker),
  ``start_orientation`` (walking: N E S O, of the labels that are walking-2020 codes the trajectories agree with,
  ``design.design_codes``; none for a study's own labels) and ``distance_class`` (global distance < 3 m / > 3 m).
- ``choices``: pair study, one row per forward trial: chosen end orientation and whether it is
  optimal for Subject 1, Subject 2, the pair (``optimal_s1`` ...), with the chance of being optimal
  under a random choice (``chance_*``: 1 if both configurations are optimal, else 1/2).
- ``patterns``: pair study, one row per pair and goal: which scenarios ended in the same configuration.
- ``closer``: pair study, per pair, goal and entity whose three forward trials share the end
  orientation: is the scenario-3 path closer to the scenario-1 or to the scenario-2 path?
- ``return_variability``: pair study, per pair, goal and entity with 3 returns: Kruskal p across
  the returns of the sample-wise distances to their mean (Q4.3).
- ``pairs``: per pair and entity: mean individual-vs-mean d_xy, and weight/height differences
  when anthropometrics are given.
- ``gamma_as_files``: walking study with the published mean blocks, one row per subject trajectory:
  the subject-vs-mean angular distance as the authors' script computed it (docs/methods.md sec. 11):
  d_gamma = 1/N sum_i |wrap(gamma_s,i) - wrap(gamma_m,i)| on the N time samples, against the
  published mean block's gamma, with the marker-loss trajectories kept as their files hold them
  (gamma = 0, so their distance is the mean |gamma_m|, and 0 where the mean has no orientation
  either); ``d_gamma_loss_zero``: the same with the marker-loss rows at distance 0 (a switch).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from cobot_analysis.angles import wrap
from cobot_analysis.compare import TrajectorySet, plain_dtypes
from cobot_analysis.design import GLOBAL_DISTANCE_SPLIT, design_codes
from cobot_analysis.distances import optimal_configurations

_META = ["study", "trial", "kind", "subject", "pair", "condition", "direction", "scenario", "configuration",
         "end_orientation", "repetition", "entity"]
SOURCE_COLUMNS: dict[str, list[str]] = {
    "trials": [*_META, "travel_time", "travelled_distance", "global_distance", "orientation_missing", "quality"],
    "durations": ["study", "pair", "condition", "configuration", "direction", "scenario", "end_orientation", "duration"],
    "distances": ["comparison", *_META, "b_trial", "b_kind", "b_subject", "b_pair", "b_scenario", "b_direction",
                  "b_end_orientation", "b_repetition", "travel_time", "travelled_distance", "global_distance",
                  "orientation_change", "d_xy", "d_theta", "d_gamma", "carrier", "start_orientation", "distance_class",
                  "scenario_pair"],
    "pair_durations": ["study", "pair", "direction", "scenario", "duration", "n"],
    "choices": ["study", "pair", "condition", "scenario", "end_orientation", "optimal_s1", "optimal_s2", "optimal_pair",
                "chance_s1", "chance_s2", "chance_pair"],
    "patterns": ["study", "pair", "condition", "pattern"],
    "closer": ["study", "pair", "condition", "entity", "d_s3_s1", "d_s3_s2", "closer_to", "closer_s1"],
    "return_variability": ["study", "pair", "condition", "entity", "p", "significant"],
    "pairs": ["study", "pair", "entity", "d_xy", "weight_diff", "height_diff"],
    "gamma_as_files": ["study", "trial", "subject", "condition", "start_orientation", "orientation_missing", "d_gamma",
                       "d_gamma_loss_zero"],
}


def _empty(name: str) -> pd.DataFrame:
    return pd.DataFrame({c: pd.Series(dtype=object) for c in SOURCE_COLUMNS[name]})


def _conform(df: pd.DataFrame, name: str) -> pd.DataFrame:
    for c in SOURCE_COLUMNS[name]:
        if c not in df.columns:
            df[c] = None
    return df


def trials_source(ts: TrajectorySet) -> pd.DataFrame:
    m = ts.meta[ts.meta["kind"].eq("trial")].copy() if len(ts) else ts.meta.copy()
    if m.empty:
        return _empty("trials")
    idx = m.index.to_numpy()
    m["orientation_missing"] = ~np.isfinite(ts.theta[idx]).all(axis=1)
    carrier = m[m["entity"].isin(["walker", "table"])].drop_duplicates(["study", "trial"])
    m["global_distance"] = m.set_index(["study", "trial"]).index.map(
        carrier.set_index(["study", "trial"])["travelled_distance"]).to_numpy()
    return _conform(m.reset_index(drop=True), "trials")


def durations_source(trials: pd.DataFrame, durations: pd.DataFrame | None) -> pd.DataFrame:
    """Per-trial carriage durations: the published table if given, else the table trajectories."""
    if durations is not None and len(durations):
        d = plain_dtypes(durations.rename(columns={"duration_s": "duration"}))
        return _conform(d, "durations")
    t = trials[trials["entity"].eq("table") & trials["travel_time"].notna()] if len(trials) else trials
    if t.empty:
        return _empty("durations")
    return _conform(t.rename(columns={"travel_time": "duration"}).reset_index(drop=True), "durations")


def pair_durations_source(durations: pd.DataFrame) -> pd.DataFrame:
    """Pair-level travel times: the mean duration of each pair per direction and scenario (one value
    per pair, so that pairs with more trials do not weigh more and trials of a pair are not
    treated as independent)."""
    if durations.empty:
        return _empty("pair_durations")
    d = durations.dropna(subset=["pair", "duration"])
    out = d.groupby(["study", "pair", "direction", "scenario"], as_index=False).agg(duration=("duration", "mean"), n=("duration", "size"))
    return _conform(out, "pair_durations")


def start_orientations(ts: TrajectorySet | None) -> dict[tuple[str, str], str]:
    """(study, condition) -> start orientation letter of the walker conditions whose labels are walking-2020 codes
    the trajectories agree with (``design.design_codes``, judged per study on its first and last measured positions)."""
    if ts is None or not len(ts.meta):
        return {}
    finite = np.isfinite(ts.x) & np.isfinite(ts.y)
    rows, first = np.arange(len(ts.meta)), finite.argmax(axis=1)
    last = finite.shape[1] - 1 - finite[:, ::-1].argmax(axis=1)
    starts, ends = np.c_[ts.x[rows, first], ts.y[rows, first]], np.c_[ts.x[rows, last], ts.y[rows, last]]
    out = {}
    walker = ts.meta["entity"].eq("walker").to_numpy()
    for study, i in ts.meta[walker].groupby("study", sort=False).indices.items():
        idx = np.flatnonzero(walker)[i]
        codes, _ = design_codes(ts.meta["condition"].iloc[idx].astype(str), starts[idx], ends[idx])
        out.update({(str(study), c): w.orientation for c, w in codes.items()})
    return out


def distances_source(distances: pd.DataFrame | None, orientations: dict[tuple[str, str], str] | None = None) -> pd.DataFrame:
    """compare's distances, with ``orientations`` (``start_orientations``) as ``start_orientation``."""
    if distances is None or distances.empty:
        return _empty("distances")
    d = plain_dtypes(distances)
    d["carrier"] = d["entity"].map({"subject1": "subject", "subject2": "subject", "table": "table", "walker": "walker"})
    d["start_orientation"] = [(orientations or {}).get((str(s), str(c))) for s, c in zip(d["study"], d["condition"])]
    gd = d["global_distance"].astype(float)
    d["distance_class"] = np.where(gd.isna(), None, np.where(gd < GLOBAL_DISTANCE_SPLIT, "< 3 m", "> 3 m"))
    sa = pd.to_numeric(d.get("scenario"), errors="coerce")
    sb = pd.to_numeric(d.get("b_scenario"), errors="coerce")
    lo, hi = np.fmin(sa, sb), np.fmax(sa, sb)
    d["scenario_pair"] = [f"S{int(a)}-S{int(b)}" if np.isfinite(a) and np.isfinite(b) else None for a, b in zip(lo, hi)]
    return _conform(d, "distances")


def choices_source(trials: pd.DataFrame, tol: float = 0.05) -> pd.DataFrame:
    """Optimality of each chosen end configuration (docs/methods.md sec. 3).

    The distance D_k a configuration would cost Subject k is estimated as the mean travelled
    distance of Subject k over all forward trials of that goal ending in that orientation (all pairs,
    all scenarios); configurations within ``tol`` m of the best are all optimal.
    """
    f = trials[trials["direction"].eq("forward") & trials["entity"].isin(["subject1", "subject2"])] if len(trials) else trials
    if f.empty or f["end_orientation"].isna().all():
        return _empty("choices")
    f = f.assign(end=wrap(f["end_orientation"].astype(float)).round(3))
    cost = f.pivot_table(index=["study", "condition", "end"], columns="entity", values="travelled_distance", aggfunc="mean")
    cost["pair"] = cost.sum(axis=1, min_count=2)
    optimal = {}
    for (study, cond), g in cost.groupby(level=[0, 1]):
        ends = g.index.get_level_values(2)
        for who, col in (("s1", "subject1"), ("s2", "subject2"), ("pair", "pair")):
            opt = optimal_configurations(dict(zip(ends, g[col].to_numpy())), tol)
            # only one configuration ever chosen: optimality cannot be judged from the data
            optimal[(study, cond, who)] = opt if len(ends) > 1 else None
    rows = f[f["entity"].eq("subject1")].drop_duplicates(["study", "trial"])
    out = rows[["study", "pair", "condition", "scenario", "end_orientation", "end"]].copy()
    for who in ("s1", "s2", "pair"):
        sets = [optimal.get((s, c, who)) for s, c in zip(out["study"], out["condition"])]
        out[f"optimal_{who}"] = [None if o is None else e in o for o, e in zip(sets, out["end"])]
        out[f"chance_{who}"] = [None if o is None else len(o) / 2 for o in sets]
    return _conform(out.drop(columns="end").dropna(subset=["optimal_s1"]).reset_index(drop=True), "choices")


def patterns_source(trials: pd.DataFrame) -> pd.DataFrame:
    """Q1.2: per pair and goal, which scenarios ended in the same configuration."""
    f = trials[trials["direction"].eq("forward") & trials["entity"].eq("table")] if len(trials) else trials
    if f.empty:
        return _empty("patterns")
    f = f.assign(end=wrap(f["end_orientation"].astype(float)).round(2))
    w = f.pivot_table(index=["study", "pair", "condition"], columns="scenario", values="end", aggfunc="first")
    if not {1, 2, 3} <= set(w.columns):
        return _empty("patterns")
    w = w.dropna(subset=[1, 2, 3])

    def pattern(r) -> str:
        s12, s13, s23 = r[1] == r[2], r[1] == r[3], r[2] == r[3]
        if s12 and s13:
            return "all three"
        return "S1&S3 only" if s13 else "S2&S3 only" if s23 else "S1&S2 only" if s12 else "all different"

    out = w.reset_index()
    out["pattern"] = w.apply(pattern, axis=1).to_numpy()
    return _conform(out[["study", "pair", "condition", "pattern"]], "patterns")


def closer_source(distances: pd.DataFrame) -> pd.DataFrame:
    """Q1.3: scenario-3 path closer to scenario 1 or 2 (same pair, goal, entity, end orientation)."""
    d = distances[distances["comparison"].eq("scenario-scenario")] if len(distances) else distances
    if d.empty:
        return _empty("closer")
    d = d.assign(sp=d["scenario_pair"])
    w = d.pivot_table(index=["study", "pair", "condition", "entity"], columns="sp", values="d_xy", aggfunc="mean")
    if not {"S1-S3", "S2-S3"} <= set(w.columns):
        return _empty("closer")
    w = w.dropna(subset=["S1-S3", "S2-S3"]).reset_index()
    w = w.rename(columns={"S1-S3": "d_s3_s1", "S2-S3": "d_s3_s2"})
    w["closer_to"] = np.where(w["d_s3_s1"] < w["d_s3_s2"], "S1", "S2")
    w["closer_s1"] = w["closer_to"].eq("S1")
    return _conform(w, "closer")


def kruskal_rows(values: np.ndarray) -> np.ndarray:
    """Kruskal-Wallis p for many independent problems at once: ``values`` (G, k, n) = G problems of
    k groups of n values each. H = 12 / (M (M + 1)) sum_j R_j^2 / n - 3 (M + 1), M = k n, with the
    usual tie correction; p from chi^2 with k - 1 degrees of freedom (as scipy.stats.kruskal)."""
    from scipy import stats

    g, k, n = values.shape
    m = k * n
    flat = values.reshape(g, m)
    idx = np.argsort(flat, axis=1, kind="stable")
    srt = np.take_along_axis(flat, idx, axis=1)
    pos = np.broadcast_to(np.arange(m), (g, m))
    new = np.ones((g, m), dtype=bool)
    new[:, 1:] = srt[:, 1:] != srt[:, :-1]
    last = np.ones((g, m), dtype=bool)
    last[:, :-1] = new[:, 1:]
    start = np.maximum.accumulate(np.where(new, pos, 0), axis=1)  # first position of each tie block
    end = np.minimum.accumulate(np.where(last, pos, m - 1)[:, ::-1], axis=1)[:, ::-1]  # last position
    ranks = np.empty((g, m))
    np.put_along_axis(ranks, idx, (start + end) / 2.0 + 1.0, axis=1)  # average ranks, 1-based
    h = 12.0 / (m * (m + 1)) * (ranks.reshape(g, k, n).sum(axis=2) ** 2 / n).sum(axis=1) - 3 * (m + 1)
    t = (end - start + 1).astype(float)
    ties = 1 - (t ** 2 - 1).sum(axis=1) / (m ** 3 - m)  # sum over blocks of t^3 - t
    with np.errstate(invalid="ignore", divide="ignore"):
        return stats.chi2.sf(h / ties, k - 1)


def return_variability_source(ts: TrajectorySet, alpha: float = 0.05, n_points: int = 10) -> pd.DataFrame:
    """Q4.3: per pair, goal and entity with 3 returns, Kruskal across the returns of the distances
    |p_i - mean_i| to the mean of those returns, at ``n_points`` phases evenly spaced over 5-95 %
    of the path (vectorised over groups). Neighbouring samples of a path are strongly correlated:
    testing all N samples as independent values would make almost any difference significant, so
    a few well-separated phases are used (documented choice, configurable here)."""
    m = ts.meta
    if "direction" not in m.columns:
        return _empty("return_variability")
    sel = m[m["kind"].eq("trial") & m["direction"].eq("return")]
    keys = ["study", "pair", "condition", "entity"]
    sizes = sel.groupby(keys)["trial"].transform("size")
    sel = sel[sizes.eq(3)].sort_values(keys, kind="stable")
    if sel.empty:
        return _empty("return_variability")
    idx = sel.index.to_numpy().reshape(-1, 3)
    x, y = ts.x[idx], ts.y[idx]  # (G, 3, N)
    dev = np.hypot(x - x.mean(axis=1, keepdims=True), y - y.mean(axis=1, keepdims=True))
    cols = np.round(np.linspace(0.05, 0.95, n_points) * (ts.n_samples - 1)).astype(int)
    p = kruskal_rows(dev[:, :, cols])
    out = sel.iloc[::3][keys].reset_index(drop=True)
    out["p"], out["significant"] = p, p < alpha
    return _conform(out, "return_variability")


def read_anthropometrics(directory: Path | None) -> pd.DataFrame | None:
    """``pairs.csv`` (id, subject1, subject2) and ``subjects.csv`` (id, weight, height) of ``directory`` ->
    ``anthropometrics``; None when not available."""
    if directory is None:
        return None
    pairs_csv, subjects_csv = Path(directory) / "pairs.csv", Path(directory) / "subjects.csv"
    if not (pairs_csv.is_file() and subjects_csv.is_file()):
        return None
    return anthropometrics(pd.read_csv(subjects_csv), pd.read_csv(pairs_csv), directory)


def anthropometrics(subjects: pd.DataFrame, pairs: pd.DataFrame, path=None) -> pd.DataFrame | None:
    """A study's subjects (id, weight, height) and pairs (id, subject1, subject2) -> per pair
    |weight_1 - weight_2| (kg) and |height_1 - height_2| (m); None when the study has no pairs or no subjects.
    ``path``: where they come from, for the message of a table that lacks a column."""
    from cobot_analysis.errors import InputError
    from cobot_analysis.io.protocol import check_ids, id_text

    if pairs.empty or subjects.empty:
        return None
    need = {"id", "weight", "height"}
    if not need <= set(subjects.columns) or not {"id", "subject1", "subject2"} <= set(pairs.columns):
        raise InputError("anthropometrics need subjects (id, weight, height) and pairs (id, subject1, subject2)",
                         path=path, remedy="fix the tables' columns, or give --anthropometrics a directory of subjects.csv "
                                           "and pairs.csv")
    check_ids(subjects, pairs, None, path)  # each id once, each pair's subjects listed: no weight left to chance
    s = subjects.assign(id=id_text(subjects["id"])).set_index("id")
    pairs = pairs.assign(subject1=id_text(pairs["subject1"]), subject2=id_text(pairs["subject2"]))
    out = pd.DataFrame({"pair": id_text(pairs["id"])})
    out["weight_diff"] = (pairs["subject1"].map(s["weight"]) - pairs["subject2"].map(s["weight"])).abs().to_numpy()
    out["height_diff"] = (pairs["subject1"].map(s["height"]) - pairs["subject2"].map(s["height"])).abs().to_numpy()
    return out


def pairs_source(distances: pd.DataFrame, anthropometrics: pd.DataFrame | None) -> pd.DataFrame:
    d = distances[distances["comparison"].eq("individual-mean") & distances["kind"].eq("trial")] if len(distances) else distances
    if d.empty or d["pair"].isna().all():
        return _empty("pairs")
    out = d.groupby(["study", "pair", "entity"], as_index=False)["d_xy"].mean()
    if anthropometrics is not None:
        out = out.merge(anthropometrics, on="pair", how="left")
    return _conform(out, "pairs")


def gamma_as_files_source(ts: TrajectorySet) -> pd.DataFrame:
    """The authors' subject-vs-mean d_gamma, marker-loss rows kept as zero gamma (module doc)."""
    m = ts.meta
    if not len(ts) or not m["kind"].eq("mean").any():
        return _empty("gamma_as_files")
    walker = m["entity"].eq("walker")
    means = m[m["kind"].eq("mean") & walker]
    at = dict(zip(zip(means["study"], means["condition"]), means.index))
    trials = m[m["kind"].eq("trial") & walker & pd.Series(list(zip(m["study"], m["condition"])), index=m.index).isin(at)]
    if trials.empty:
        return _empty("gamma_as_files")
    i = trials.index.to_numpy()
    j = np.array([at[k] for k in zip(trials["study"], trials["condition"])])
    files = lambda g: wrap(np.nan_to_num(g, nan=0.0))  # noqa: E731 - the files hold 0 where the marker was lost
    d = np.abs(files(ts.gamma[i]) - files(ts.gamma[j])).mean(axis=1)
    lost = ~np.isfinite(ts.gamma[i]).all(axis=1)
    out = trials[["study", "trial", "subject", "condition"]].reset_index(drop=True)
    letters = start_orientations(ts)
    out["start_orientation"] = [letters.get((str(s), str(c))) for s, c in zip(out["study"], out["condition"])]
    out["orientation_missing"], out["d_gamma"], out["d_gamma_loss_zero"] = lost, d, np.where(lost, 0.0, d)
    return _conform(out, "gamma_as_files")


def build_sources(ts: TrajectorySet | None, distances: pd.DataFrame | None, durations: pd.DataFrame | None = None,
                  anthropometrics: pd.DataFrame | None = None, alpha: float = 0.05,
                  only: set[str] | None = None) -> dict[str, pd.DataFrame]:
    """Every source of ``SOURCE_COLUMNS`` (empty tables where the data do not support them), or
    only the named ones."""
    if only is not None:
        ts_ok = ts is not None
        trials = trials_source(ts) if ts_ok else _empty("trials")
        has_dir = trials["direction"].notna().any()
        make = {"trials": lambda: trials, "durations": lambda: durations_source(trials, durations),
                "choices": lambda: choices_source(trials) if has_dir else _empty("choices"),
                "patterns": lambda: patterns_source(trials) if has_dir else _empty("patterns"),
                "return_variability": lambda: return_variability_source(ts, alpha) if ts_ok else _empty("return_variability"),
                "gamma_as_files": lambda: gamma_as_files_source(ts) if ts_ok else _empty("gamma_as_files")}
        unknown = set(only) - set(make)
        if unknown:
            raise ValueError(f"build_sources(only=...) supports {sorted(make)}, not {sorted(unknown)}")
        return {k: make[k]() for k in only}
    trials = trials_source(ts) if ts is not None else _empty("trials")
    dist = distances_source(distances, start_orientations(ts))
    dur = durations_source(trials, durations)
    return {
        "trials": trials,
        "durations": dur,
        "pair_durations": pair_durations_source(dur),
        "distances": dist,
        "choices": choices_source(trials) if "direction" in trials and trials["direction"].notna().any() else _empty("choices"),
        "patterns": patterns_source(trials) if trials["direction"].notna().any() else _empty("patterns"),
        "closer": closer_source(dist),
        "return_variability": return_variability_source(ts, alpha) if ts is not None else _empty("return_variability"),
        "pairs": pairs_source(dist, anthropometrics),
        "gamma_as_files": gamma_as_files_source(ts) if ts is not None else _empty("gamma_as_files"),
    }

