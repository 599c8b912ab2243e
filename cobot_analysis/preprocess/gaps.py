"""Gaps in marker trajectories: report them, fill the short ones (docs/methods.md sec. 2.2).

A gap is a maximal run of frames where a marker is missing (NaN or flagged occluded). Gaps of at
most ``max_gap`` seconds (default 0.1 s) that have valid samples on both sides are filled by a
cubic spline (``scipy.interpolate.CubicSpline``, not-a-knot) through the marker's valid samples
within ``SPLINE_CONTEXT`` frames of the filled gaps, evaluated at the gap frames only, and the
filled frames are flagged. Longer gaps, and gaps at the
start or end of a recording (nothing to interpolate between), stay NaN: the quantities that need
that marker are reported as missing downstream, never invented.
"""

from __future__ import annotations

import numpy as np

from cobot_analysis.schema import Column, TableSchema

#: default longest gap that is filled (s).
MAX_GAP = 0.1
#: valid frames on each side of a gap that the spline passes through (a spline's dependence on far
#: knots decays by ~0.27 per knot, so more context changes nothing measurable).
SPLINE_CONTEXT = 20

GAPS = TableSchema(
    name="gaps",
    version=1,
    description=("Gaps (runs of missing frames) of the markers the preprocess stage uses (pelvis, table "
                 "corners), per recording and marker, and whether each was filled."),
    columns={
        "trial": Column("string", "", "recording identifier (as in markers.parquet)"),
        "entity": Column("string", "", "walker, subject1, subject2 or table"),
        "marker": Column("string", "", "canonical marker label"),
        "start_frame": Column("int", "-", "first missing frame"),
        "n_frames": Column("int", "-", "number of consecutive missing frames"),
        "duration": Column("float", "s", "n_frames / rate"),
        "filled": Column("bool", "", "true if filled by cubic spline (short, interior gap)"),
    },
)


def find_gaps(missing: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start frames and lengths of the runs of True in the 1-D boolean ``missing``."""
    m = np.concatenate([[False], np.asarray(missing, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    starts, stops = edges[0::2], edges[1::2]
    return starts, stops - starts


def fillable(starts: np.ndarray, lengths: np.ndarray, n: int, max_frames: int) -> np.ndarray:
    """Which gaps are filled: at most ``max_frames`` long and with a valid sample on each side."""
    return (lengths <= max_frames) & (starts > 0) & (starts + lengths < n)


def fill_gaps(xyz: np.ndarray, rate: float, max_gap: float = MAX_GAP
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fill the short gaps of one marker ``xyz (T, 3)`` (NaN = missing).

    Returns ``(filled xyz, filled-frame mask (T,), gap starts, gap lengths, gap filled flags)``.
    ``max_frames = round(max_gap * rate)``; a gap of ``k`` frames lasts ``k / rate`` s.
    """
    from scipy.interpolate import CubicSpline

    xyz = np.asarray(xyz, dtype=float)
    n = len(xyz)
    missing = np.isnan(xyz).any(axis=1)
    starts, lengths = find_gaps(missing)
    do = fillable(starts, lengths, n, int(round(max_gap * rate)))
    mask = np.zeros(n, dtype=bool)
    if not do.any():
        return xyz, mask, starts, lengths, do
    near = np.zeros(n, dtype=bool)
    for s, k in zip(starts[do], lengths[do]):  # gaps, not samples
        mask[s:s + k] = True
        near[max(0, s - SPLINE_CONTEXT):s + k + SPLINE_CONTEXT] = True
    frames = np.arange(n)
    valid = ~missing & near
    if valid.sum() < 4:  # sparse data around the gaps: use every valid sample
        valid = ~missing
    if valid.sum() < 4:  # too few points for a cubic spline: leave the gaps open
        return xyz, np.zeros(n, dtype=bool), starts, lengths, np.zeros_like(do)
    spline = CubicSpline(frames[valid], xyz[valid], axis=0)
    out = xyz.copy()
    out[mask] = spline(frames[mask])
    return out, mask, starts, lengths, do
