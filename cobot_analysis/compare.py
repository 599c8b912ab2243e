"""Comparing trajectories: individual vs mean, any vs any, forward vs return, table A vs table B.

Long trajectory tables (one row per trajectory x sample) are pivoted once into arrays
``(n_trajectories, N)`` (``TrajectorySet``); the pairs to compare are found with table joins on
the metadata and all their distances (docs/methods.md sec. 3: d_xy, d_theta, d_gamma) are computed in a
few vectorised calls of ``distances.pair_distances`` (no Python loop over pairs or samples).
The result is ``distances.parquet``: one row per compared pair with the grouping columns of the
first trajectory ("a") and the identity of the second ("b_*").
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from cobot_analysis.errors import InputError
from cobot_analysis.distances import pair_distances, reverse_time
from cobot_analysis.schema import NONNEGATIVE, TRIAL_COLUMNS, Column, TableSchema

KEY = ["study", "trial", "entity"]
#: per-trajectory metadata carried from a trajectory table (columns that exist are kept).
META = [*TRIAL_COLUMNS, "entity", "travel_time", "travelled_distance", "quality"]
SIGNALS = ("x", "y", "theta", "gamma")
#: columns that identify a trajectory's condition in each study (the grouping of the means).
WALKING_GROUPS = ["study", "condition", "entity"]
PAIR_GROUPS = ["study", "condition", "direction", "scenario", "configuration", "end_orientation", "entity"]
#: columns of "b" stored beside the grouping columns of "a" in distances.parquet.
B_COLUMNS = ["trial", "kind", "subject", "pair", "scenario", "direction", "end_orientation", "repetition"]

DISTANCES = TableSchema(
    name="distances",
    version=1,
    description=("Distances between two time-normalised trajectories (docs/methods.md sec. 3), one row per "
                 "compared pair: grouping columns of trajectory a, identity of trajectory b (b_*)."),
    columns={
        "comparison": Column("string", "", "individual-mean, any-any, symmetry (forward vs reversed return), against, ..."),
        **{k: Column(c.dtype, c.unit, f"trajectory a: {c.description}", required=c.required) for k, c in TRIAL_COLUMNS.items()},
        "entity": Column("string", "", "walker, subject1, subject2 or table (same for a and b)"),
        **{f"b_{k}": Column(TRIAL_COLUMNS[k].dtype, TRIAL_COLUMNS[k].unit, f"trajectory b: {k}", required=False) for k in B_COLUMNS},
        "travel_time": Column("float", "s", "travel time of trajectory a (NaN if unknown)", required=False, limits=NONNEGATIVE),
        "travelled_distance": Column("float", "m", "start-end distance of trajectory a", required=False),
        "global_distance": Column("float", "m", "start-goal distance of the condition (walker / table path of a's trial)", required=False),
        "orientation_change": Column("float", "rad", "|theta_end - theta_start| of trajectory a (unwrapped)", required=False),
        "d_xy": Column("float", "m", "linear distance (1/N) sum |p_a - p_b|", limits=NONNEGATIVE),
        "d_theta": Column("float", "rad", "angular distance (1/N) sum |wrap(theta_a - theta_b)|; NaN if an orientation is missing",
                          limits=NONNEGATIVE),
        "d_gamma": Column("float", "rad", "local angular distance over N-1 samples; NaN if missing", limits=NONNEGATIVE),
        "convention": Column("string", "", "published or continuous: how the paths were compared (docs/methods.md sec. 11)",
                             required=False),
    },
)


@dataclass
class TrajectorySet:
    """Trajectories as arrays: ``meta`` has one row per trajectory (row i <-> ``x[i]``)."""

    meta: pd.DataFrame
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    gamma: np.ndarray
    angle_difference: str = "wrapped"  # how this set's angles are compared (distances.d_theta)

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        return {"x": self.x, "y": self.y, "theta": self.theta, "gamma": self.gamma}

    def __len__(self) -> int:
        return len(self.meta)

    @property
    def n_samples(self) -> int:
        return self.x.shape[1] if self.x.ndim == 2 else 0

    def subset(self, mask) -> "TrajectorySet":
        idx = np.flatnonzero(np.asarray(mask))
        return TrajectorySet(self.meta.iloc[idx].reset_index(drop=True), self.x[idx], self.y[idx], self.theta[idx], self.gamma[idx],
                             self.angle_difference)

    def compared_as(self, comparison) -> "TrajectorySet":
        """The set as a ``conventions.Comparison`` compares it: with ``arclength`` (and both paths
        resampled) every path resampled by arc length to its N samples (``distances.resample_arclength``;
        angles stay on the time samples), angles compared with ``comparison.angle_difference``; gamma
        as recorded (``measured_gamma`` "data") or from the path (``distances.gamma_from_path``, "path":
        a mean's gamma is then the one of the mean path, not the mean of its trials' gammas, as fit-ioc's
        model comparison takes it)."""
        from cobot_analysis.distances import gamma_from_path, resample_arclength

        x, y, gamma = self.x, self.y, self.gamma
        if comparison.resample == "arclength" and comparison.both_resampled and len(self):
            xy = [resample_arclength(xi, yi, self.n_samples) for xi, yi in zip(self.x, self.y)]
            x, y = np.array([v[0] for v in xy]), np.array([v[1] for v in xy])
        if comparison.measured_gamma == "path" and len(self):
            gamma = gamma_from_path(x, y, self.theta)
        return TrajectorySet(self.meta, x, y, self.theta, gamma, comparison.angle_difference)


def plain_dtypes(df: pd.DataFrame) -> pd.DataFrame:
    """Nullable pandas dtypes -> numpy ones (strings as objects with None, integers as floats with
    NaN), so that masks never hold <NA> (Parquet files read back with string / Int64 dtypes)."""
    df = df.copy()
    for c in df.columns:
        dt = df[c].dtype
        if isinstance(dt, pd.StringDtype) or (dt == object and df[c].isna().any()):
            df[c] = df[c].astype(object).where(df[c].notna(), None)
        elif isinstance(dt, pd.api.extensions.ExtensionDtype) and pd.api.types.is_numeric_dtype(dt):
            df[c] = df[c].astype("float64")
        elif isinstance(dt, pd.BooleanDtype):
            df[c] = df[c].astype(object).where(df[c].notna(), None)
    return df


def read_trajectory_set(path: str | Path, tables: tuple[str, ...] = ("trajectories", "means", "generated_trajectories")) -> TrajectorySet:
    """Read a trajectory table (trajectories, means, generated paths) straight into a ``TrajectorySet``.

    Fast path for files written trajectory by trajectory (samples 0..N-1 in order, the layout every
    stage writes): the numeric columns are read once and reshaped, and the metadata is read from the
    sample-0 rows only, single-threaded (pyarrow's thread pool is slower than one thread on a
    loaded 2-core machine). Any other layout goes through ``pivot``.
    """
    import pyarrow.parquet as pq

    from cobot_analysis.schema import SCHEMAS, TRAJECTORIES, VERIFY, check_file, check_values, not_the_table, table_metadata

    path = check_file(path, "run the stage that writes it first or check --out")

    def unreadable(exc: Exception) -> InputError:  # pyarrow raises several types for a damaged footer or data page
        return InputError(f"not a readable Parquet file ({type(exc).__name__})", path=path, remedy="re-run the stage that wrote it")

    def read(**kw):
        try:
            return pq.read_table(path, use_threads=False, **VERIFY, **kw)
        except Exception as exc:
            raise unreadable(exc) from None

    try:
        name = table_metadata(path).get("table")
        names = pq.ParquetFile(path).schema_arrow.names
    except Exception as exc:
        raise unreadable(exc) from None
    if name not in tables:
        raise not_the_table(path, tables[0], name, f"pass one of: {', '.join(tables)}")
    missing = [c for c in (*KEY, "kind", "sample", "x", "y") if c not in names]
    if missing:
        raise InputError(f"{name} table lacks columns {missing}", path=path, remedy="re-run the stage that wrote it")
    schema = SCHEMAS.get(name, TRAJECTORIES)  # generated paths: the trajectories' columns
    num = read(columns=[c for c in ("sample", *SIGNALS) if c in names])
    check_values(num, schema, path)
    sample = num["sample"].to_numpy(zero_copy_only=False)
    n_traj = int((sample == 0).sum())
    n = len(sample) // n_traj if n_traj else 0
    if not n or n * n_traj != len(sample) or not (sample.reshape(-1, n) == np.arange(n)).all():
        table = read()
        check_values(table, schema, path)
        return pivot(table.to_pandas(), path)
    meta = read(columns=[c for c in META if c in names], filters=[("sample", "=", 0)])
    check_values(meta, schema, path)
    meta = meta.to_pandas()
    if meta.duplicated(KEY).any():
        raise InputError("several trajectories share a (study, trial, entity) key", path=path, remedy="re-run the stage that wrote it")

    def arr(col: str) -> np.ndarray:
        if col not in names:
            return np.full((n_traj, n), np.nan)
        return num[col].to_numpy(zero_copy_only=False).astype(float).reshape(n_traj, n)

    return _finish(plain_dtypes(meta), arr("x"), arr("y"), arr("theta"), arr("gamma"), path)


def _finish(meta, x, y, theta, gamma, path) -> TrajectorySet:
    if x.shape[1] < 2:
        raise InputError(f"trajectories of {x.shape[1]} sample: no path", path=path,
                         remedy="time-normalise every trajectory to N >= 2 samples (preprocess --samples)")
    ts = TrajectorySet(meta, x, y, theta, gamma)
    snap_configurations(ts)
    bad = ~np.isfinite(ts.x).all(axis=1) | ~np.isfinite(ts.y).all(axis=1)
    if bad.any():
        raise InputError(f"{int(bad.sum())} trajectories have NaN positions (e.g. {meta.loc[np.argmax(bad), 'trial']})",
                         path=path, remedy="fill or drop gaps in preprocess; positions must be complete")
    return ts


def pivot(df: pd.DataFrame, path: str | Path | None = None) -> TrajectorySet:
    """Long table -> ``TrajectorySet``; every trajectory must have the same number of samples."""
    missing = [c for c in (*KEY, "sample", "x", "y") if c not in df.columns]
    if missing:
        raise InputError(f"trajectory table lacks columns {missing}", path=path, remedy="pass a trajectories.parquet or means.parquet")
    if df.empty:
        raise InputError("trajectory table is empty", path=path, remedy="check the import / preprocess stage output")
    df = df.sort_values([*KEY, "sample"], kind="stable").reset_index(drop=True)
    code = df.groupby(KEY, sort=False, observed=True, dropna=False).ngroup().to_numpy()
    counts = np.bincount(code)
    if counts.min() != counts.max():
        repeated = df.duplicated([*KEY, "sample"])
        if repeated.any():  # the same sample twice: rows repeated, or two tables concatenated
            row = df.loc[repeated.idxmax()]
            raise InputError(f"trajectory {row['trial']}/{row['entity']} of study {row['study']} has sample {row['sample']} more "
                             "than once", path=path, remedy="keep one row per trajectory and sample (pandas drop_duplicates), "
                                                            "or re-run the stage that wrote it")
        odd = int(np.argmin(counts) if (counts == counts.max()).sum() > 1 else np.argmax(counts))
        row = df.loc[int(np.flatnonzero(code == odd)[0])]
        raise InputError(f"trajectories have different numbers of samples ({counts.min()} to {counts.max()}; "
                         f"{row['trial']}/{row['entity']} has {counts[odd]})", path=path,
                         remedy="time-normalise every trajectory to the same N (preprocess --samples)")
    n = int(counts[0])
    if not (df["sample"].to_numpy().reshape(-1, n) == np.arange(n)).all():
        raise InputError("sample indices are not 0..N-1 within each trajectory", path=path, remedy="re-run the stage that wrote it")
    first = np.flatnonzero(df["sample"].to_numpy() == 0)
    meta = plain_dtypes(df.loc[first, [c for c in META if c in df.columns]].reset_index(drop=True))

    def arr(col: str) -> np.ndarray:
        if col not in df.columns:
            return np.full((len(first), n), np.nan)
        return df[col].to_numpy(dtype=float, copy=True).reshape(-1, n)

    return _finish(meta, arr("x"), arr("y"), arr("theta"), arr("gamma"), path)


def snap_configurations(ts: TrajectorySet) -> None:
    """Pair study: set ``end_orientation`` to the design orientation of the configuration at the goal.

    Forward paths: the declared (or measured) end orientation; return paths: the table's orientation
    at the start of the return, i.e. the configuration the pair left the goal in (the convention of
    the published data, ``Orientation_Table_Init``). Each is snapped to the nearer of the two
    orientations of the configuration family (design.CONFIGURATIONS), so that trials group by
    configuration and not by a measured angle. Rows without a known family are left unchanged.
    """
    from cobot_analysis.angles import angle_diff
    from cobot_analysis.design import CONFIGURATIONS

    m = ts.meta
    if not {"configuration", "end_orientation", "direction"} <= set(m.columns):
        return
    known = m["configuration"].isin(list(CONFIGURATIONS)).to_numpy()
    if not known.any():
        return
    table = np.flatnonzero(m["entity"].eq("table").to_numpy())
    start = pd.Series(ts.theta[table, 0], index=pd.MultiIndex.from_frame(m.iloc[table][["study", "trial"]]))
    start = start[~start.index.duplicated()]
    t0 = start.reindex(pd.MultiIndex.from_frame(m[["study", "trial"]])).to_numpy(dtype=float)
    ref = np.where(m["direction"].eq("return").to_numpy(), t0, pd.to_numeric(m["end_orientation"], errors="coerce").to_numpy(dtype=float))
    snapped = m["end_orientation"].to_numpy(dtype=float, copy=True)
    for fam, options in CONFIGURATIONS.items():
        rows = np.flatnonzero(known & m["configuration"].eq(fam).to_numpy() & np.isfinite(ref))
        if len(rows):
            err = np.abs(angle_diff(ref[rows, None], np.asarray(options)[None, :]))
            snapped[rows] = np.asarray(options)[np.argmin(err, axis=1)]
    m["end_orientation"] = snapped


def default_groups(meta: pd.DataFrame) -> list[str]:
    """Walking: condition x entity; pair study: goal x path x scenario x end configuration x entity."""
    is_pairs = "direction" in meta.columns and meta["direction"].notna().any()
    cols = PAIR_GROUPS if is_pairs else WALKING_GROUPS
    return [c for c in cols if c in meta.columns]


def group_keys(meta: pd.DataFrame, by: list[str]) -> pd.Series:
    """One hashable key per row from the ``by`` columns (NaN-safe, end orientation rounded, whole numbers keyed
    alike whether the table holds them as int or float: a scenario 1 of generate's paths is the means' 1.0)."""
    parts = []
    for c in by:
        col = meta[c]
        if c == "end_orientation":
            col = col.astype(float).round(3)
        elif pd.api.types.is_float_dtype(col) and (col.dropna() % 1 == 0).all():
            col = col.astype("Int64")
        parts.append(col.astype(str).where(col.notna(), "<NA>"))
    if not parts:
        return pd.Series(["all"] * len(meta), index=meta.index)
    key = parts[0]
    for p in parts[1:]:
        key = key + "|" + p
    return key


def _global_distance(meta: pd.DataFrame) -> pd.Series:
    """Global distance of each trajectory's trial: the walker's or the table's travelled distance."""
    if "travelled_distance" not in meta.columns:
        return pd.Series(np.nan, index=meta.index)
    carrier = meta["entity"].isin(["walker", "table"])
    ref = meta.loc[carrier].drop_duplicates(["study", "trial"]).set_index(["study", "trial"])["travelled_distance"]
    idx = pd.MultiIndex.from_frame(meta[["study", "trial"]])
    return pd.Series(ref.reindex(idx).to_numpy(), index=meta.index)


def _rows(comparison: str, a: TrajectorySet, b: TrajectorySet, ia, ib) -> pd.DataFrame:
    ia, ib = np.asarray(ia, dtype=int), np.asarray(ib, dtype=int)
    out = a.meta.iloc[ia][[c for c in (*TRIAL_COLUMNS, "entity", "travel_time", "travelled_distance") if c in a.meta.columns]]
    out = out.reset_index(drop=True)
    out.insert(0, "comparison", comparison)
    out["global_distance"] = _global_distance(a.meta).to_numpy()[ia]
    out["orientation_change"] = np.abs(a.theta[ia, -1] - a.theta[ia, 0]) if len(ia) else np.zeros(0)
    for c in B_COLUMNS:
        out[f"b_{c}"] = b.meta[c].to_numpy()[ib] if c in b.meta.columns else None
    out = pd.concat([out, pd.DataFrame(pair_distances(a.arrays, b.arrays, ia, ib, a.angle_difference))], axis=1)
    return out


def individual_vs_mean(trials: TrajectorySet, means: TrajectorySet, by: list[str] | None = None, *,
                       members: bool = True) -> pd.DataFrame:
    """Each trajectory against the mean of its group (the ``by`` columns, default ``default_groups``);
    ``members``: the trajectories are members of the means, compared only with ``comparable_means`` (a
    model path is no member: every mean of its group is compared with it, a mean of one trial too)."""
    by = by or default_groups(trials.meta)
    absent = [c for c in by if c not in means.meta.columns]
    if absent:
        raise InputError(f"the means lack the grouping columns {absent}", remedy="re-run `cobot-analysis average` with the same --by")
    mkey = group_keys(means.meta, by)
    if mkey.duplicated().any():
        raise InputError(f"several means per group {mkey[mkey.duplicated()].iloc[0]!r}", remedy="average with the same --by as compare")
    lookup = pd.Series(np.arange(len(means)), index=mkey.to_numpy())
    tkey = group_keys(trials.meta, by)
    ib = lookup.reindex(tkey.to_numpy()).to_numpy()
    ok = ~np.isnan(ib)
    if members:
        ok[ok] = comparable_means(means.meta)[ib[ok].astype(int)]
    return _rows("individual-mean", trials, means, np.flatnonzero(ok), ib[ok].astype(int))


def comparable_means(meta: pd.DataFrame) -> np.ndarray:
    """Means a trial may be compared with: of at least two trajectories (a mean of one trial is that
    trial: its distance 0 says nothing) and whose members share a frame (no ``frames_differ`` flag,
    ``averaging.frame_spread``). Published means (no count) are comparable."""
    n = pd.to_numeric(meta["n_trials"], errors="coerce") if "n_trials" in meta.columns else pd.Series(np.nan, index=meta.index)
    flags = meta["quality"].fillna("").astype(str) if "quality" in meta.columns else pd.Series("", index=meta.index)
    return ((n.isna() | (n >= 2)) & ~flags.str.contains("frames_differ")).to_numpy()


#: why ``individual_vs_mean`` leaves a trial out (the keys of ``excluded_means``), as the line and the report say it
EXCLUDED_REASONS = {"single": "whose mean is of that trial alone",
                    "frames": "whose mean mixes trajectories that do not share a frame (`frames_differ`)"}


def excluded_means(trials: TrajectorySet, means: TrajectorySet, by: list[str] | None = None) -> dict[str, int]:
    """How many trials ``individual_vs_mean`` leaves out, by reason: "single" (their mean is of one
    trial, itself) and "frames" (the members of their mean do not share a frame)."""
    by = by or default_groups(trials.meta)
    if any(c not in means.meta.columns for c in by) or not len(means):
        return {"single": 0, "frames": 0}
    m = means.meta.assign(_key=group_keys(means.meta, by).to_numpy()).drop_duplicates("_key").set_index("_key")
    hit = m.reindex(group_keys(trials.meta, by).to_numpy())
    n = pd.to_numeric(hit["n_trials"], errors="coerce")
    frames = hit["quality"].fillna("").astype(str).str.contains("frames_differ") if "quality" in hit else n * 0
    return {"single": int((n.eq(1) & ~frames).sum()), "frames": int(frames.sum())}


def against_vs_mean(other: TrajectorySet, means: TrajectorySet, by: list[str], label: str, path=None) -> pd.DataFrame:
    """``compare --against``: each trajectory of ``other`` against the mean of its group (the ``by``
    columns it has). A table none of whose trajectories matches a mean is an ``InputError`` naming
    the values that differ; a partial match is warned about with the count."""
    from cobot_analysis.console import warn

    cols = [c for c in by if c in other.meta.columns]
    if not cols:
        raise InputError(f"has none of the grouping columns of the means ({', '.join(by)})", path=path,
                         remedy="give the table those columns (as generate and the trajectory tables have)")
    hit = group_keys(other.meta, cols).isin(set(group_keys(means.meta, cols)))
    if hit.all():
        return individual_vs_mean(other, means, cols, members=False).assign(comparison=label)
    differ = []
    for c in cols:
        theirs = {str(v) for v in other.meta.loc[~hit.to_numpy(), c].dropna()}
        ours = {str(v) for v in means.meta[c].dropna()}
        if theirs - ours:
            differ.append(f"{c} {', '.join(sorted(theirs - ours)[:3])} (means: {', '.join(sorted(ours)[:3])}"
                          f"{', ...' if len(ours) > 3 else ''})")
    why = "; ".join(differ) or f"no mean has their combination of {', '.join(cols)}"
    if not hit.any():
        unnamed = "study" in cols and set(other.meta["study"].dropna().astype(str)) == {"model"}  # generate without a study
        raise InputError(f"none of its {len(other)} trajectories matches a mean on {', '.join(cols)}: {why}", path=path,
                         remedy="compare with the means of the same study and grouping (--by, --means), or fix those columns"
                         + (f"; paths generated without a study are of study 'model': generate them with "
                            f"study=\"{sorted(means.meta['study'].dropna().astype(str))[0]}\"" if unnamed else ""))
    warn(f"{path}: {int((~hit).sum())} of its {len(other)} trajectories match no mean on {', '.join(cols)} and are not "
         f"compared: {why}")
    return individual_vs_mean(other, means, cols, members=False).assign(comparison=label)


def any_vs_any(ts: TrajectorySet, same: list[str], differ: list[str] = (), comparison: str = "any-any",
               other: TrajectorySet | None = None) -> pd.DataFrame:
    """Every pair (a, b) that agrees on the ``same`` columns and differs on each ``differ`` column.

    Within one set each unordered pair is compared once (a before b); with ``other`` every a of
    ``ts`` is compared with every matching b of ``other``.
    """
    b_set = ts if other is None else other
    left = pd.DataFrame({"_k": group_keys(ts.meta, same).to_numpy(), "_ia": np.arange(len(ts))})
    right = pd.DataFrame({"_k": group_keys(b_set.meta, same).to_numpy(), "_ib": np.arange(len(b_set))})
    m = left.merge(right, on="_k")
    if other is None:
        m = m[m["_ia"] < m["_ib"]]
    keep = np.ones(len(m), dtype=bool)
    for c in differ:
        va = ts.meta[c].to_numpy()[m["_ia"].to_numpy()]
        vb = b_set.meta[c].to_numpy()[m["_ib"].to_numpy()]
        keep &= pd.Series(va).astype(str).to_numpy() != pd.Series(vb).astype(str).to_numpy()
    m = m[keep]
    return _rows(comparison, ts, b_set, m["_ia"].to_numpy(), m["_ib"].to_numpy())


def forward_vs_return(ts: TrajectorySet, match: list[str]) -> pd.DataFrame:
    """Symmetry: each forward path against the time-reversed return path matched on ``match``.

    The b trajectory's arrays are reversed in time (sample i <-> N-1-i) before d_xy/d_theta.
    """
    fwd = ts.subset(ts.meta["direction"].eq("forward").to_numpy())
    ret = ts.subset(ts.meta["direction"].eq("return").to_numpy())
    ret = TrajectorySet(ret.meta, *(reverse_time(v) for v in (ret.x, ret.y, ret.theta, ret.gamma)))
    if not len(fwd) or not len(ret):
        return _rows("symmetry", ts, ts, [], [])
    return any_vs_any(fwd, same=match, comparison="symmetry", other=ret)


def recording_ids(meta: pd.DataFrame) -> pd.Series:
    """The recording a forward or return trial was cut from: its trial id without the direction
    word (``P01_d1_p4_gris_s2_forward`` and ``..._return`` -> ``P01_d1_p4_gris_s2_``)."""
    return meta["trial"].astype(str).str.replace(r"(forward|return)", "", regex=True)


def compare_sets(trials: TrajectorySet, means: TrajectorySet | None, *, by: list[str] | None = None,
                 symmetry_match: list[str] | None = None) -> pd.DataFrame:
    """The standard comparisons of a study: individual-mean; between-scenario means (pair study,
    same goal, path, end orientation and entity); mean forward vs reversed mean return; trial-level
    forward vs reversed return of the same recording when trials carry a pair id."""
    parts = []
    if means is not None and len(means):
        parts.append(individual_vs_mean(trials, means, by))
        scen = pd.to_numeric(means.meta["scenario"], errors="coerce") if "scenario" in means.meta.columns else None
        if scen is not None and scen.notna().any():  # pooled means (scenario null) are not a scenario
            same = [c for c in ("study", "condition", "direction", "end_orientation", "entity") if c in means.meta.columns]
            parts.append(any_vs_any(means.subset(scen.notna().to_numpy()), same=same, differ=["scenario"],
                                    comparison="scenario-scenario-mean"))
        if "direction" in means.meta.columns and means.meta["direction"].eq("return").any() and scen is not None:
            # forward means of scenario 3 (returns are scenario 3 by design) vs the reversed return means
            both = means.subset((scen.eq(3) | means.meta["direction"].eq("return")).to_numpy())
            parts.append(forward_vs_return(both, ["study", "condition", "end_orientation", "entity"]).assign(comparison="symmetry-mean"))
    tr = trials.subset(trials.meta["kind"].eq("trial").to_numpy())
    if len(tr) and "scenario" in tr.meta.columns and tr.meta["scenario"].nunique() > 1:
        same = [c for c in ("study", "pair", "condition", "direction", "end_orientation", "entity") if c in tr.meta.columns]
        parts.append(any_vs_any(tr, same=same, differ=["scenario"], comparison="scenario-scenario"))
    if "direction" in tr.meta.columns and tr.meta["direction"].eq("return").any():
        tr.meta["recording"] = recording_ids(tr.meta)
        parts.append(forward_vs_return(tr, symmetry_match or ["study", "recording", "entity"]))
    parts = [p for p in parts if len(p)]
    if not parts:
        return _rows("individual-mean", trials, trials, [], [])
    return pd.concat(parts, ignore_index=True)


def converged_paths(df: pd.DataFrame, path=None, name: str | None = None) -> pd.DataFrame:
    """The model paths of a generated table that are solutions of their model (``converged``; a table without the
    column is kept whole): a path whose solver stopped is its last iterate, no model's path to measure. Those left out
    are warned about by name (``name``: the table's in the warning, default ``path``); none left is an ``InputError``."""
    from cobot_analysis.console import warn

    if "converged" not in df or df["converged"].astype(bool).all():
        return df
    ok = df.groupby("trial", sort=False)["converged"].transform(lambda c: bool(c.astype(bool).all()))
    left = list(dict.fromkeys(df.loc[~ok, "trial"].astype(str)))
    remedy = "re-run generate with a higher --max-iter (their reason is in the status column)"
    if ok.sum() == 0:
        raise InputError(f"none of its {len(left)} model paths converged", path=path, remedy=remedy)
    warn(f"{name or path}: {len(left)} model path(s) left out, their solver did not converge or they miss their goal "
         f"({', '.join(left[:5])}{', ...' if len(left) > 5 else ''}); {remedy}")
    return df[ok]


def against_set(path: Path, n_samples: int, convention, schema=None, name: str | None = None) -> TrajectorySet:
    """``compare --against`` table as a set on ``n_samples`` samples, under ``convention``: its
    ``convention`` (column or metadata, when it has one) must be the one asked for; each trajectory is
    put on ``n_samples`` samples as the convention compares a model path with a measured one
    (arc length, or time; ``distances.path_distances``). ``schema``: the table's, whose limits its values are checked
    against (generate's ``models.outputs.GENERATED``; default the trajectories'); ``name``: the table's in warnings
    (default ``path``)."""
    import pyarrow.parquet as pq

    from cobot_analysis import conventions
    from cobot_analysis.distances import gamma_from_path, resample_arclength, resample_time
    from cobot_analysis.schema import TRAJECTORIES, VERIFY, check_file, check_values, table_metadata

    path = check_file(path, "pass the table generate wrote")
    try:
        table = pq.read_table(path, **VERIFY)
        stored = table_metadata(path).get("convention")
    except Exception as exc:  # pyarrow raises several types for corrupt files
        raise InputError(f"not a readable trajectory table ({type(exc).__name__})", path=path, remedy="pass a Parquet trajectory table") from None
    check_values(table, schema or TRAJECTORIES, path)  # a model path has the trajectories' columns
    df = table.to_pandas()
    found = {str(path): stored or (str(df["convention"].iloc[0]) if "convention" in df and len(df) else None),
             "--convention": convention.name}
    conventions.check_same(found, "the --against table and this comparison")
    missing = [c for c in (*KEY, "sample", "x", "y") if c not in df.columns]
    if missing:
        raise InputError(f"trajectory table lacks columns {missing}", path=path, remedy="pass a trajectories.parquet or generated.parquet")
    df = converged_paths(df, path, name)
    rows = []
    for _, g in df.sort_values([*KEY, "sample"]).groupby(KEY, sort=False, observed=True):
        x, y = g["x"].to_numpy(float), g["y"].to_numpy(float)
        th = g["theta"].to_numpy(float) if "theta" in g else np.full(len(g), np.nan)
        if convention.comparison.resample == "arclength":
            try:
                x, y = resample_arclength(x, y, n_samples)
            except ValueError as exc:
                raise InputError(f"trajectory {g['trial'].iloc[0]!r}: {exc}", path=path, remedy="leave it out of the table") from None
            th = resample_time(th, n_samples, authors=True)
        else:
            x, y, th = (resample_time(v, n_samples) for v in (x, y, th))
        first = g.iloc[[0]].assign(sample=0)
        rows.append(pd.concat([first] * n_samples, ignore_index=True).assign(
            sample=np.arange(n_samples), x=x, y=y, theta=th, gamma=gamma_from_path(x, y, th)))
    if not rows:
        raise InputError("trajectory table is empty", path=path, remedy="pass the table generate wrote")
    return pivot(pd.concat(rows, ignore_index=True), path)
