"""One prediction run per predictor serves the settings and the horizon sweep of a predict stage
(``sweep.trajectory_runs``): the same numbers as computing each on its own, kept and resumed in the
work directory."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.models.prediction import sweep as sweep_mod
from cobot_analysis.models.prediction.sweep import horizon_sweep
from cobot_analysis.models.prediction.sweep import (SweepConfig, WorkDir, horizon_tables, run_sweep, setting_rows,
                                                    trajectories_from_table, trajectory_runs)
from tests.test_predict_cli import trajectories_table

END = (1.5 * np.cos(1.0), 1.5 * np.sin(1.0), 1.0 + np.pi / 2)  # where the first synthetic arc ends
HORIZONS = (5, 20, -1)


def _trajectories(n_traj=2):
    df = trajectories_table(n_traj=n_traj, n=40)
    df["x"] += np.random.default_rng(1).normal(0, 0.003, len(df))  # not a perfect arc: the solves do work
    return trajectories_from_table(df, SweepConfig(settings=((8, 20),)))


@pytest.mark.parametrize("predictors", [("oc", "cv", "ctrv"),
                                        pytest.param(("oc", "goal", "goal-inferred", "cv"), marks=pytest.mark.slow)])
def test_settings_are_unchanged_when_their_n0_is_run_over_the_whole_path(predictors):
    """Every predictor's prediction at a sample depends on the past only: extending the run of N0 = 8 to the
    whole path (for the horizon sweep) leaves the (8, 20) and (8, 12) rows identical (the goal-aware
    predictors: about 4 s, slow)."""
    traj = _trajectories(1)[0]
    config = SweepConfig(settings=((8, 20), (8, 12)), predictors=predictors, goal=END, candidates=(END[:2], (-3.0, -3.0)))
    alone = setting_rows(traj, config, trajectory_runs(traj, config))
    shared_runs = trajectory_runs(traj, config, 8)
    assert shared_runs[8, "oc"][0].shape[1] == len(traj.poses) - 8 + 1  # H = N - N0
    shared = setting_rows(traj, config, shared_runs)
    pd.testing.assert_frame_equal(shared[0], alone[0])
    pd.testing.assert_frame_equal(shared[1], alone[1])
    assert (shared[0]["n_failed"] == 0).all() and shared[0]["delta_xy"].notna().all()


def test_stage_horizon_sweep_equals_the_standalone_one_and_resumes(tmp_path, monkeypatch):
    """run_sweep(..., horizons=...) gives the horizon rows horizon_sweep computes on its own, keeps them in
    the work directory (a second run predicts nothing) and adds them to a sweep finished without them."""
    trajs = _trajectories()
    config = SweepConfig(settings=((8, 20),), predictors=("oc", "cv"))
    reference, _ = horizon_sweep(trajs, config, 8, HORIZONS, jobs=1)

    work = WorkDir(tmp_path / "w")
    plain, _, _ = run_sweep(trajs, config, work, jobs=1)  # settings only
    metrics, windows, resumed = run_sweep(trajs, config, work, jobs=1, horizons=(8, HORIZONS))
    assert resumed == 0  # the horizons were missing: both trajectories run again (once, for both)
    errors, inference = horizon_tables(trajs, config, work, (8, HORIZONS))
    pd.testing.assert_frame_equal(errors, reference)
    pd.testing.assert_frame_equal(metrics, plain)
    assert len(inference) == 0 and set(errors["horizon"]) == set(HORIZONS)

    calls = []
    monkeypatch.setattr(sweep_mod, "trajectory_runs", lambda *a: calls.append(a) or pytest.fail("recomputed"))
    again, _, resumed = run_sweep(trajs, config, work, jobs=1, horizons=(8, HORIZONS))
    assert resumed == len(trajs) and not calls
    pd.testing.assert_frame_equal(horizon_tables(trajs, config, work, (8, HORIZONS))[0], reference)
