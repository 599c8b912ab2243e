"""Subjects from the table (docs/methods.md sec. 8).

The mean pose of a subject in the table frame, per normalised sample i and direction:
``x_rel = cos(th_T) dx + sin(th_T) dy``, ``y_rel = -sin(th_T) dx + cos(th_T) dy`` with
``(dx, dy) = p_S - p_T``, ``theta_rel = wrap(theta_S - theta_T)``, averaged over the scenario-3
trials (circular mean for theta_rel), or read from the published ``subject*_wrt_table.dat``.
A subject is then reconstructed from any table trajectory:
``x_rec = x_T + x_rel cos th_T - y_rel sin th_T``, ``y_rec = y_T + x_rel sin th_T + y_rel cos th_T``,
``theta_rec = theta_T + theta_rel``, and compared with the measured subject (d_xy, d_theta).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from cobot_analysis.angles import angle_diff, circular_mean
from cobot_analysis.compare import TrajectorySet
from cobot_analysis.errors import InputError
from cobot_analysis.distances import d_theta, d_xy
from cobot_analysis.schema import Column, TableSchema

SUBJECTS = ("subject1", "subject2")

RECONSTRUCTION = TableSchema(
    name="reconstruction",
    version=1,
    description="Subjects reconstructed from the table trajectory (docs/methods.md sec. 8): accuracy per trajectory.",
    columns={
        "study": Column("string", "", "study"),
        "trial": Column("string", "", "trial (or mean) whose table trajectory was used"),
        "kind": Column("string", "", "trial or mean"),
        "pair": Column("string", "", "pair id (null for means)", required=False),
        "condition": Column("string", "", "goal"),
        "direction": Column("string", "", "forward or return"),
        "scenario": Column("int", "-", "scenario", required=False),
        "end_orientation": Column("float", "rad", "table end orientation", required=False),
        "entity": Column("string", "", "subject1 or subject2 (the reconstructed subject)"),
        "relative_pose": Column("string", "", "where the subject-in-table-frame pose came from: trials or published"),
        "d_xy": Column("float", "m", "reconstructed vs measured subject, linear distance"),
        "d_theta": Column("float", "rad", "reconstructed vs measured subject, angular distance (NaN if missing)"),
    },
)


def relative_pose(ts: TrajectorySet, scenario: int | None = 3, kind: str = "trial") -> dict:
    """Mean subject pose in the table frame per direction over the trajectories of ``kind`` (trials,
    or means when only means exist): ``{(entity, direction): (x_rel, y_rel, theta_rel)}``."""
    m = ts.meta
    sel = m["kind"].eq(kind)
    if scenario is not None and "scenario" in m.columns:
        sel &= pd.to_numeric(m["scenario"], errors="coerce").eq(scenario)
    tpos = np.flatnonzero((sel & m["entity"].eq("table")).to_numpy())
    lookup = pd.Series(tpos, index=pd.MultiIndex.from_frame(m.loc[tpos, ["study", "trial"]]))
    out = {}
    for ent in SUBJECTS:
        for direction, g in m[sel & m["entity"].eq(ent)].groupby("direction"):
            tj = lookup.reindex(pd.MultiIndex.from_frame(g[["study", "trial"]])).to_numpy(dtype=float)
            ok = ~np.isnan(tj)
            if not ok.any():
                continue
            si, tj = g.index.to_numpy()[ok], tj[ok].astype(int)
            th = ts.theta[tj]
            dx, dy = ts.x[si] - ts.x[tj], ts.y[si] - ts.y[tj]
            xr = np.cos(th) * dx + np.sin(th) * dy
            yr = -np.sin(th) * dx + np.cos(th) * dy
            with np.errstate(invalid="ignore"):
                thr = angle_diff(ts.theta[si], th)
            out[(ent, direction)] = (np.nanmean(xr, axis=0), np.nanmean(yr, axis=0), circular_mean(thr, axis=0))
    return out


def read_wrt_table(directory: str | Path) -> dict:
    """The published ``subject1_wrt_table.dat`` / ``subject2_wrt_table.dat`` (6 rows x N:
    x_fwd x_ret y_fwd y_ret theta_fwd theta_ret) -> same mapping as ``relative_pose``."""
    out = {}
    for k, ent in enumerate(SUBJECTS, 1):
        path = Path(directory) / f"subject{k}_wrt_table.dat"
        try:
            a = np.loadtxt(path, ndmin=2)
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot read the subject-in-table-frame file ({type(exc).__name__})", path=path,
                             remedy="pass the pair-carriage-2022 dataset directory with --wrt-table") from None
        if a.shape[0] != 6 or not np.isfinite(a).all():
            raise InputError(f"expected 6 finite rows, found shape {a.shape}", path=path, remedy="use the published file unchanged")
        out[(ent, "forward")] = (a[0], a[2], a[4])
        out[(ent, "return")] = (a[1], a[3], a[5])
    return out


def relative_pose_table(df: pd.DataFrame) -> dict:
    """The importer's subject_wrt_table.parquet (entity, direction, sample, x_rel, y_rel, theta_rel)
    -> same mapping as ``relative_pose``."""
    out = {}
    for (ent, direction), g in df.sort_values("sample").groupby(["entity", "direction"]):
        out[(str(ent), str(direction))] = tuple(g[c].to_numpy(dtype=float) for c in ("x_rel", "y_rel", "theta_rel"))
    return out


def reconstruct(x_t, y_t, th_t, x_rel, y_rel, th_rel):
    """Subject pose from the table pose and the subject pose in the table frame (arrays of N)."""
    c, s = np.cos(th_t), np.sin(th_t)
    return x_t + x_rel * c - y_rel * s, y_t + x_rel * s + y_rel * c, th_t + th_rel


def _resample(v: np.ndarray, n: int) -> np.ndarray:
    if len(v) == n:
        return v
    return np.interp(np.linspace(0, 1, n), np.linspace(0, 1, len(v)), v)


def accuracy(ts: TrajectorySet, rel: dict, source: str, scenario: int | None = 3, progress=None) -> pd.DataFrame:
    """Reconstruct both subjects from every table trajectory of ``ts`` (scenario ``scenario``, all
    kinds) and compare with the measured subject trajectory of the same trial -> RECONSTRUCTION rows.
    ``progress`` (e.g. ``console.track``) wraps the loop over table trajectories."""
    m = ts.meta
    sel = m["entity"].eq("table")
    if scenario is not None and "scenario" in m.columns:
        sel &= pd.to_numeric(m["scenario"], errors="coerce").eq(scenario)
    index = pd.Series(np.arange(len(m)), index=pd.MultiIndex.from_frame(m[["study", "trial", "entity"]]))
    rows = []
    tables = np.flatnonzero(sel)
    for ti in progress(tables, f"reconstruct ({source})") if progress else tables:
        t = m.iloc[ti]
        for ent in SUBJECTS:
            key = (t["study"], t["trial"], ent)
            if key not in index.index or (ent, t["direction"]) not in rel:
                continue
            si = int(index[key])
            xr, yr, thr = (_resample(np.asarray(v, float), ts.n_samples) for v in rel[(ent, t["direction"])])
            x, y, th = reconstruct(ts.x[ti], ts.y[ti], ts.theta[ti], xr, yr, thr)
            with np.errstate(invalid="ignore"):
                dth = float(d_theta(th, ts.theta[si]))
            rows.append({"study": t["study"], "trial": t["trial"], "kind": t["kind"], "pair": t.get("pair"),
                         "condition": t["condition"], "direction": t["direction"], "scenario": t.get("scenario"),
                         "end_orientation": t.get("end_orientation"), "entity": ent, "relative_pose": source,
                         "d_xy": float(d_xy(x, y, ts.x[si], ts.y[si])), "d_theta": dth})
    return pd.DataFrame(rows, columns=list(RECONSTRUCTION.columns))
