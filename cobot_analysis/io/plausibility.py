"""Plausibility of marker positions: what a motion-capture volume and a moving body allow.

A position that no lab can record is refused, never averaged (a corrupt byte in a C3D data block
turns 950 mm into 1e35 m). Three checks on every visible sample of the markers kept:

- finite: +-inf is not a position (NaN is an occluded sample, as the readers mark it);
- inside the lab: ``|x|, |y|, |z| <= lab_extent`` (default ``LAB_EXTENT`` = 100 m from the lab
  origin: the largest motion-capture volumes, sports halls, span a few tens of metres);
- no jump: between two consecutive visible samples ``i < j`` of a marker, the displacement over
  ``(j - i) / rate`` stays below ``max_speed`` (default ``MAX_SPEED`` = 20 m/s: markers of walking
  and running people stay below about 10 m/s, the feet of the recordings in ``../shared/realdata``
  below 6 m/s). A corrupt value, or a marker swapped with another for some frames, jumps by
  metres (or tens of centimetres) within one frame.

The limits are options of ``import`` (``--lab-extent``, ``--max-speed``) and are stored in the
metadata of ``markers.parquet`` so that ``preprocess`` applies the same ones.
"""

from __future__ import annotations

import os

import numpy as np

from cobot_analysis.errors import InputError

#: m: largest |coordinate| of a marker from the lab origin.
LAB_EXTENT = 100.0
#: m/s: largest marker speed between consecutive visible samples.
MAX_SPEED = 20.0

REMEDY = ("check the trial in the capture software (a corrupt file or a mislabelled marker) and re-export it, "
          "or leave it out of the protocol")


def _where(labels: list[str], bad: np.ndarray, rate: float, limit: int = 3) -> str:
    """'LASI (frames 10-12, t = 0.05 s), RASI (frame 40, ...)' for a (frames, markers) mask."""
    parts = []
    for k in np.flatnonzero(bad.any(axis=0))[:limit]:
        frames = np.flatnonzero(bad[:, k])
        span = f"frame {frames[0]}" if len(frames) == 1 else f"{len(frames)} samples in frames {frames[0]}-{frames[-1]}"
        parts.append(f"{labels[k]} ({span}, from t = {frames[0] / rate:.3f} s)")
    more = int(bad.any(axis=0).sum()) - limit
    return ", ".join(parts) + (f" and {more} more markers" if more > 0 else "")


def check_positions(xyz: np.ndarray, labels: list[str], rate: float, path: str | os.PathLike, *,
                    lab_extent: float = LAB_EXTENT, max_speed: float = MAX_SPEED, what: str = "") -> None:
    """Refuse marker positions ``xyz [frames, markers, 3]`` (m, NaN = occluded) that no lab records.

    Raises ``InputError`` naming the file (``what``: e.g. 'trial t1: ') with the markers, frames and
    values at fault. Frames count from 0 at the first sample of the recording.
    """
    xyz = np.asarray(xyz, dtype=float)
    with np.errstate(invalid="ignore"):
        infinite = np.isinf(xyz).any(axis=2)
        if infinite.any():
            raise InputError(f"{what}infinite marker coordinates: {_where(labels, infinite, rate)}", path=path, remedy=REMEDY)
        far = (np.abs(xyz) > lab_extent).any(axis=2)
        if far.any():
            worst = float(np.nanmax(np.abs(xyz)))
            raise InputError(f"{what}implausible marker positions, up to {worst:.3g} m from the lab origin (limit {lab_extent:g} m): "
                             f"{_where(labels, far, rate)}", path=path,
                             remedy=f"{REMEDY}; a lab larger than {lab_extent:g} m: import with --lab-extent")
    visible = ~np.isnan(xyz).any(axis=2)
    jumps = []  # (first frame, marker, next frame, step, speed, number of jumps of that marker)
    for k in range(xyz.shape[1]):  # markers, never frames
        idx = np.flatnonzero(visible[:, k])
        if len(idx) < 2:
            continue
        step = np.linalg.norm(np.diff(xyz[idx, k], axis=0), axis=1)
        speed = step * rate / np.diff(idx)
        fast = np.flatnonzero(speed > max_speed)
        if fast.size:
            i = fast[0]
            jumps.append((int(idx[i]), k, int(idx[i + 1]), float(step[i]), float(speed[i]), len(fast)))
    if jumps:
        a, k, b, step, speed, _ = min(jumps)
        total = sum(j[5] for j in jumps)
        more = f"; {total} jumps over the limit in {len(jumps)} marker(s)" if total > 1 else ""
        raise InputError(f"{what}implausible jump of marker {labels[k]}: {step:.3g} m between frames {a} and {b} "
                         f"(t = {a / rate:.3f} s), {speed:.3g} m/s (limit {max_speed:g} m/s){more}", path=path,
                         remedy=f"{REMEDY}; a marker that really moves faster: import with --max-speed")
