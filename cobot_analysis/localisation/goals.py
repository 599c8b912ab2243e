"""Goal accuracy (docs/methods.md sec. 9, step 5): stops of the robot, matched to the commanded goals.

- Speed of the truth: centred differences over ``window`` seconds,
  ``v(t) = ||p_xy(t + w/2) - p_xy(t - w/2)|| / w`` and ``omega(t)`` likewise on the unwrapped yaw.
- A stop is a run where ``v < speed_threshold`` and ``|omega| < yaw_rate_threshold`` lasting at
  least ``min_duration``; the reached pose is the mean truth pose over the stop without its first
  and last ``trim`` seconds (circular mean for yaw), mapped into the goal (ICP map) frame by the
  inverse of the alignment of ``compare``.
- Stops are matched to goals greedily by increasing planar distance (each goal and each stop used
  once; pairs farther than ``match_radius`` are not matched); when the command times of the goals
  are known (goal topic), only stops starting between a goal's command and the next count. Errors: ``|x_r - x_g|``,
  ``|y_r - y_g|``, ``||p_r - p_g||``, ``|wrap(yaw_r - yaw_g)|``; a goal is reached within tolerance
  when ``||p_r - p_g|| <= tol_xy`` and ``|wrap(yaw_r - yaw_g)| <= tol_yaw``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from cobot_analysis.angles import angle_diff, circular_mean
from cobot_analysis.errors import InputError
from cobot_analysis.localisation.compare import Alignment
from cobot_analysis.localisation.poses import PoseStream
from cobot_analysis.schema import LAB_EXTENT


@dataclass(frozen=True)
class StopRule:
    speed_threshold: float = 0.02  # m/s
    yaw_rate_threshold: float = 0.03  # rad/s
    min_duration: float = 3.0  # s
    window: float = 0.5  # s
    trim: float = 1.0  # s
    match_radius: float = 0.5  # m
    tol_xy: float = 0.08  # m
    tol_yaw: float = 0.07  # rad


def speeds(truth: PoseStream, window: float):
    """Planar speed (m/s) and yaw rate (rad/s) of the truth by centred differences over ``window``."""
    h = window / 2
    t = truth.t
    lo, hi = np.clip(t - h, t[0], t[-1]), np.clip(t + h, t[0], t[-1])
    span = np.where(hi - lo > 0, hi - lo, np.inf)
    xy = truth.xyz[:, :2]
    dx = np.column_stack([np.interp(hi, t, xy[:, k]) - np.interp(lo, t, xy[:, k]) for k in range(2)])
    yaw = truth.yaw
    return np.hypot(dx[:, 0], dx[:, 1]) / span, (np.interp(hi, t, yaw) - np.interp(lo, t, yaw)) / span


def detect_stops(truth: PoseStream, rule: StopRule = StopRule()) -> np.ndarray:
    """``(k, 2)`` start and end times of the stops."""
    v, w = speeds(truth, rule.window)
    still = (v < rule.speed_threshold) & (np.abs(w) < rule.yaw_rate_threshold)
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    out = [(truth.t[a], truth.t[b]) for a, b in zip(starts, ends) if truth.t[b] - truth.t[a] >= rule.min_duration]
    return np.asarray(out, dtype=float).reshape(-1, 2)


def read_goals_csv(path: str | os.PathLike) -> np.ndarray:
    """Commanded goals from a CSV with columns ``x, y, yaw`` (m, rad; map frame)."""
    path = Path(path)
    try:
        df = pd.read_csv(path)
    except Exception as exc:  # noqa: BLE001
        raise InputError(f"not a readable CSV ({type(exc).__name__})", path=path, remedy="give columns goal,x,y,yaw") from exc
    missing = [c for c in ("x", "y", "yaw") if c not in df.columns]
    if missing:
        raise InputError(f"goals file lacks columns {missing}", path=path, remedy="give columns goal,x,y,yaw (m, rad)")
    g = df[["x", "y", "yaw"]].to_numpy(float)
    if len(g) == 0 or not np.isfinite(g).all():
        raise InputError("goals file is empty or has NaN", path=path, remedy="give one finite goal per row")
    far = np.abs(g[:, :2]).max(axis=1) > LAB_EXTENT
    if far.any():
        i = int(np.argmax(far))
        raise InputError(f"goal {i + 1} ({g[i, 0]:g}, {g[i, 1]:g}) lies beyond the lab (|x|, |y| <= {LAB_EXTENT:g} m)", path=path,
                         remedy="give x and y in metres in the ICP map frame (not millimetres)")
    return g


def goal_accuracy(truth: PoseStream, icp: PoseStream, goals: np.ndarray, alignment: Alignment, delay: float,
                  rule: StopRule = StopRule(), goal_times=None) -> pd.DataFrame:
    """One row per commanded goal: the matched stop, reached pose, errors, ICP pose at the stop.
    With ``goal_times`` (when each goal was commanded) a goal is matched only to a stop that
    starts between its command and the next one (repeated goal positions stay in order)."""
    stops = detect_stops(truth, rule)
    reached, icp_pose = [], []
    for a, b in stops:
        a2, b2 = (a + rule.trim, b - rule.trim) if b - a > 2 * rule.trim + 0.5 else (a, b)
        m = slice(np.searchsorted(truth.t, a2, side="left"), np.searchsorted(truth.t, b2, side="right"))  # a2 <= t <= b2
        xyz = truth.xyz[m].mean(axis=0)
        yaw = float(circular_mean(truth.yaw[m]))
        rx, ryaw = alignment.to_icp_frame(xyz[None, :], yaw)
        reached.append([rx[0, 0], rx[0, 1], float(ryaw)])
        mi = (icp.t - delay >= a2) & (icp.t - delay <= b2)
        if mi.any():
            icp_pose.append([icp.xyz[mi, 0].mean(), icp.xyz[mi, 1].mean(), float(circular_mean(icp.yaw[mi]))])
        else:
            icp_pose.append([np.nan] * 3)
    reached, icp_pose = np.asarray(reached).reshape(-1, 3), np.asarray(icp_pose).reshape(-1, 3)
    match = {}
    if len(stops):
        dist = np.hypot(goals[:, None, 0] - reached[None, :, 0], goals[:, None, 1] - reached[None, :, 1])
        match = _greedy(dist, rule.match_radius)
        if goal_times is not None and len(goal_times) == len(goals):
            # Goal k can only be reached between its command and the next one.
            nxt = np.append(np.asarray(goal_times, dtype=float)[1:], np.inf)
            inside = (stops[None, :, 0] >= np.asarray(goal_times)[:, None]) & (stops[None, :, 0] < nxt[:, None])
            timed = _greedy(np.where(inside, dist, np.inf), rule.match_radius)
            if len(timed) >= len(match):  # unless the goal stamps are on another clock
                match = timed
    rows = []
    for g, (gx, gy, gyaw) in enumerate(goals):
        row = {"goal": g + 1, "goal_x": gx, "goal_y": gy, "goal_yaw": gyaw, "found": g in match}
        if g in match:
            s = match[g]
            rx, ry, ryaw = reached[s]
            ix, iy, iyaw = icp_pose[s]
            dyaw = float(angle_diff(ryaw, gyaw))
            row.update({
                "t_start": stops[s, 0], "t_end": stops[s, 1], "duration": stops[s, 1] - stops[s, 0],
                "reached_x": rx, "reached_y": ry, "reached_yaw": ryaw,
                "dx": rx - gx, "dy": ry - gy, "dyaw": dyaw, "err_xy": float(np.hypot(rx - gx, ry - gy)),
                "icp_x": ix, "icp_y": iy, "icp_yaw": iyaw,
                "loc_err_xy": float(np.hypot(ix - rx, iy - ry)), "loc_err_yaw": float(abs(angle_diff(iyaw, ryaw))),
            })
            row["within_tolerance"] = bool(row["err_xy"] <= rule.tol_xy and abs(dyaw) <= rule.tol_yaw)
        else:
            row["within_tolerance"] = False
        rows.append(row)
    cols = ["goal", "goal_x", "goal_y", "goal_yaw", "found", "t_start", "t_end", "duration", "reached_x", "reached_y",
            "reached_yaw", "dx", "dy", "dyaw", "err_xy", "within_tolerance", "icp_x", "icp_y", "icp_yaw", "loc_err_xy",
            "loc_err_yaw"]
    df = pd.DataFrame(rows).reindex(columns=cols)
    df.attrs["n_stops"] = int(len(stops))
    return df


def _greedy(dist: np.ndarray, radius: float) -> dict[int, int]:
    """Goal -> stop pairs by increasing distance, each used once, up to ``radius``."""
    match, used = {}, set()
    for flat in np.argsort(dist, axis=None):
        g, s = (int(v) for v in np.unravel_index(flat, dist.shape))
        if not dist[g, s] <= radius:
            break
        if g not in match and s not in used:
            match[g] = s
            used.add(s)
    return match


def goal_summary(df: pd.DataFrame) -> dict:
    """Per-run goal figures: mean +- sd of the absolute errors over the found goals."""
    f = df[df["found"]]
    out = {"goals_commanded": int(len(df)), "goals_found": int(len(f)), "goals_within_tolerance": int(df["within_tolerance"].sum())}
    for name, col in (("x", "dx"), ("y", "dy"), ("xy", "err_xy"), ("yaw", "dyaw")):
        e = f[col].abs().to_numpy(float)
        out[f"goal_err_{name}_mean"] = float(e.mean()) if len(e) else float("nan")
        out[f"goal_err_{name}_sd"] = float(e.std(ddof=1)) if len(e) > 1 else float("nan")
    return out


def goals_from_stream(stream: PoseStream) -> np.ndarray:
    """Goals published as poses (e.g. ``/goal`` PoseStamped): ``(k, 3)`` x, y, yaw."""
    return np.column_stack([stream.xyz[:, 0], stream.xyz[:, 1], np.asarray(stream.yaw)])

