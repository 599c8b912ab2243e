"""Time normalisation (docs/methods.md sec. 2.8): resample a trajectory over 0..100 % of its duration.

Endpoint convention: both ends are included. Sample ``j`` (0..N-1) lies at phase
``100 j / (N - 1)`` %, i.e. at time ``t_on + j (t_off - t_on) / (N - 1)``; sample 0 is the onset and
sample N-1 the offset (the published walking data: 500 samples, sample j at 0.2 j %). Values are
linearly interpolated between the two neighbouring frames; a sample next to a missing frame is
NaN (except where it falls exactly on a valid frame). Angles are interpolated unwrapped.
"""

from __future__ import annotations

import numpy as np

N_SAMPLES = 500


def phase(n: int = N_SAMPLES) -> np.ndarray:
    """Phase in % of the N samples: ``100 j / (N - 1)``."""
    return 100.0 * np.arange(n) / (n - 1)


def normalise(values: np.ndarray, onset: float, offset: float, n: int = N_SAMPLES) -> np.ndarray:
    """Resample ``values (T, ...)`` at the fractional frame positions ``onset + j (offset - onset)/(N-1)``.

    ``onset`` / ``offset`` are frame positions (may be fractional) inside ``[0, T - 1]``.
    Vectorised over all trailing columns: one call per trajectory.
    """
    values = np.asarray(values, dtype=float)
    pos = onset + (offset - onset) * np.arange(n) / (n - 1)
    lo = np.clip(np.floor(pos).astype(int), 0, len(values) - 1)
    hi = np.minimum(lo + 1, len(values) - 1)
    w = (pos - lo).reshape((n,) + (1,) * (values.ndim - 1))
    a, b = values[lo], values[hi]
    with np.errstate(invalid="ignore"):
        out = a + w * (b - a)
    return np.where(w == 0, a, out)  # exactly on a frame: that frame, even if the next is NaN
