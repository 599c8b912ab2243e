"""Distances between time-normalised trajectories (docs/methods.md sec. 3), vectorised.

Every function takes arrays whose last axis is the sample axis (N samples), so a batch of
trajectory pairs of shape ``(..., N)`` is compared in one call without a Python loop.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from cobot_analysis.angles import angle_diff, wrap

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]


def d_xy(x1: ArrayLike, y1: ArrayLike, x2: ArrayLike, y2: ArrayLike) -> FloatArray:
    """Linear distance ``d_xy = (1/N) sum_i sqrt((x1_i - x2_i)^2 + (y1_i - y2_i)^2)`` (m)."""
    return np.mean(np.hypot(np.asarray(x1) - np.asarray(x2), np.asarray(y1) - np.asarray(y2)), axis=-1)


def d_theta(theta1: ArrayLike, theta2: ArrayLike, difference: str = "wrapped") -> FloatArray:
    """Angular distance ``d_theta = (1/N) sum_i |wrap(theta1_i - theta2_i)|`` (rad, sec. 3) over the last axis;
    ``difference="each"``: ``|wrap(theta1_i) - wrap(theta2_i)|``, the authors' scripts, which wrap each angle on
    its own, so that a pair across +-pi counts nearly 2 pi (sec. 11)."""
    a, b = np.asarray(theta1, dtype=float), np.asarray(theta2, dtype=float)
    if difference == "each":
        return np.mean(np.abs(wrap(a) - wrap(b)), axis=-1)
    return np.mean(np.abs(angle_diff(a, b)), axis=-1)


def d_gamma(gamma1: ArrayLike, gamma2: ArrayLike, difference: str = "wrapped") -> FloatArray:
    """Local angular distance ``d_gamma = (1/(N-1)) sum_{i<N} |wrap(gamma1_i - gamma2_i)|`` (rad), ``difference``
    as in ``d_theta``.

    The last sample is left out (docs/methods.md sec. 3): gamma of a generated path is defined from the
    step i -> i+1 (see ``gamma_from_path``).
    """
    return d_theta(np.asarray(gamma1)[..., :-1], np.asarray(gamma2)[..., :-1], difference)


def gamma_from_path(x: ArrayLike, y: ArrayLike, theta: ArrayLike) -> FloatArray:
    """Local orientation of a generated path: ``gamma_i = atan2(y_{i+1} - y_i, x_{i+1} - x_i) - theta_i``.

    Defined for i < N; the last sample repeats the previous value so the length stays N. Wrapped
    to (-pi, pi].
    """
    x, y, theta = (np.asarray(v, dtype=float) for v in (x, y, theta))
    heading = np.arctan2(np.diff(y, axis=-1), np.diff(x, axis=-1))
    g = angle_diff(heading, theta[..., :-1])
    return np.concatenate([g, g[..., -1:]], axis=-1)


# ---- one generated or measured path against a measured one, under a convention ---------------------
REPEATED = 1e-9  # m: a shorter step between two points of a path repeats the point (``resample_arclength``)


def resample_arclength(x: ArrayLike, y: ArrayLike, n: int) -> tuple[FloatArray, FloatArray]:
    """The authors' path resampling (docs/methods.md sec. 11): the points ``i`` with
    ``|x_{i+1} - x_i| + |y_{i+1} - y_i| > 0`` are kept (which drops repeated points and always the
    last one; here > ``REPEATED``: an OC solution's rounding, a step of 1e-16 m where the walker
    starts at rest, is a repeated point, and the spline through it would overshoot), an interpolating
    parametric cubic spline (scipy ``splprep``, s = 0, chord-length parameter u in [0, 1]) is fitted
    through them and evaluated at ``n`` equally spaced u."""
    from scipy.interpolate import splev, splprep

    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    keep = np.flatnonzero(np.abs(np.diff(x)) + np.abs(np.diff(y)) > REPEATED)
    if len(keep) < 4:
        raise ValueError(f"a path needs at least 4 distinct points to be resampled by arc length (has {len(keep)})")
    tck, _ = splprep([x[keep], y[keep]], s=0)
    xr, yr = splev(np.linspace(0.0, 1.0, n), tck)
    return np.asarray(xr), np.asarray(yr)


def resample_time(values: ArrayLike, n: int, *, authors: bool = False) -> FloatArray:
    """``values`` (one per node, equally spaced in time) at ``n`` samples equally spaced in time
    (linear interpolation). ``authors``: their mapping, sample i at node time i / n of the path
    (np.interp(arange(n), linspace(0, n, len(values)), values)), which stops 1/n short of the end."""
    values = np.asarray(values, dtype=float)
    if len(values) == n and not authors:
        return values
    src = np.linspace(0.0, n if authors else n - 1, len(values))
    return np.interp(np.arange(n), src, values)


def path_distances(measured: dict[str, ArrayLike], other: dict[str, ArrayLike], comparison: Any, *, measured_gamma: ArrayLike | None = None,
                   resample_measured: bool | None = None, measured_resampled: tuple | None = None) -> dict[str, float]:
    """d_xy, d_theta, d_gamma of ``other`` = (x, y, theta) against ``measured`` = (x, y, theta)
    (N samples) under a ``conventions.Comparison``:

    - ``time``: ``other`` on the measured samples by time (linear in normalised time if its length
      differs), then the pointwise distances of sec. 3;
    - ``arclength``: ``other``'s path resampled by arc length to N points (``resample_arclength``;
      the measured one too when ``comparison.both_resampled``, or ``resample_measured`` says so),
      its theta by time (``resample_time(authors=True)``); angles compared with
      ``comparison.angle_difference``.

    ``measured_resampled``: the measured (x, y) already resampled by arc length, for a caller comparing many
    paths with one measured path (the same values as resampling it here).
    gamma: ``measured_gamma`` when given (e.g. the published data's own), else from the measured
    path, and from the (resampled) path for ``other`` (``gamma_from_path``); d_gamma over the first
    N - 1 samples. With ``measured_gamma`` also ``d_theta_tangent``: ``other``'s theta against the
    measured path's tangent theta - gamma. NaN where a theta is NaN.
    """
    mx, my, mth = (np.asarray(v, dtype=float) for v in measured)
    ox, oy, oth = (np.asarray(v, dtype=float) for v in other)
    n = len(mx)
    mg = gamma_from_path(mx, my, mth) if measured_gamma is None else np.asarray(measured_gamma, dtype=float)
    if comparison.resample == "arclength":
        if comparison.both_resampled if resample_measured is None else resample_measured:
            mx, my = resample_arclength(mx, my, n) if measured_resampled is None else measured_resampled
        ox, oy = resample_arclength(ox, oy, n)
        oth = resample_time(oth, n, authors=True)
    else:
        ox, oy, oth = (resample_time(v, n) for v in (ox, oy, oth))
    with np.errstate(invalid="ignore"):
        out = {"d_xy": float(d_xy(mx, my, ox, oy)),
               "d_theta": float(d_theta(mth, oth, comparison.angle_difference)),
               "d_gamma": float(d_gamma(mg, gamma_from_path(ox, oy, oth), comparison.angle_difference))}
        if measured_gamma is not None:  # the model's theta against the measured path's tangent, theta - gamma
            out["d_theta_tangent"] = float(d_theta(mth - mg, oth, comparison.angle_difference))
    return out


# ---- distances over many pairs at once ------------------------------------------------------------
def pair_distances(a: dict[str, FloatArray], b: dict[str, FloatArray], ia: ArrayLike, ib: ArrayLike, angle_difference: str = "wrapped") -> dict[str, FloatArray]:
    """d_xy, d_theta, d_gamma between trajectories ``a[k][ia[j]]`` and ``b[k][ib[j]]`` for every j.

    ``a`` and ``b`` map "x", "y", "theta", "gamma" to arrays (n_traj, N); ``ia``/``ib`` are index
    arrays of equal length; ``angle_difference`` as in ``d_theta`` ("wrapped" or "each").
    Angular distances are NaN where either trajectory lacks orientation
    at some sample (docs/methods.md sec. 2.9: such trials leave only the orientation comparison).
    Work is done in blocks so that memory stays bounded for tens of thousands of pairs.
    """
    ia, ib = np.asarray(ia, dtype=int), np.asarray(ib, dtype=int)
    out = {k: np.full(len(ia), np.nan) for k in ("d_xy", "d_theta", "d_gamma")}
    block = 4096
    for s in range(0, len(ia), block):
        i, j = ia[s:s + block], ib[s:s + block]
        out["d_xy"][s:s + block] = d_xy(a["x"][i], a["y"][i], b["x"][j], b["y"][j])
        for key, distance in (("theta", d_theta), ("gamma", d_gamma)):
            if key in a and key in b:
                with np.errstate(invalid="ignore"):
                    out[f"d_{key}"][s:s + block] = distance(a[key][i], b[key][j], angle_difference)
    return out


def reverse_time(values: ArrayLike) -> FloatArray:
    """A trajectory travelled backwards in time: sample i becomes sample N-1-i (last axis)."""
    return np.asarray(values)[..., ::-1]


def travelled_distance(x: ArrayLike, y: ArrayLike) -> FloatArray:
    """Straight-line distance from start to end position ``D = |p_{N-1} - p_0|`` (m, docs/methods.md sec. 3)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    return np.hypot(x[..., -1] - x[..., 0], y[..., -1] - y[..., 0])


def path_length(x: ArrayLike, y: ArrayLike) -> FloatArray:
    """Length of the polyline through the samples ``sum_i |p_{i+1} - p_i|`` (m)."""
    return np.sum(np.hypot(np.diff(x, axis=-1), np.diff(y, axis=-1)), axis=-1)


def optimal_configurations(d_by_config: dict[Any, float], tol: float = 0.05) -> set[Any]:
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
