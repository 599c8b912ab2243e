"""Markers from a true pose: rigid pelvis, gait oscillation, feet, head, table; noise and gaps.

Gait oscillation (added to the base path, scaled by the envelope ``e = tanh(v / 0.35 m/s)`` so it
vanishes at rest), with the stride phase ``psi = pi f_step t + psi0`` (one stride = two steps):

- lateral sway of the pelvis centre at the stride frequency ``f_step / 2`` (~0.9 Hz):
  ``a_lat e sin(psi)`` along the pelvis' left axis (``a_lat`` about 4-5 cm);
- vertical bob at the step frequency ``f_step`` (~1.8 Hz): ``a_z e cos(2 psi)`` (about 1.5-2 cm);
- pelvis yaw (transverse rotation) at the stride frequency: ``a_yaw e cos(psi)`` (about 3-4 deg);
- postural sway when standing: ``a_post (1 - e) (sin(2 pi 0.23 t + p1), sin(2 pi 0.31 t + p2))``
  (a few mm, speed below 1 cm/s), so that "at rest" is as still as a standing person, not frozen.

Pelvis markers are rigid in the pelvis frame (x forward, y left, z up) with their barycentre at the
true CoM: ``LASI (d/2, w/2, 0)``, ``RASI (d/2, -w/2, 0)``, ``LPSI (-d/2, p/2, 0.03)``,
``RPSI (-d/2, -p/2, 0.03)`` (w ~ 0.24 m ASIS-ASIS, p ~ 0.09 m PSIS-PSIS, d ~ 0.16 m ASIS->PSIS),
so the forward normal of RASI->LASI is the true theta. Table corners (table frame x along the
long side): ``TAB1 (-L/2, -W/2)``, ``TAB2 (L/2, -W/2)``, ``TAB3 (-L/2, W/2)``, at the table-top
height; centre = (TAB2 + TAB3) / 2, long axis = TAB1 -> TAB2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cobot_analysis.design import TABLE_SIZE
from cobot_analysis.io.protocol import SUBJECT_MARKERS, TABLE_MARKERS

STEP_FREQUENCY = 1.8  # Hz, mean step frequency (subject values 1.7-1.95)
LATERAL_SWAY = 0.045  # m, amplitude of the lateral pelvis sway (subject values 0.035-0.055)
VERTICAL_BOB = 0.018  # m, amplitude of the vertical pelvis oscillation
YAW_OSCILLATION = 0.06  # rad, amplitude of the pelvis yaw oscillation (~3.4 deg)
POSTURAL_SWAY = 0.003  # m, amplitude of the postural sway when standing
POSTURAL_FREQUENCIES = (0.23, 0.31)  # Hz, of the postural sway along x and y
ENVELOPE_SPEED = 0.35  # m/s, speed scale of the gait envelope e = tanh(v / ENVELOPE_SPEED)
NOISE_SD = 0.0007  # m, standard deviation of the measurement noise per coordinate
RATE = 200.0  # Hz, Vicon rate of both studies

SHORT_GAP_MAX = 16  # frames (0.08 s at 200 Hz): short gaps, fillable by interpolation
LONG_GAP_RANGE = (0.3, 2.0)  # s: long gaps that make the pelvis orientation unavailable
_SLOT = 40  # frames: short gaps are placed one per slot so that they never merge


@dataclass(frozen=True)
class Body:
    """Anthropometry of one subject (m)."""

    height: float
    pelvis_height: float  # ASIS height above the floor
    asis_width: float
    psis_width: float
    depth: float  # ASIS -> PSIS distance along the forward axis

    @classmethod
    def draw(cls, rng: np.random.Generator, height: float) -> "Body":
        return cls(height=height, pelvis_height=0.54 * height + rng.normal(0, 0.01),
                   asis_width=float(np.clip(rng.normal(0.24, 0.012), 0.21, 0.27)),
                   psis_width=float(np.clip(rng.normal(0.09, 0.008), 0.07, 0.11)),
                   depth=float(np.clip(rng.normal(0.16, 0.01), 0.13, 0.19)))


@dataclass(frozen=True)
class Gait:
    """Gait oscillation parameters of one subject (or one recording)."""

    f_step: float = STEP_FREQUENCY
    a_lat: float = LATERAL_SWAY
    a_z: float = VERTICAL_BOB
    a_yaw: float = YAW_OSCILLATION
    psi0: float = 0.0
    a_post: float = POSTURAL_SWAY
    post_phase: tuple[float, float] = (0.0, 0.0)

    @classmethod
    def draw(cls, rng: np.random.Generator, scale: float = 1.0) -> "Gait":
        return cls(f_step=float(rng.uniform(1.7, 1.95)), a_lat=scale * float(rng.uniform(0.035, 0.055)),
                   a_z=scale * float(rng.uniform(0.014, 0.022)), a_yaw=float(rng.uniform(0.04, 0.08)),
                   psi0=float(rng.uniform(0, 2 * np.pi)), a_post=float(rng.uniform(0.5, 1.0)) * POSTURAL_SWAY,
                   post_phase=(float(rng.uniform(0, 2 * np.pi)), float(rng.uniform(0, 2 * np.pi))))


def envelope(speed) -> np.ndarray:
    """Gait envelope ``e = tanh(v / ENVELOPE_SPEED)``: 0 at rest, ~1 when walking."""
    return np.tanh(np.asarray(speed, dtype=float) / ENVELOPE_SPEED)


def speed_of(xy: np.ndarray, rate: float) -> np.ndarray:
    """Speed of a sampled horizontal path (central differences)."""
    return np.hypot(*np.gradient(xy, 1.0 / rate, axis=0).T)


def oscillate(t, xy, theta, speed, gait: Gait):
    """Gait oscillation and postural sway of a base path -> (true CoM xy, vertical offset, true pelvis theta)."""
    t = np.asarray(t)
    e = envelope(speed)
    psi = np.pi * gait.f_step * t + gait.psi0
    lat = gait.a_lat * e * np.sin(psi)
    left = np.column_stack([-np.sin(theta), np.cos(theta)])
    post = gait.a_post * (1.0 - e)[:, None] * np.column_stack(
        [np.sin(2 * np.pi * f * t + p) for f, p in zip(POSTURAL_FREQUENCIES, gait.post_phase)])
    return xy + lat[:, None] * left + post, gait.a_z * e * np.cos(2 * psi), theta + gait.a_yaw * e * np.cos(psi)


def _place(origin_xy, z, theta, local) -> np.ndarray:
    """Points given in a yawed frame -> world: (n, k, 3)."""
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    lx, ly, lz = (np.asarray(v, dtype=float)[None, :] for v in np.asarray(local).T)
    out = np.empty((len(theta), len(local), 3))
    out[..., 0] = origin_xy[:, 0:1] + c * lx - s * ly
    out[..., 1] = origin_xy[:, 1:2] + s * lx + c * ly
    out[..., 2] = np.asarray(z)[:, None] + lz
    return out


def subject_markers(t, com_xy, dz, theta, speed, body: Body, gait: Gait) -> np.ndarray:
    """The 14 markers of ``SUBJECT_MARKERS`` (pelvis, feet, head) -> (n, 14, 3) in metres.

    ``com_xy``, ``dz``, ``theta``: true pelvis CoM, vertical gait offset and pelvis orientation.
    Feet alternate at the stride phase; the head rides above the pelvis.
    """
    n = len(theta)
    d, w, p = body.depth, body.asis_width, body.psis_width
    pelvis = _place(com_xy, body.pelvis_height + dz, theta,
                    [(d / 2, w / 2, 0.0), (d / 2, -w / 2, 0.0), (-d / 2, p / 2, 0.03), (-d / 2, -p / 2, 0.03)])
    e = envelope(speed)
    psi = np.pi * gait.f_step * np.asarray(t) + gait.psi0
    feet = []
    for side, shift in ((1.0, 0.0), (-1.0, np.pi)):  # left, right foot half a stride apart
        ph = psi + shift
        fwd = 0.32 * e * np.sin(ph)
        lift = 0.08 * e * np.clip(np.cos(ph), 0.0, None) ** 2
        heel_xy = com_xy + fwd[:, None] * np.column_stack([np.cos(theta), np.sin(theta)])
        local = [(-0.05, side * 0.09, 0.0), (0.15, side * 0.08, -0.03), (0.11, side * 0.13, -0.035)]  # HEE TOE MT5
        feet.append(_place(heel_xy, 0.07 + lift, theta, local))
    head = _place(com_xy, np.full(n, body.height - 0.08), theta,
                  [(0.09, 0.07, 0.0), (0.09, -0.07, 0.0), (-0.10, 0.07, 0.0), (-0.10, -0.07, 0.0)])
    out = np.concatenate([pelvis, feet[0], feet[1], head], axis=1)
    assert out.shape[1] == len(SUBJECT_MARKERS)
    return out


def table_markers(centre_xy, theta, z_top) -> np.ndarray:
    """The 3 corner markers ``TAB1 TAB2 TAB3`` -> (n, 3, 3) at the table-top height ``z_top``."""
    half_l, half_w = TABLE_SIZE[0] / 2, TABLE_SIZE[1] / 2
    out = _place(centre_xy, z_top, theta, [(-half_l, -half_w, 0.0), (half_l, -half_w, 0.0), (-half_l, half_w, 0.0)])
    assert out.shape[1] == len(TABLE_MARKERS)
    return out


def add_noise(rng: np.random.Generator, xyz: np.ndarray, sd: float = NOISE_SD) -> np.ndarray:
    """Measurement noise: i.i.d. Gaussian ``N(0, sd^2)`` on every coordinate."""
    return xyz + rng.normal(0.0, sd, xyz.shape)


@dataclass(frozen=True)
class LongGap:
    marker: int  # column in the recording's marker list
    start: int  # first missing frame
    stop: int  # first visible frame after the gap


def plan_gaps(rng: np.random.Generator, n_frames: int, n_markers: int, *, long_markers=(), long_window=None,
              short_rate: float = 0.4, p_end: float = 0.08, rate: float = RATE) -> tuple[np.ndarray, list[LongGap]]:
    """Occlusions of one recording -> (missing mask (frames, markers), long gaps).

    - short gaps of 1..``SHORT_GAP_MAX`` frames, Poisson(``short_rate``) per marker, at most one per
      40-frame slot and never touching another gap (so each stays short and fillable);
    - one long gap of ``LONG_GAP_RANGE`` seconds on one of ``long_markers`` (when given) inside
      ``long_window = (first, stop)`` frames (the motion);
    - with probability ``p_end`` each: a short run of a random marker missing at the very start,
      and likewise at the very end of the recording.
    """
    missing = np.zeros((n_frames, n_markers), dtype=bool)
    longs: list[LongGap] = []
    if len(long_markers):
        marker = int(long_markers[rng.integers(len(long_markers))])
        first, stop = long_window if long_window is not None else (0, n_frames)
        length = min(int(round(rng.uniform(*LONG_GAP_RANGE) * rate)), max(stop - first - 2, 1))
        start = int(rng.integers(first + 1, max(stop - length, first + 2)))
        missing[start:start + length, marker] = True
        longs.append(LongGap(marker, start, start + length))
    n_slots = n_frames // _SLOT
    if n_slots > 2:
        for m in range(n_markers):
            k = min(int(rng.poisson(short_rate)), n_slots - 2)
            for slot in rng.choice(np.arange(1, n_slots - 1), size=k, replace=False):
                length = int(rng.integers(1, SHORT_GAP_MAX + 1))
                start = int(slot * _SLOT + rng.integers(1, _SLOT - length))
                if missing[max(start - 2, 0):start + length + 2, m].any():  # would touch a long gap
                    continue
                missing[start:start + length, m] = True
    for at_end in (False, True):
        if rng.random() < p_end:
            m, length = int(rng.integers(n_markers)), int(rng.integers(1, SHORT_GAP_MAX + 1))
            if at_end:
                missing[n_frames - length:, m] = True
            else:
                missing[:length, m] = True
    return missing, longs
