"""Zero-phase low-pass Butterworth filter (docs/methods.md sec. 2.3), applied per continuous segment.

Order conventions (``convention``), for a requested ``order`` n and cut-off fc:

- ``"effective"`` (default): the forward-backward result has order n and -3 dB at fc. An
  (n/2)-th order design is run forward and backward, its cut-off raised by Winter's correction
  ``C = (2^(1/2) - 1)^(1/(2 (n/2)))`` (for n = 4 this is ``(2^(1/n_passes) - 1)^(1/4)`` with
  n_passes = 2, C = 0.802), applied on the pre-warped frequency
  ``tan(pi f_design / fs) = tan(pi fc / fs) / C`` so that the digital gain at fc is exactly
  ``1/sqrt(2)``. n must be even. This is the biomechanics reading of "4th-order zero-phase
  (zero-lag) Butterworth" (Winter: a 2nd-order filter passed twice is a 4th-order zero-lag
  filter), hence the default for docs/methods.md sec. 2.3.
- ``"design"``: an n-th order Butterworth designed at fc and run forward and backward
  (``scipy.signal.sosfiltfilt``; MATLAB ``butter(n, ...)`` + ``filtfilt``). The magnitude is
  squared, ``|H|^2 = 1 / (1 + (w/wc)^(2n))^2``: an effective order 2n with -6 dB (gain 1/2) at fc.

Either way the pelvis signal (< 5 Hz: gait at ~1.8 Hz) passes unchanged; the conventions differ
in how much 10-20 Hz noise remains.

NaN samples (long gaps left open) split a signal into continuous segments, each filtered on
its own; segments shorter than the filter's default padding are filtered with a shorter pad and
segments of fewer than 2 samples are left as they are.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

CUTOFF = 10.0  # Hz
ORDER = 4
CONVENTIONS = ("design", "effective")
DEFAULT_CONVENTION = "effective"


def design_cutoff(cutoff: float, rate: float, order: int, convention: str = DEFAULT_CONVENTION) -> tuple[int, float]:
    """``(design order, design cut-off Hz)`` of the filter run forward-backward under ``convention``."""
    if convention not in CONVENTIONS:
        raise ValueError(f"order convention must be one of {CONVENTIONS}, not {convention!r}")
    if not 0 < cutoff < rate / 2:
        raise ValueError(f"cut-off {cutoff} Hz must lie in (0, {rate / 2}) Hz (Nyquist)")
    if convention == "design":
        return order, cutoff
    if order % 2:
        raise ValueError(f"the 'effective' convention needs an even order (forward-backward doubles it), not {order}")
    half = order // 2
    c = (math.sqrt(2.0) - 1.0) ** (1.0 / (2 * half))
    warped = math.tan(math.pi * cutoff / rate) / c
    f = rate / math.pi * math.atan(warped)
    if f >= rate / 2:
        raise ValueError(f"corrected cut-off of {cutoff} Hz exceeds the Nyquist frequency at {rate} Hz")
    return half, f


@lru_cache(maxsize=64)
def butter_sos(cutoff: float, rate: float, order: int = ORDER, convention: str = DEFAULT_CONVENTION) -> np.ndarray:
    """Second-order sections of the Butterworth low-pass to run forward-backward (cached: do not modify)."""
    from scipy.signal import butter

    n, f = design_cutoff(cutoff, rate, order, convention)
    return butter(n, f, btype="low", fs=rate, output="sos")


def _padlen(sos: np.ndarray) -> int:
    """``scipy.signal.sosfiltfilt``'s default pad length."""
    return 3 * (2 * len(sos) + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum()))


def segments(missing: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of the runs of valid (not missing) samples."""
    m = np.concatenate([[True], np.asarray(missing, dtype=bool), [True]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return list(zip(edges[0::2], edges[1::2]))


@lru_cache(maxsize=64)
def _zi(sos_bytes: bytes, n_sections: int) -> np.ndarray:
    from scipy.signal import sosfilt_zi

    return sosfilt_zi(np.frombuffer(sos_bytes).reshape(n_sections, 6))


def filtfilt(sos: np.ndarray, x: np.ndarray, padlen: int) -> np.ndarray:
    """``scipy.signal.sosfiltfilt(sos, x, axis=0, padtype="odd", padlen=padlen)``, with the filter's
    steady-state initial conditions cached (computing them dominates for short signals)."""
    from scipy.signal import sosfilt

    zi = _zi(np.ascontiguousarray(sos, dtype=float).tobytes(), len(sos)).reshape((len(sos), 2) + (1,) * (x.ndim - 1))
    if padlen > 0:  # odd extension: 2 x_0 - x_k before, 2 x_-1 - x_-1-k after
        x = np.concatenate([2 * x[:1] - x[padlen:0:-1], x, 2 * x[-1:] - x[-2:-padlen - 2:-1]])
    y, _ = sosfilt(sos, x, axis=0, zi=zi * x[:1])
    y, _ = sosfilt(sos, y[::-1], axis=0, zi=zi * y[-1:])
    y = y[::-1]
    return y[padlen:len(y) - padlen] if padlen > 0 else y


def lowpass(x: np.ndarray, sos: np.ndarray) -> np.ndarray:
    """Zero-phase filter the columns of ``x (T, ...)`` along time, each continuous segment apart.

    Columns that share their NaN pattern (the usual case: x, y, z of a marker; all markers
    without gaps) are filtered together in one call.
    """
    x = np.asarray(x, dtype=float)
    flat = x.reshape(len(x), -1)
    missing = np.isnan(flat)
    if not missing.any():  # the usual case: one call for every column
        return filtfilt(sos, flat, min(_padlen(sos), len(flat) - 1)).reshape(x.shape) if len(flat) > 1 else x.copy()
    out = np.full_like(flat, np.nan)
    pad = _padlen(sos)
    groups: dict[bytes, list[int]] = {}
    for j, key in enumerate(np.packbits(missing, axis=0).T):  # columns, never samples
        groups.setdefault(key.tobytes(), []).append(j)
    for cols in groups.values():  # distinct gap patterns: a few per recording
        for a, b in segments(missing[:, cols[0]]):
            seg = flat[a:b][:, cols]
            out[a:b, cols] = seg if b - a < 2 else filtfilt(sos, seg, min(pad, b - a - 1))
    return out.reshape(x.shape)
