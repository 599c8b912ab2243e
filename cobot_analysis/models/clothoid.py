"""Clothoid path model (docs/methods.md 5.2): one G1 clothoid arc between start and goal poses.

theta(s) = theta0 + k0 s + k1 s^2 / 2, fitted with the G1 Hermite interpolation of Bertolazzi &
Frego (2015) (``pyclothoids``), sampled at N points equally spaced in arc length. The walker
faces along the path (gamma = 0); the time law is the constant nominal speed (t = s / v_nominal).
"""

from __future__ import annotations

import numpy as np


def clothoid_path(start, goal, n_samples: int = 500):
    """``(s, x, y, theta)`` of the G1 clothoid from ``start`` to ``goal`` (poses (x, y, theta))."""
    from pyclothoids import Clothoid

    c = Clothoid.G1Hermite(float(start[0]), float(start[1]), float(start[2]),
                           float(goal[0]), float(goal[1]), float(goal[2]))
    s = np.linspace(0.0, c.length, n_samples)
    x0, y0, th0, k0, dk, _ = c.Parameters
    x, y = (np.asarray(v) for v in c.SampleXY(n_samples))
    theta = th0 + k0 * s + dk * s**2 / 2
    return s, x, y, theta
