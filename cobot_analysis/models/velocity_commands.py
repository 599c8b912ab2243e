"""Velocity commands for a walking robot from a generated path (docs/methods.md sec. 10).

With the generated path sampled at rate f (p_sim) and the robot's current pose p_real:

    v(t) = (p_sim(t + 1/f) - p_real(t)) f,  expressed in the robot frame (rotation by -theta_real(t)),

then saturated component-wise at |v_x|, |v_y| <= 0.1 m/s and |omega| <= 7 deg/s. Without a
measured robot pose (export ahead of execution) p_real = p_sim (open loop), so the commands are
the path's finite-difference velocities in its own frame. The last sample commands zero.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from cobot_analysis.angles import angle_diff
from cobot_analysis.errors import InputError

V_MAX = 0.1  # m/s, x and y
OMEGA_MAX = math.radians(7.0)  # rad/s


def check_time_law(path_df: pd.DataFrame, *, path=None) -> None:
    """Refuse a path made under the published convention: its timing is the authors' duration rule
    (20 s per metre of start-goal distance, docs/methods.md sec. 11), no pace to command a robot at."""
    conv = str(path_df["convention"].iloc[0]) if "convention" in path_df and len(path_df) else ""
    if conv == "published":
        trial = str(path_df["trial"].iloc[0])
        t, x, y = (path_df[c].to_numpy(float) for c in ("time", "x", "y"))
        speed = np.hypot(np.diff(x), np.diff(y)).sum() / t[-1] if t[-1] > 0 else math.nan
        raise InputError(f"trajectory {trial!r} was generated under the published convention, whose duration rule "
                         f"implies a mean speed of {speed:.3f} m/s (no human or robot pace)", path=path,
                         remedy="generate it with --convention continuous and export that path")


def check_followable(path_df: pd.DataFrame, *, path=None) -> None:
    """Refuse a path that is no solution (the solver did not converge, or the goal was missed: ``converged`` false)
    or no walker's path (it ``spins``: its commands would be the saturated yaw rate, all the way)."""
    from cobot_analysis.models import spin_status

    trial, last = str(path_df["trial"].iloc[0]), path_df.iloc[-1]
    if not bool(last["converged"]):
        raise InputError(f"trajectory {trial!r} is no solution of its model: {last.get('status', 'not converged')}",
                         path=path, remedy="generate it again with a higher --max-iter (or from another --start), or "
                                           "export a trial whose status is ok")
    spin = spin_status(path_df["theta"].to_numpy(float), path_df["omega"].to_numpy(float) if "omega" in path_df else None)
    if spin:
        raise InputError(f"trajectory {trial!r} {spin}", path=path,
                         remedy="generate it with weights that price the turning rate's changes: a copy of the weights "
                                "file with a3 = 0.1, given to generate --weights (docs/methods.md sec. 5.5)")


def resample_path(time, x, y, theta, rate: float) -> pd.DataFrame:
    """The path at ``rate`` Hz from t = 0 to its end (linear interpolation; theta unwrapped)."""
    time = np.asarray(time, float)
    t = np.arange(0.0, time[-1] + 1e-9, 1.0 / rate)
    return pd.DataFrame({"time": t, "x": np.interp(t, time, x), "y": np.interp(t, time, y),
                         "theta": np.interp(t, time, np.unwrap(np.asarray(theta, float)))})


def velocity_commands(sim: pd.DataFrame, rate: float, real: pd.DataFrame | None = None, *,
                      v_max: float = V_MAX, omega_max: float = OMEGA_MAX) -> pd.DataFrame:
    """Commands (robot frame) for the path ``sim`` (time, x, y, theta at ``rate``); ``real``: the
    robot's poses at the same times (default: ``sim``, open loop)."""
    real = sim if real is None else real
    xs, ys, ths = (sim[c].to_numpy(float) for c in ("x", "y", "theta"))
    xr, yr, thr = (real[c].to_numpy(float) for c in ("x", "y", "theta"))
    dx = np.append(xs[1:] - xr[:-1], 0.0) * rate
    dy = np.append(ys[1:] - yr[:-1], 0.0) * rate
    dth = np.append(angle_diff(ths[1:], thr[:-1]), 0.0) * rate
    c, s = np.cos(thr), np.sin(thr)
    vx_raw, vy_raw = c * dx + s * dy, -s * dx + c * dy
    vx, vy, om = np.clip(vx_raw, -v_max, v_max), np.clip(vy_raw, -v_max, v_max), np.clip(dth, -omega_max, omega_max)
    return pd.DataFrame({"time": sim["time"].to_numpy(float), "v_x": vx, "v_y": vy, "omega": om,
                         "saturated": (vx != vx_raw) | (vy != vy_raw) | (om != dth)})
