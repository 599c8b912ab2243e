"""Plausibility of marker positions: what a motion-capture volume and a moving body allow.

A position that no lab can record is refused, never averaged (a corrupt byte in a C3D data block
turns 950 mm into 1e35 m). The sampling rate must be a motion-capture rate (``RATE_RANGE``,
1 Hz to 10 kHz: camera systems record at 50 Hz to a few kHz). Four checks on every visible
sample of the markers kept:

- finite: +-inf is not a position (NaN is an occluded sample, as the readers mark it);
- inside the lab: ``|x|, |y|, |z| <= lab_extent`` (default ``LAB_EXTENT`` = 100 m from the lab
  origin: the largest motion-capture volumes, sports halls, span a few tens of metres);
- no jump: between two consecutive visible samples ``i < j`` of a marker, the displacement over
  ``(j - i) / rate`` stays below ``max_speed`` (default ``MAX_SPEED`` = 20 m/s: markers of walking
  and running people stay below about 10 m/s, the feet of real gait recordings from other labs (BTKData, pyomeca)
  below 6 m/s). A corrupt value, or a marker swapped with another for some frames, jumps by
  metres (or tens of centimetres) within one frame;
- no spike: a sample between two visible neighbours lies within ``max_spike`` (default
  ``MAX_SPIKE`` = 5 cm) of their midpoint, unless the rate is so low that this is reached by an
  acceleration below ``MAX_ACCELERATION`` (1000 m/s^2, 100 g): the deviation of a smooth path
  from the midpoint is ``a / (2 rate^2)``; in real gait recordings (BTKData, pyomeca) it is
  at most 2.2 cm (a shank marker at 120 Hz), 0.5 to 9.5 mm for the pelvis markers.

Rates (``trial_rate``): the rate a file declares wins when it is valid; a protocol ``rate`` that
differs is a warning naming both; an invalid declared rate (0, negative, NaN) is refused unless
the protocol says ``invalid_rate: protocol``, never replaced silently.

The limits are options of ``import`` (``--lab-extent``, ``--max-speed``, ``--max-spike``) and are
stored in the metadata of ``markers.parquet`` so that ``preprocess`` applies the same ones
(docs/methods.md sec. 2).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from cobot_analysis.errors import InputError
from cobot_analysis.schema import LAB_EXTENT  # m: largest |coordinate| of a marker from the lab origin

#: m/s: largest marker speed between consecutive visible samples.
MAX_SPEED = 20.0
#: m: largest distance of a sample from the midpoint of its two neighbours (single-sample spike).
MAX_SPIKE = 0.05
#: m/s^2: accelerations no marker on a person or a table reaches (sets the spike limit below 100 Hz).
MAX_ACCELERATION = 1000.0
#: Hz: sampling rates of motion-capture recordings.
RATE_RANGE = (1.0, 10_000.0)

REMEDY = ("check the trial in the capture software (a corrupt file or a mislabelled marker) and re-export it, "
          "or leave it out of the protocol")
FAR_REMEDY = "positions in metres from an origin inside the capture volume"  # what a position beyond the lab means


def check_rate(rate: float, path: str | os.PathLike, what: str = "") -> None:
    """Refuse a sampling rate outside ``RATE_RANGE`` (a corrupt RATE parameter or header word)."""
    lo, hi = RATE_RANGE
    if not lo <= rate <= hi:
        raise InputError(f"{what}sampling rate {rate:.6g} Hz is not a motion-capture rate ({lo:g} to {hi:g} Hz)", path=path,
                         remedy="re-export the trial from the capture software (or give 'rate' in the protocol for a file without one)")


#: protocol ``invalid_rate`` values: refuse a file whose declared rate is invalid, or use the protocol's ``rate``.
INVALID_RATE_POLICIES = ("refuse", "protocol")


def trial_rate(declared: float | None, source: str, protocol_rate: float | None, invalid_rate: str,
               path: str | os.PathLike) -> tuple[float, list[str]]:
    """The sampling rate of a trial and the notes (warnings) it gives: ``(rate, notes)``.

    A valid rate the file declares (finite, > 0) wins; a protocol ``rate`` that differs is one
    note naming both. A declared rate that is invalid (0, negative, NaN: a damaged header) is
    refused, unless the protocol says ``invalid_rate: protocol`` (with its ``rate``): then the
    protocol's rate is used and said. A file that declares no rate (``declared`` None) takes the
    protocol's rate, said too. The rate used is checked against ``RATE_RANGE``.
    """
    name = Path(path).name
    if declared is not None and np.isfinite(declared) and declared > 0:
        check_rate(float(declared), path)
        if protocol_rate and abs(declared - protocol_rate) > 1e-9 * protocol_rate:
            return float(declared), [f"{name}: the file's rate {declared:g} Hz ({source}) differs from the protocol's rate "
                                     f"{protocol_rate:g} Hz; using the file's"]
        return float(declared), []
    if declared is None:
        if not protocol_rate:
            raise InputError("no sampling rate in the file", path=path, remedy="give 'rate' (Hz) in the protocol")
        check_rate(protocol_rate, path, "protocol ")
        return float(protocol_rate), [f"{name}: the file states no rate; using the protocol's rate {protocol_rate:g} Hz"]
    if invalid_rate == "protocol" and protocol_rate:
        check_rate(protocol_rate, path, "protocol ")
        return float(protocol_rate), [f"{name}: invalid rate {declared:g} Hz ({source}) replaced by the protocol's rate "
                                      f"{protocol_rate:g} Hz (invalid_rate: protocol)"]
    raise InputError(f"invalid sampling rate {declared:g} Hz ({source})", path=path,
                     remedy="re-export the trial from the capture software, or state its true rate in the protocol "
                            "('rate: HZ' and 'invalid_rate: protocol')")


def _where(labels: list[str], bad: np.ndarray, rate: float, limit: int = 3) -> str:
    """'LASI (frames 10-12, t = 0.05 s), RASI (frame 40, ...)' for a (frames, markers) mask."""
    parts = []
    for k in np.flatnonzero(bad.any(axis=0))[:limit]:
        frames = np.flatnonzero(bad[:, k])
        span = f"frame {frames[0]}" if len(frames) == 1 else f"{len(frames)} samples in frames {frames[0]}-{frames[-1]}"
        parts.append(f"{labels[k]} ({span}, from t = {frames[0] / rate:.3f} s)")
    more = int(bad.any(axis=0).sum()) - limit
    return ", ".join(parts) + (f" and {more} more markers" if more > 0 else "")


def _norm(dx: np.ndarray, dy: np.ndarray, dz: np.ndarray) -> np.ndarray:
    """``sqrt(dx^2 + dy^2 + dz^2)`` elementwise (the same sums as ``np.linalg.norm`` over a last axis of 3)."""
    return np.sqrt(dx * dx + dy * dy + dz * dz)


def check_positions(xyz: np.ndarray, labels: list[str], rate: float, path: str | os.PathLike, *,
                    lab_extent: float = LAB_EXTENT, max_speed: float = MAX_SPEED, max_spike: float = MAX_SPIKE,
                    what: str = "") -> None:
    """Refuse marker positions ``xyz [frames, markers, 3]`` (m, NaN = occluded) that no lab records.

    Raises ``InputError`` naming the file (``what``: e.g. 'trial t1: ') with the markers, frames and
    values at fault. Frames count from 0 at the first sample of the recording.
    """
    xyz = np.asarray(xyz, dtype=float)
    with np.errstate(invalid="ignore"):
        size = np.abs(xyz)
        # one pass for both (inf exceeds any finite limit, NaN none): the masks are made only when needed
        if (size > lab_extent).any() or (not lab_extent < np.inf and np.isinf(xyz).any()):
            infinite = np.isinf(xyz).any(axis=2)
            if infinite.any():
                raise InputError(f"{what}infinite marker coordinates: {_where(labels, infinite, rate)}", path=path, remedy=REMEDY)
            far = (size > lab_extent).any(axis=2)
            worst = float(np.nanmax(size))
            raise InputError(f"{what}implausible marker positions, up to {worst:.3g} m from the lab origin (limit {lab_extent:g} m): "
                             f"{_where(labels, far, rate)}", path=path,
                             remedy=f"{REMEDY}; " + (f"a lab larger than {lab_extent:g} m: import with --lab-extent up to {LAB_EXTENT:g}"
                                                     if lab_extent < LAB_EXTENT else f"the pipeline takes {FAR_REMEDY}"))
    x, y, z = (xyz[:, :, c] for c in range(3))  # (frames, markers) each: no reduction over a 3-long axis (slow)
    visible = ~(np.isnan(x) | np.isnan(y) | np.isnan(z))
    n_frames = len(xyz)
    if n_frames >= 2 and visible.any():  # every marker at once: each visible frame against the marker's previous visible one
        frames = np.arange(n_frames)[:, None]
        last = np.maximum.accumulate(np.where(visible, frames, -1), axis=0)  # latest visible frame <= f
        prev = np.vstack([np.full((1, xyz.shape[1]), -1), last[:-1]])  # latest visible frame < f (-1: none)
        pair = visible & (prev >= 0)
        src = np.maximum(prev, 0)
        with np.errstate(invalid="ignore", divide="ignore"):
            step = _norm(*(c - np.take_along_axis(c, src, axis=0) for c in (x, y, z)))
            speed = step * rate / (frames - src)
        fast = pair & (speed > max_speed)
        if fast.any():
            j, k = np.nonzero(fast)
            i = prev[j, k]
            at = np.lexsort((k, i))[0]  # the earliest jump is named (then the lowest marker index), all are counted
            a, kk, b = int(i[at]), int(k[at]), int(j[at])
            total = len(j)
            more = f"; {total} jumps over the limit in {len(np.unique(k))} marker(s)" if total > 1 else ""
            raise InputError(f"{what}implausible jump of marker {labels[kk]}: {float(step[b, kk]):.3g} m between frames {a} and {b} "
                             f"(t = {a / rate:.3f} s), {float(speed[b, kk]):.3g} m/s (limit {max_speed:g} m/s){more}", path=path,
                             remedy=f"{REMEDY}; a marker that really moves faster: import with --max-speed")
    spike_limit = max(max_spike, MAX_ACCELERATION / (2 * rate ** 2))
    triple = visible[:-2] & visible[1:-1] & visible[2:]  # (frames - 2, markers)
    with np.errstate(invalid="ignore"):
        dev = _norm(*(c[1:-1] - (c[:-2] + c[2:]) / 2 for c in (x, y, z)))
        spikes = triple & (dev > spike_limit)
    if spikes.any():
        i, k = np.argwhere(spikes)[0]
        raise InputError(f"{what}implausible spike of marker {labels[k]} at frame {i + 1} (t = {(i + 1) / rate:.3f} s): "
                         f"{dev[i, k]:.3g} m from the midpoint of its neighbours (limit {spike_limit:.3g} m); "
                         f"{int(spikes.sum())} such samples in {int(spikes.any(axis=0).sum())} marker(s)", path=path,
                         remedy=f"{REMEDY}; a marker that really moves so abruptly: import with --max-spike")
