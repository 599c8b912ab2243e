"""Small in-memory trajectory tables with planted (or null) effects: examples, doctests and the analysis tests.

Fast (no raw markers): straight-ish paths with a random lateral bulge per trajectory. Pair study:
``pairs x goals x 3 scenarios`` recordings, each a forward trial (scenario s) and a return trial
(scenario 3 by design, repetition = s), 3 entities each. Planted effects (switchable):
scenario 3 faster (``speedup``), table less variable than the subjects (``table_sd`` < ``subject_sd``),
end configuration favouring the optimal one for Subject 1 (``p_optimal``), returns = time-reversed
forward paths plus noise.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from cobot_analysis.design import PAIR_GOALS, WALKING_CONDITIONS, walking_condition
from cobot_analysis.schema import TRAJECTORIES

N = 40
ARM = 0.9  # m, subject centre from the table centre


def _frame(meta: dict, x, y, theta, n=N) -> dict:
    """One trajectory as a dict of per-trajectory scalars and per-sample arrays (see ``_table``)."""
    phase = 100.0 * np.arange(n) / (n - 1)
    return {**meta, "sample": np.arange(n), "phase": phase, "time": phase * meta["travel_time"] / 100,
            "x": np.asarray(x, float), "y": np.asarray(y, float), "theta": np.asarray(theta, float), "gamma": np.zeros(n),
            "travelled_distance": float(np.hypot(x[-1] - x[0], y[-1] - y[0])), "quality": meta.get("quality", "ok")}


def _table(frames: list[dict]) -> pd.DataFrame:
    """Long table from trajectory dicts in one concatenation (fast for thousands of trajectories)."""
    n = len(frames[0]["sample"])
    cols = {}
    for c in frames[0]:
        if isinstance(frames[0][c], np.ndarray):
            cols[c] = np.concatenate([f[c] for f in frames])
        else:
            cols[c] = np.repeat(np.array([f[c] for f in frames], dtype=object), n)
    df = pd.DataFrame(cols)
    for c in ("n_trials", "repetition", "scenario", "end_orientation", "travel_time", "travelled_distance"):
        if c in df and df[c].notna().any():
            df[c] = pd.to_numeric(df[c])
    return df[[c for c in TRAJECTORIES.columns if c in df.columns]]


def _bulge(rng, sd, n=N):
    s = np.linspace(0, 1, n)
    return rng.normal(0, sd) * np.sin(np.pi * s), s


def walking_table(seed=0, n_subjects=5, n_conditions=3, n_trials=3, subject_effect=0.0, n=N, missing_theta=0.2):
    """Walking study: each subject's paths deviate by ``0.05 + subject_effect * k`` m (k = subject index)."""
    rng = np.random.default_rng(seed)
    frames = []
    for c, code in enumerate(WALKING_CONDITIONS[:n_conditions]):
        start = np.array(walking_condition(code).start[:2])
        for k in range(n_subjects):
            for r in range(n_trials):
                b, s = _bulge(rng, 0.05 + subject_effect * k, n)
                x = start[0] * (1 - s) + b
                y = start[1] * (1 - s)
                theta = np.arctan2(-start[1], -start[0]) + 0.1 * b
                miss = rng.random() < missing_theta
                meta = {"study": "synthetic-walking", "trial": f"S{k:02d}_{code}_{r}", "kind": "trial", "n_trials": 1,
                        "subject": f"S{k + 1:02d}", "pair": None, "condition": code, "direction": None, "scenario": None,
                        "configuration": None, "end_orientation": None, "repetition": r + 1, "entity": "walker",
                        "travel_time": float(np.hypot(*start) / 1.1 * rng.lognormal(0, 0.05)),
                        "quality": "orientation_missing" if miss else "ok"}
                f = _frame(meta, x, y, np.full(n, np.nan) if miss else theta, n)
                if miss:
                    f["gamma"] = np.full(n, np.nan)
                frames.append(f)
    return _table(frames)


def pair_table(seed=0, n_pairs=6, goals=4, speedup=0.10, table_sd=0.03, subject_sd=0.10, p_optimal=0.85, n=N,
               study="synthetic-pairs"):
    """Pair study with the planted effects above; ``speedup=0``, ``p_optimal=0.5`` and
    ``table_sd == subject_sd`` give the null study."""
    rng = np.random.default_rng(seed)
    frames = []
    for p in range(n_pairs):
        pair = f"P{p + 1:02d}"
        for goal in PAIR_GOALS[:goals]:
            gx, gy = goal.position
            th0 = goal.start_pose[2]
            ends = goal.end_orientations
            # Subject 1 is ahead of the table at the start: the end orientation that leaves him ahead is optimal for him.
            d1 = [math.hypot(gx + ARM * math.cos(e) - ARM * math.cos(th0), gy + ARM * math.sin(e) - ARM * math.sin(th0)) for e in ends]
            best = int(np.argmin(d1))
            for s in (1, 2, 3):
                choice = best if rng.random() < p_optimal else 1 - best
                e = ends[choice]
                dist = math.hypot(gx, gy)
                tt = dist / 0.8 * (1 - speedup if s == 3 else 1.0) * rng.lognormal(0, 0.06)
                b_t, u = _bulge(rng, table_sd, n)
                nx, ny = -gy / dist, gx / dist  # unit normal to the straight path
                tx, ty = gx * u + b_t * nx, gy * u + b_t * ny
                dth = (e - th0 + math.pi) % (2 * math.pi) - math.pi
                tth = th0 + dth * u
                for direction in ("forward", "return"):
                    rec = {"study": study, "kind": "trial", "n_trials": 1, "subject": None, "pair": pair,
                           "condition": goal.stem, "direction": direction, "scenario": s if direction == "forward" else 3,
                           "configuration": goal.family, "end_orientation": e, "repetition": 1 if direction == "forward" else s,
                           "travel_time": tt if direction == "forward" else tt * rng.lognormal(0, 0.03)}
                    rev = (lambda a: a) if direction == "forward" else (lambda a: a[::-1].copy())
                    noise_t, _ = _bulge(rng, 0.2 * table_sd, n)
                    X, Y, TH = rev(tx) + noise_t * nx, rev(ty) + noise_t * ny, rev(tth)
                    trial = f"{pair}_{goal.stem}_s{s}_{direction}"
                    frames.append(_frame({**rec, "trial": trial, "entity": "table"}, X, Y, TH, n))
                    for ent, sign, face in (("subject1", 1.0, math.pi), ("subject2", -1.0, 0.0)):
                        b_s, _ = _bulge(rng, subject_sd, n)
                        sx = X + sign * ARM * np.cos(TH) + b_s * nx
                        sy = Y + sign * ARM * np.sin(TH) + b_s * ny
                        frames.append(_frame({**rec, "trial": trial, "entity": ent}, sx, sy, TH + face, n))
    return _table(frames)
