"""Distances between time-normalised trajectories (docs/methods.md sec. 3), vectorised.

Every function takes arrays whose last axis is the sample axis (N samples), so a batch of
trajectory pairs of shape ``(..., N)`` is compared in one call without a Python loop.
"""

from __future__ import annotations

import numpy as np

from cobot_analysis.angles import angle_diff


def d_xy(x1, y1, x2, y2):
    """Linear distance ``d_xy = (1/N) sum_i sqrt((x1_i - x2_i)^2 + (y1_i - y2_i)^2)`` (m)."""
    return np.mean(np.hypot(np.asarray(x1) - np.asarray(x2), np.asarray(y1) - np.asarray(y2)), axis=-1)


def d_theta(theta1, theta2):
    """Angular distance ``d_theta = (1/N) sum_i |wrap(theta1_i - theta2_i)|`` (rad)."""
    return np.mean(np.abs(angle_diff(theta1, theta2)), axis=-1)


def d_gamma(gamma1, gamma2):
    """Local angular distance ``d_gamma = (1/(N-1)) sum_{i<N} |wrap(gamma1_i - gamma2_i)|`` (rad).

    The last sample is left out (docs/methods.md sec. 3): gamma of a generated path is defined from the
    step i -> i+1 (see ``gamma_from_path``).
    """
    return np.mean(np.abs(angle_diff(np.asarray(gamma1)[..., :-1], np.asarray(gamma2)[..., :-1])), axis=-1)


def gamma_from_path(x, y, theta):
    """Local orientation of a generated path: ``gamma_i = atan2(y_{i+1} - y_i, x_{i+1} - x_i) - theta_i``.

    Defined for i < N; the last sample repeats the previous value so the length stays N. Wrapped
    to (-pi, pi].
    """
    x, y, theta = (np.asarray(v, dtype=float) for v in (x, y, theta))
    heading = np.arctan2(np.diff(y, axis=-1), np.diff(x, axis=-1))
    g = angle_diff(heading, theta[..., :-1])
    return np.concatenate([g, g[..., -1:]], axis=-1)


# ---- distances over many pairs at once ------------------------------------------------------------
def pair_distances(a: dict, b: dict, ia, ib) -> dict[str, np.ndarray]:
    """d_xy, d_theta, d_gamma between trajectories ``a[k][ia[j]]`` and ``b[k][ib[j]]`` for every j.

    ``a`` and ``b`` map "x", "y", "theta", "gamma" to arrays (n_traj, N); ``ia``/``ib`` are index
    arrays of equal length. Angular distances are NaN where either trajectory lacks orientation
    at some sample (docs/methods.md sec. 2.9: such trials leave only the orientation comparison).
    Work is done in blocks so that memory stays bounded for tens of thousands of pairs.
    """
    ia, ib = np.asarray(ia, dtype=int), np.asarray(ib, dtype=int)
    out = {k: np.full(len(ia), np.nan) for k in ("d_xy", "d_theta", "d_gamma")}
    block = 4096
    for s in range(0, len(ia), block):
        i, j = ia[s:s + block], ib[s:s + block]
        out["d_xy"][s:s + block] = d_xy(a["x"][i], a["y"][i], b["x"][j], b["y"][j])
        for key, fn in (("theta", d_theta), ("gamma", d_gamma)):
            if key in a and key in b:
                with np.errstate(invalid="ignore"):
                    out[f"d_{key}"][s:s + block] = fn(a[key][i], b[key][j])
    return out


def reverse_time(values):
    """A trajectory travelled backwards in time: sample i becomes sample N-1-i (last axis)."""
    return np.asarray(values)[..., ::-1]


def symmetry(x_fwd, y_fwd, theta_fwd, x_ret, y_ret, theta_ret):
    """Forward/return symmetry (docs/methods.md sec. 3): d_xy and d_theta between the forward path and
    the time-reversed return path. Returns ``(d_xy, d_theta)``.

    Orientation is compared as is: a carrier who walks the return facing the same way as on the
    forward path (e.g. walking backwards) has d_theta = 0; one who turns round has d_theta ~ pi.
    """
    return (d_xy(x_fwd, y_fwd, reverse_time(x_ret), reverse_time(y_ret)),
            d_theta(theta_fwd, reverse_time(theta_ret)))


def travelled_distance(x, y):
    """Straight-line distance from start to end position ``D = |p_{N-1} - p_0|`` (m, docs/methods.md sec. 3)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    return np.hypot(x[..., -1] - x[..., 0], y[..., -1] - y[..., 0])


def path_length(x, y):
    """Length of the polyline through the samples ``sum_i |p_{i+1} - p_i|`` (m)."""
    return np.sum(np.hypot(np.diff(x, axis=-1), np.diff(y, axis=-1)), axis=-1)


def travel_time(onset, offset):
    """Travel time = carriage offset - onset (s, docs/methods.md sec. 3)."""
    return np.asarray(offset, dtype=float) - np.asarray(onset, dtype=float)


def optimal_configurations(d_by_config: dict, tol: float = 0.05) -> set:
    """Configurations that minimise a distance among the configurations of a goal (docs/methods.md sec. 3).

    ``d_by_config`` maps a configuration (e.g. an end orientation) to its travelled distance
    (D1, D2 or D1 + D2). Configurations within ``tol`` metres of the minimum all count as optimal
    ("on a goal where both configurations give equal distances, both count as optimal").
    """
    valid = {k: v for k, v in d_by_config.items() if np.isfinite(v)}
    if not valid:
        return set()
    best = min(valid.values())
    return {k for k, v in valid.items() if v <= best + tol}
