"""Errors of receding-horizon predictions against the recorded trajectory (docs/methods.md sec. 7).

Predictions of one trajectory are an array ``P`` of shape ``(W, H + 1, 3)``: window ``w`` is the
prediction made at sample ``k = N0 - 1 + w`` (0-based; docs/methods.md counts from 1) for the samples
``k .. k + H`` with ``H = N_OC - N0``; a skipped window is all NaN. Columns are (x, y, theta).

With ``N_k = min(k + H, N - 1) - k + 1`` the recorded samples a window can be compared with:

- ``delta_xy    = (1/N_hum) sum_k (1/N_k) sum_{i=k}^{k+N_k-1} ||c_i - x*_i||``
- ``delta_theta = (1/N_hum) sum_k (1/N_k) sum_{i=k}^{k+N_k-1} |wrap(ctheta_i - theta*_i)|``
- ``d_pred      = (1/N_hum) sum_k ||x*_k - x*_{k+H}||`` (how far ahead the prediction reaches)
- ``ADE = mean over full-horizon windows of (1/H) sum_{j=1}^{H} ||c_{k+j} - x*_{k+j}||``
- ``FDE = mean over full-horizon windows of ||c_{k+H} - x*_{k+H}||``

``N_hum = N - N0 + 1`` windows when none is skipped; skipped windows (NaN in the measured past
or a failed solve) are left out of every mean and counted. ADE/FDE use the strictly future samples
of windows whose whole horizon lies inside the recording (``k + H <= N - 1``), the usual
fixed-horizon definition; they are NaN when no window has a full horizon.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from cobot_analysis.angles import angle_diff


@dataclass(frozen=True)
class WindowErrors:
    """Per-window errors (arrays of length W; NaN for skipped windows)."""

    error_xy: np.ndarray  # (1/N_k) sum ||c_i - x*_i|| over k..k+N_k-1 (m)
    error_theta: np.ndarray  # same with |wrap(ctheta_i - theta*_i)| (rad)
    reach: np.ndarray  # ||x*_k - x*_{k+H}|| (m)
    ade: np.ndarray  # mean future error over a full horizon (m); NaN if the horizon is cut
    fde: np.ndarray  # error at k + H (m); NaN if the horizon is cut
    valid: np.ndarray  # bool: the window has a prediction


def truth_windows(poses: np.ndarray, n0: int, horizon: int) -> np.ndarray:
    """The recorded poses each window is compared with, shape (W, H + 1, 3), NaN past the end."""
    poses = np.asarray(poses, dtype=float)
    padded = np.concatenate([poses, np.full((horizon, poses.shape[1]), np.nan)])
    view = np.lib.stride_tricks.sliding_window_view(padded, horizon + 1, axis=0)  # (N, 3, H+1)
    return view[n0 - 1: poses.shape[0]].transpose(0, 2, 1)


def window_errors(poses: np.ndarray, predictions: np.ndarray, n0: int) -> WindowErrors:
    """Errors of every window of ``predictions`` (W, H + 1, 3) against ``poses`` (N, 3)."""
    predictions = np.asarray(predictions, dtype=float)
    horizon = predictions.shape[1] - 1
    truth = truth_windows(poses, n0, horizon)
    valid = np.isfinite(predictions[:, 0, :2]).all(axis=1)
    e_xy = np.hypot(truth[..., 0] - predictions[..., 0], truth[..., 1] - predictions[..., 1])
    e_th = np.abs(angle_diff(truth[..., 2], predictions[..., 2]))
    with warnings.catch_warnings():  # all-NaN rows give NaN on purpose ("mean of empty slice")
        warnings.simplefilter("ignore", RuntimeWarning)
        error_xy = np.nanmean(e_xy, axis=1)
        error_theta = np.nanmean(e_th, axis=1)
        full = np.isfinite(truth[:, -1, :2]).all(axis=1) & valid
        ade = np.where(full, np.nanmean(e_xy[:, 1:], axis=1) if horizon else np.nan, np.nan)
    fde = np.where(full, e_xy[:, -1], np.nan)
    reach = np.hypot(*(predictions[:, 0, :2] - predictions[:, -1, :2]).T)
    nan = np.where(valid, 1.0, np.nan)
    return WindowErrors(error_xy * nan, error_theta * nan, reach * nan, ade, fde, valid)


@dataclass(frozen=True)
class PredictionMetrics:
    """docs/methods.md sec. 7 metrics of one trajectory and the window counts behind them."""

    delta_xy: float
    delta_theta: float
    d_pred: float
    ade: float
    fde: float
    n_windows: int  # N_hum = N - N0 + 1
    n_used: int  # windows with a prediction
    n_full: int  # windows with a full horizon (behind ADE/FDE)


def summarise(errors: WindowErrors, use: np.ndarray | None = None) -> PredictionMetrics:
    """Average per-window errors over the windows in ``use`` (default: every valid window)."""
    use = errors.valid if use is None else (np.asarray(use, dtype=bool) & errors.valid)

    def mean(values: np.ndarray) -> float:
        v = values[use]
        v = v[np.isfinite(v)]
        return float(v.mean()) if v.size else float("nan")

    return PredictionMetrics(
        delta_xy=mean(errors.error_xy), delta_theta=mean(errors.error_theta), d_pred=mean(errors.reach),
        ade=mean(errors.ade), fde=mean(errors.fde), n_windows=int(errors.valid.size), n_used=int(use.sum()),
        n_full=int((use & np.isfinite(errors.ade)).sum()),
    )
