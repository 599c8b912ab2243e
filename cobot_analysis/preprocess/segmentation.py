"""Segmentation of recordings into trajectories (docs/methods.md sec. 1.2 and 3).

Pair-study recordings (walk-to-table, forward carriage, set-down, return carriage) are cut by the
table height ``h`` (mean z of the visible table corners, ``kinematics.table_height``):

- floor level ``h0`` = median of ``h`` over the first ``floor_window`` seconds (default 0.5 s) of
  the recording from the first sample where the table is seen, when it rests on the floor before the
  subjects reach it;
- the table is carried while ``h > h0 + threshold`` (default 5 mm); each maximal run of such
  samples lasting at least ``min_duration`` (default 0.5 s, to ignore bumps) is a carriage;
- two carriages set down for less than ``min_set_down`` (default 0 s: never) between them are one: the
  carriers set the table down to re-grip it;
- onset = first sample of the run, offset = its last sample (so ``travel_time = offset - onset``).

Walking trials are cut by the pelvis CoM speed, with hysteresis: the subject walks while
``|v| >= threshold`` (default 0.1 m/s); runs shorter than ``min_duration`` (default 0.5 s) are
ignored (sway while standing); runs with no rest of ``min_rest`` (default 1 s, measured: ``|v| <
rest_speed``) between them are one walk (a slow-down or a hesitation stays inside), and a recording
may hold several walks (``walks``: e.g. to the goal, then back to the start); each walk is then
extended outwards while ``|v| >= rest_speed`` (default 0.05 m/s, above the speed noise of a standing
subject), so that onset and offset lie where the subject starts and stops moving rather than where it
passes the detection threshold.

A trajectory whose onset is the first sample of the recording, or of a run of valid samples (the
markers were not seen before), started before it was recorded; likewise at its offset
(``cut_off``). Its travel time and path are then those of the recorded part only: the stage flags
it ``truncated`` rather than report the recording's length as a travel time.
"""

from __future__ import annotations

import numpy as np

LIFT_THRESHOLD = 0.005  # m above the floor level
FLOOR_WINDOW = 0.5  # s at the start of the recording
SPEED_THRESHOLD = 0.1  # m/s
REST_SPEED = 0.05  # m/s
MIN_DURATION = 0.5  # s
MIN_SET_DOWN = 0.0  # s: a shorter set-down between two lifts (a re-grip) joins them into one carriage
MIN_REST = 1.0  # s: standing still this long between two walks of a recording makes them two walks


def runs(active: np.ndarray, min_samples: int = 1) -> list[tuple[int, int]]:
    """``[(first, last), ...]`` (inclusive) of the runs of True lasting at least ``min_samples``."""
    m = np.concatenate([[False], np.asarray(active, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return [(int(a), int(b) - 1) for a, b in zip(edges[0::2], edges[1::2]) if b - a >= min_samples]


def floor_level(height: np.ndarray, rate: float, window: float = FLOOR_WINDOW) -> float:
    """Resting table height: median of the valid heights in the first ``window`` seconds from the first sample where
    the table is seen."""
    height = np.asarray(height, dtype=float)
    seen = np.flatnonzero(~np.isnan(height))
    if not seen.size:
        return float("nan")
    head = height[seen[0]: seen[0] + max(1, int(round(window * rate)))]
    return float(np.median(head[~np.isnan(head)]))


def carriages(height: np.ndarray, rate: float, threshold: float = LIFT_THRESHOLD, window: float = FLOOR_WINDOW,
              min_duration: float = MIN_DURATION, min_set_down: float = MIN_SET_DOWN) -> tuple[list[tuple[int, int]], float]:
    """Carriage (onset, offset) sample pairs of a pair recording and the floor level used."""
    h0 = floor_level(height, rate, window)
    with np.errstate(invalid="ignore"):
        lifted = np.asarray(height, dtype=float) > h0 + threshold
    found = runs(lifted, max(1, int(round(min_duration * rate))))
    joined = found[:1]
    for on, off in found[1:]:
        if (on - joined[-1][1]) / rate < min_set_down:
            joined[-1] = (joined[-1][0], off)
        else:
            joined.append((on, off))
    return joined, h0


def walks(speed: np.ndarray, rate: float, threshold: float = SPEED_THRESHOLD, min_duration: float = MIN_DURATION,
          rest_speed: float = REST_SPEED, min_rest: float = MIN_REST) -> list[tuple[int, int]]:
    """(onset, offset) samples of each walk of a recording from its CoM speed (module docstring); [] if it never
    walks. Two runs of walking are one walk unless the subject stands still (``|v| < rest_speed``, measured: a
    gap in the data is no rest) for ``min_rest`` seconds between them."""
    speed = np.asarray(speed, dtype=float)
    with np.errstate(invalid="ignore"):
        moving = speed >= threshold
        resting = ~(speed >= min(rest_speed, threshold))  # NaN counts as rest
        still = speed < min(rest_speed, threshold)
    found = runs(moving, max(1, int(round(min_duration * rate))))
    if not found:
        return []
    long_rests = runs(still, max(1, int(round(min_rest * rate)))) if np.isfinite(min_rest) else []
    groups = [[found[0]]]
    for prev, run in zip(found, found[1:]):
        if any(prev[1] < r0 and r1 < run[0] for r0, r1 in long_rests):
            groups.append([])
        groups[-1].append(run)
    out = []
    for g in groups:
        on, off = g[0][0], g[-1][1]
        before = np.flatnonzero(resting[:on])
        after = np.flatnonzero(resting[off + 1:])
        out.append((int(before[-1]) + 1 if before.size else 0, off + int(after[0]) if after.size else len(speed) - 1))
    return out


def walking_bounds(speed: np.ndarray, rate: float, threshold: float = SPEED_THRESHOLD,
                   min_duration: float = MIN_DURATION, rest_speed: float = REST_SPEED) -> tuple[int, int] | None:
    """(onset, offset) samples spanning every walk of ``speed`` (``walks`` as one: a subject's walk to the table,
    whatever its pauses); None if it never walks."""
    found = walks(speed, rate, threshold, min_duration, rest_speed, min_rest=np.inf)
    return found[0] if found else None


def cut_off(signal: np.ndarray, onset: int, offset: int, end: bool = True) -> bool:
    """True if the run ``[onset, offset]`` of ``signal`` (speed or table height) starts at the first
    sample or right after a missing one, or (``end``) ends at the last sample or right before a
    missing one: the movement ran off the recorded data."""
    signal = np.asarray(signal, dtype=float)
    start_cut = onset == 0 or np.isnan(signal[onset - 1])
    end_cut = offset >= len(signal) - 1 or np.isnan(signal[offset + 1])
    return bool(start_cut or (end and end_cut))
