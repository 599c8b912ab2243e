"""Angles: wrapping, unwrapping and circular means (radians throughout)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]


def wrap(angle: ArrayLike) -> FloatArray:
    """Wrap to (-pi, pi]: ``pi - ((pi - a) mod 2 pi)``. The mod is taken only where ``y = pi - a`` lies
    outside [0, 2 pi): inside it would return y itself (fmod is exact, and the sign of a zero y is lost
    in ``pi - y``), and it returns a NaN y unchanged, so every value is the mod's, at a fraction of its
    cost on wrapped angles and on NaN (where the mod is slowest)."""
    y = np.pi - np.asarray(angle, dtype=float)
    if y.ndim == 0:
        return np.pi - np.mod(y, 2 * np.pi)
    np.mod(y, 2 * np.pi, out=y, where=(y < 0) | (y >= 2 * np.pi))
    return np.pi - y


def angle_diff(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Smallest signed difference ``a - b`` wrapped to (-pi, pi]."""
    return wrap(np.asarray(a, dtype=float) - np.asarray(b, dtype=float))


def circular_mean(angles: ArrayLike, axis: int = 0, weights: ArrayLike | None = None) -> FloatArray:
    """Circular mean ``atan2(sum w sin a, sum w cos a)`` along ``axis``, ignoring NaN.

    Returns NaN where every value is NaN.
    """
    a = np.asarray(angles, dtype=float)
    w = np.ones_like(a) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), a.shape)
    valid = ~np.isnan(a)
    s = np.where(valid, w * np.sin(np.where(valid, a, 0.0)), 0.0).sum(axis=axis)
    c = np.where(valid, w * np.cos(np.where(valid, a, 0.0)), 0.0).sum(axis=axis)
    out = np.arctan2(s, c)
    return np.where(valid.any(axis=axis), out, np.nan)


def circular_median(angles: ArrayLike) -> float:
    """Circular median: the value whose summed angular distance to all others is least (NaN ignored; NaN if none).
    Unlike the circular mean it is not pulled by a few values half a turn away."""
    a = np.asarray(angles, dtype=float).ravel()
    a = a[np.isfinite(a)]
    if not a.size:
        return float("nan")
    cost = np.concatenate([np.abs(angle_diff(a[i:i + 1024, None], a[None, :])).sum(axis=1) for i in range(0, a.size, 1024)])
    return float(a[np.argmin(cost)])


def circular_std(angles: ArrayLike, axis: int = 0) -> FloatArray:
    """Circular standard deviation ``sqrt(-2 ln R)``, R the mean resultant length (NaN ignored)."""
    a = np.asarray(angles, dtype=float)
    with np.errstate(invalid="ignore"):
        r = np.hypot(np.nanmean(np.sin(a), axis=axis), np.nanmean(np.cos(a), axis=axis))
        return np.sqrt(-2.0 * np.log(np.clip(r, 1e-300, 1.0)))


def turns_with_path(x: ArrayLike, y: ArrayLike, theta: ArrayLike, limit: float) -> bool:
    """Whether an unwrapped heading ``theta`` that passes ``limit`` (rad) turns that far with its own path
    (laps of a track), not because it is in degrees: it starts within ``limit``, and its range is at most
    that of the path's tangent ``phi = unwrap(atan2(dy, dx))`` (over the steps longer than a tenth of the
    median step: the tangent of a walker at rest is noise) plus one turn. The same heading in degrees
    starts beyond ``limit`` (any start above 19 degrees for 3 turns) or spans about 57 times its path's
    turning. Samples with a NaN are left out."""
    x, y, th = (np.asarray(v, dtype=float) for v in (x, y, theta))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(th)
    x, y, th = x[ok], y[ok], th[ok]
    if len(th) < 3 or abs(th[0]) > limit:
        return False
    dx, dy = np.diff(x), np.diff(y)
    step = np.hypot(dx, dy)
    moving = step > 0.1 * np.median(step)
    if moving.sum() < 2:
        return False
    phi = np.unwrap(np.arctan2(dy[moving], dx[moving]))
    return bool(np.ptp(th) <= np.ptp(phi) + 2 * np.pi)
