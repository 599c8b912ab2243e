"""Baseline predictors of docs/methods.md sec. 7, with the ``Predictor`` interface of ``predict``.

Both extrapolate the last measured displacement over the horizon ``H = N_OC - N0`` (prediction
``P_j`` for the sample ``k + j``, ``j = 0..H``, with ``P_0 = C_k``):

- constant velocity (``cv``): ``P_j = C_k + j (C_k - C_{k-1})`` for x, y and theta (the theta step is
  wrapped, so the extrapolation is continuous across +-pi);
- constant turn rate and velocity (``ctrv``): the path keeps its last speed ``s = ||C_k - C_{k-1}||``
  per sample and its last turn rate ``w = wrap(psi_k - psi_{k-1})`` per sample, ``psi_k`` the heading
  of the displacement ``C_k - C_{k-1}``: ``P_j = P_{j-1} + s (cos(psi_k + j w), sin(psi_k + j w))``,
  which is exact on a circle walked at constant speed. The orientation turns with the path:
  ``theta_j = theta_k + j w``. Below ``s < 1e-6`` m per sample the heading is undefined: ``w = 0``.

Neither needs the orientation: where theta is missing (NaN) only its prediction is NaN.
Offline (``predict_windows``) both predict every window of a trajectory at once, with the same
elementwise operations in the same order as ``predict``: the values are bit-identical.
"""

from __future__ import annotations

import numpy as np

from cobot_analysis.angles import angle_diff
from cobot_analysis.models.prediction.base import Predictor

STILL = 1e-6  # m per sample: below this the walker is at rest and has no heading


class ConstantVelocity(Predictor):
    """Constant-velocity model: the last displacement extrapolated."""

    name = "cv"
    min_past = 2

    def predict(self, past: np.ndarray) -> np.ndarray:
        step = past[-1] - past[-2]
        step[2] = angle_diff(past[-1, 2], past[-2, 2])
        return past[-1] + np.arange(self.horizon + 1)[:, None] * step

    def predict_windows(self, poses: np.ndarray, finite: np.ndarray) -> np.ndarray:
        """``predict`` of every window with x, y ``finite`` at once (C_k the window's last sample)."""
        k = np.flatnonzero(finite) + self.n0 - 1
        last, prev = poses[k], poses[k - 1]
        step = last - prev
        step[:, 2] = angle_diff(last[:, 2], prev[:, 2])
        out = np.full((finite.size, self.horizon + 1, 3), np.nan)
        out[finite] = last[:, None] + np.arange(self.horizon + 1)[:, None] * step[:, None]
        self.skipped = int(finite.size - k.size)
        return out


class ConstantTurnRateVelocity(Predictor):
    """Constant turn rate and velocity model (CTRV) on the path heading."""

    name = "ctrv"
    min_past = 3

    def predict(self, past: np.ndarray) -> np.ndarray:
        d1, d0 = past[-1, :2] - past[-2, :2], past[-2, :2] - past[-3, :2]
        speed = float(np.hypot(*d1))
        psi = np.arctan2(d1[1], d1[0])
        turn = float(angle_diff(psi, np.arctan2(d0[1], d0[0]))) if speed > STILL and np.hypot(*d0) > STILL else 0.0
        j = np.arange(self.horizon + 1)
        out = np.empty((self.horizon + 1, 3))
        steps = speed * np.stack([np.cos(psi + j[1:] * turn), np.sin(psi + j[1:] * turn)], axis=1)
        out[0, :2] = past[-1, :2]
        out[1:, :2] = past[-1, :2] + np.cumsum(steps, axis=0)
        out[:, 2] = past[-1, 2] + j * turn
        return out

    def predict_windows(self, poses: np.ndarray, finite: np.ndarray) -> np.ndarray:
        """``predict`` of every window with x, y ``finite`` at once (C_k the window's last sample)."""
        k = np.flatnonzero(finite) + self.n0 - 1
        d1, d0 = poses[k, :2] - poses[k - 1, :2], poses[k - 1, :2] - poses[k - 2, :2]
        speed = np.hypot(d1[:, 0], d1[:, 1])
        psi = np.arctan2(d1[:, 1], d1[:, 0])
        moving = (speed > STILL) & (np.hypot(d0[:, 0], d0[:, 1]) > STILL)
        turn = np.where(moving, angle_diff(psi, np.arctan2(d0[:, 1], d0[:, 0])), 0.0)[:, None]
        j = np.arange(self.horizon + 1)
        heading = psi[:, None] + j[1:] * turn
        steps = speed[:, None, None] * np.stack([np.cos(heading), np.sin(heading)], axis=2)
        out = np.full((finite.size, self.horizon + 1, 3), np.nan)
        path = np.empty((k.size, self.horizon + 1, 3))
        path[:, 0, :2] = poses[k, :2]
        path[:, 1:, :2] = poses[k, None, :2] + np.cumsum(steps, axis=1)
        path[:, :, 2] = poses[k, 2][:, None] + j * turn
        out[finite] = path
        self.skipped = int(finite.size - k.size)
        return out
