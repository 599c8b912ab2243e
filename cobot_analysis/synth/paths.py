"""Smooth, human-like base paths: geometry (cubic Hermite + bulge) and speed profiles.

A base path is the trajectory of a pelvis CoM or table centre *without* gait oscillation:

- geometry: cubic Hermite curve ``p(u) = h00 p0 + h10 m0 + h01 p1 + h11 m1`` (u in [0, 1]) with
  tangents ``m0 = k d (cos phi0, sin phi0)``, ``m1 = k d (cos phi1, sin phi1)`` (d = |p1 - p0|),
  plus a lateral bulge ``b sin^2(pi u) n`` (n the left normal of the chord), re-sampled by arc length;
- timing: the arc length follows a smoothed trapezoidal speed profile
  ``v(t) = v_peak S(t / t_ramp) S((T - t) / t_ramp)`` with ``S(u) = 10u^3 - 15u^4 + 6u^5``
  (clipped to [0, 1]); speed and acceleration are zero at both ends (start and end at rest).
  With ``t_ramp = T / 2`` it is a bell-shaped (min-jerk-like) profile.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_FINE = 600  # samples of the Hermite curve before re-sampling by arc length


def smoothstep(u):
    """Quintic smoothstep ``S(u) = 10u^3 - 15u^4 + 6u^5`` on [0, 1], 0 below, 1 above."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


def motion_duration(length: float, v_peak: float, t_ramp: float) -> float:
    """Duration of a trapezoidal profile reaching ``v_peak``: ``T = L / v_peak + t_ramp``.

    When the distance is too short to reach ``v_peak`` (``L / v_peak < t_ramp``) the profile is a
    bell of duration ``T = 2 sqrt(L t_ramp / v_peak)`` (continuous at ``L = v_peak t_ramp``).
    """
    if length / v_peak >= t_ramp:
        return length / v_peak + t_ramp
    return 2.0 * np.sqrt(length * t_ramp / v_peak)


def arc_fraction(t, duration: float, t_ramp: float, t_ramp_end: float | None = None):
    """Travelled fraction of the path at times ``t`` (0 at t <= 0, 1 at t >= T).

    Integral of ``S(t / r1) S((T - t) / r2)``, normalised, with ``r1 = t_ramp`` and
    ``r2 = t_ramp_end`` (default ``t_ramp``), scaled down if ``r1 + r2 > T``.
    """
    r1, r2 = t_ramp, t_ramp if t_ramp_end is None else t_ramp_end
    scale = min(1.0, duration / (r1 + r2))
    r1, r2 = r1 * scale, r2 * scale
    t = np.clip(np.asarray(t, dtype=float), 0.0, duration)
    fine = np.linspace(0.0, duration, 2001)
    v = smoothstep(fine / r1) * smoothstep((duration - fine) / r2)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(fine))])
    return np.interp(t, fine, s / s[-1])


def hermite(p0, p1, phi0: float, phi1: float, k: float = 1.0, bulge: float = 0.0, n: int = _FINE) -> np.ndarray:
    """Cubic Hermite curve from ``p0`` heading ``phi0`` to ``p1`` heading ``phi1`` plus a bulge.

    Returns ``(n, 2)`` points at uniform u (not arc length).
    """
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    chord = p1 - p0
    d = float(np.hypot(*chord))
    u = np.linspace(0.0, 1.0, n)[:, None]
    h00, h10, h01, h11 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2, u**3 - u**2
    m0 = k * d * np.array([np.cos(phi0), np.sin(phi0)])
    m1 = k * d * np.array([np.cos(phi1), np.sin(phi1)])
    pts = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
    if bulge and d > 0:
        normal = np.array([-chord[1], chord[0]]) / d
        pts = pts + bulge * np.sin(np.pi * u) ** 2 * normal  # zero slope at the ends: tangents kept
    return pts


@dataclass
class BasePath:
    """A base path sampled at the frames of its motion (``t = 0 .. T`` inclusive)."""

    t: np.ndarray  # (m,) s from onset
    xy: np.ndarray  # (m, 2) m
    heading: np.ndarray  # (m,) rad, unwrapped tangent direction of the geometry
    speed: np.ndarray  # (m,) m/s
    length: float  # m, arc length

    @property
    def duration(self) -> float:
        return float(self.t[-1])


def along(points: np.ndarray, duration: float, t_ramp: float, rate: float, t_ramp_end: float | None = None) -> BasePath:
    """Move along the polyline ``points`` in ``duration`` s with the smoothed trapezoidal profile
    (acceleration in ``t_ramp``, deceleration in ``t_ramp_end``, default ``t_ramp``).

    ``duration`` is rounded to whole frames; the returned path has ``round(T rate) + 1`` samples.
    """
    seg = np.hypot(*np.diff(points, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    length = float(cum[-1])
    n = max(int(round(duration * rate)), 2)
    duration = n / rate
    t = np.arange(n + 1) / rate
    s = arc_fraction(t, duration, t_ramp, t_ramp_end) * length
    xy = np.column_stack([np.interp(s, cum, points[:, 0]), np.interp(s, cum, points[:, 1])])
    tangent = np.gradient(points, cum, axis=0) if length > 0 else np.tile([1.0, 0.0], (len(points), 1))
    head_fine = np.unwrap(np.arctan2(tangent[:, 1], tangent[:, 0]))
    heading = np.interp(s, cum, head_fine)
    speed = np.gradient(s, t)
    speed[[0, -1]] = 0.0
    return BasePath(t, xy, heading, speed, length)


def turn_profile(t, duration: float, heading, theta0: float, thetaf: float, turn_start: float, turn_end: float):
    """Orientation along a path: ``theta = h + delta0 (1 - S(t / ts)) + deltaf S((t - T + te) / te)``.

    The body starts at ``theta0`` and turns toward the direction of travel ``h`` within ``ts``
    seconds, walks facing forward, and turns to ``thetaf`` in the last ``te`` seconds.
    ``delta0 = theta0 - h(0)`` and ``deltaf = thetaf - h(T)`` are taken as given (the caller
    chooses the turning direction by adding multiples of 2 pi).
    """
    t = np.asarray(t, dtype=float)
    heading = np.asarray(heading, dtype=float)
    d0 = theta0 - heading[0]
    df = thetaf - heading[-1]
    return heading + d0 * (1.0 - smoothstep(t / turn_start)) + df * smoothstep((t - duration + turn_end) / turn_end)

