"""Distances between time-normalised trajectories (METHODS.md sec. 3), vectorised.

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

    The last sample is left out (METHODS.md sec. 3): gamma of a generated path is defined from the
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
