"""The ``Predictor`` interface of the trajectory predictors (docs/methods.md sec. 7): the measured poses
one at a time (``update``) or a whole trajectory (``predict_offline``), the windows skipped and failed,
and the check of an (N0, N_OC) setting. The predictors: ``predictor.OCPredictor`` and
``baselines.ConstantVelocity`` / ``ConstantTurnRateVelocity``; ``predictor.make_predictor`` makes one by name."""

from __future__ import annotations

from collections import deque

import numpy as np

from cobot_analysis.errors import InputError


class Predictor:
    """Receding-horizon predictor: ``update(pose) -> predicted path`` over ``N_OC - N0`` samples ahead."""

    name = "predictor"
    min_past = 1  # samples the model needs in its past window

    def __init__(self, n0: int, n_oc: int, dt: float = 1.0):
        check_setting(n0, n_oc, self.min_past)
        if not (np.isfinite(dt) and dt > 0):
            raise InputError(f"sampling period T_OC must be positive (got {dt})", remedy="pass a positive --t-oc")
        self.n0, self.n_oc, self.dt = int(n0), int(n_oc), float(dt)
        self.horizon = self.n_oc - self.n0
        self.reset()

    def reset(self) -> None:
        """Forget the past (a new trajectory)."""
        self._past: deque[np.ndarray] = deque(maxlen=self.n0)
        self.n_seen = 0  # poses seen since the reset: the current window ends at sample k = n_seen - 1
        self.skipped = 0  # windows with a NaN position in their past
        self.failed = 0  # windows where the model gave no prediction (solver failure)

    def update(self, pose) -> np.ndarray | None:
        """Add the measured pose ``C_k`` = (x, y, theta) and return the prediction for samples
        ``k .. k + H`` as an (H + 1, 3) array, or None while fewer than N0 poses were seen or when
        the window is skipped."""
        self._past.append(np.asarray(pose, dtype=float).reshape(3))
        self.n_seen += 1
        if len(self._past) < self.n0:
            return None
        past = np.array(self._past)
        return self._window(past, bool(np.isfinite(past[:, :2]).all()))

    def _window(self, past: np.ndarray, finite: bool) -> np.ndarray | None:
        """One window of ``update``: skipped unless x, y of the whole ``past`` are ``finite``."""
        if not finite:
            self.skipped += 1
            self.on_skip()
            return None
        path = self.predict(past)
        if path is None:
            self.failed += 1
        return path

    def predict_offline(self, poses: np.ndarray) -> np.ndarray:
        """Predictions for every window of a whole trajectory: (N - N0 + 1, H + 1, 3), NaN if skipped,
        the same as ``update`` in a loop (``predict_windows``), and the online state it leaves."""
        poses = np.asarray(poses, dtype=float)
        if poses.ndim != 2 or poses.shape[1] != 3:
            raise ValueError("poses must be an (N, 3) array of x, y, theta")
        if poses.shape[0] < self.n0:
            raise InputError(f"trajectory has {poses.shape[0]} samples, fewer than N0 = {self.n0}",
                             remedy="lower N0 or leave this trajectory out")
        self.reset()
        poses = np.array(poses)  # own C-ordered copy: the windows below are copies of its rows
        n0, n = self.n0, poses.shape[0]
        missing = np.concatenate([[0], np.cumsum(~np.isfinite(poses[:, :2]).all(axis=1))])
        finite = (missing[n0:] - missing[:-n0]) == 0  # window w (samples w .. w + N0 - 1) has x, y finite
        out = self.predict_windows(poses, finite)
        self.n_seen = n
        self._past.extend(poses[n - n0:])  # the online state after the last pose
        return out

    def predict_windows(self, poses: np.ndarray, finite: np.ndarray) -> np.ndarray:
        """Every window w of ``poses`` (the past: samples w .. w + N0 - 1, x, y ``finite[w]``) as ``update``
        does it, each past a fresh copy of its N0 rows, counting skipped and failed windows:
        (W, H + 1, 3), NaN where there is no prediction. A model may predict all windows at once instead."""
        n0 = self.n0
        out = np.full((finite.size, self.horizon + 1, 3), np.nan)
        for w in range(finite.size):
            self.n_seen = w + n0
            path = self._window(poses[w: w + n0].copy(), bool(finite[w]))
            if path is not None:
                out[w] = path
        return out

    # -- what a model implements ----------------------------------------------------------------
    def predict(self, past: np.ndarray) -> np.ndarray | None:
        """Prediction (H + 1, 3) for the samples k .. k + H from the past (N0, 3) (x, y finite)."""
        raise NotImplementedError

    def on_skip(self) -> None:
        """Called when a window is skipped (e.g. to drop a warm start)."""


def check_setting(n0: int, n_oc: int, min_past: int = 3) -> None:
    """Bad (N0, N_OC) settings are input errors: N_OC > N0 >= ``min_past``."""
    if n_oc <= n0:
        raise InputError(f"N_OC = {n_oc} must be larger than N0 = {n0} (the OC window extends the measured past)",
                         remedy="pass settings as N0:N_OC with N_OC > N0, e.g. 50:100")
    if n0 < min_past:
        raise InputError(f"N0 = {n0} is too short: the predictors need at least {min_past} past samples",
                         remedy=f"use N0 >= {min_past}")
