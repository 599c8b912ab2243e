"""The OC predictor's solves skip the solver's statistics (``WalkerOCP.solve(stats=False)``): the same
solution, and a failed fatrop solve is still flagged (fatrop is built with casadi's error_on_fail)."""

from __future__ import annotations

import numpy as np

from cobot_analysis.models.oc.problem import OCPShape, WalkerOCP, get_ocp
from cobot_analysis.models.presets import PRESETS, weights_vector
from cobot_analysis.models.prediction.predictor import OCPredictor

W = np.array([7.9, 4.0, 20.1, 1e-6, 0, 0, 0, 0, 0, 0, 0])  # a0..a3: a prediction window's weights
T = np.linspace(0.0, 0.49, 50)
MEASURED = np.c_[np.sin(T), 0.3 * T**2, np.full_like(T, 0.1)]  # a gentle curve, 50 nodes


def _window(ocp, **kw):
    return ocp.solve(MEASURED[0], (1e3, 1e3, 0.0), W, 0.49, start_velocity=(1.0, 0.0, 0.0), track=MEASURED,
                     guess="rest", **kw)


def test_without_stats_the_solution_is_the_same_and_iterations_are_not_counted():
    ocp = get_ocp(OCPShape(49))
    full, lean = _window(ocp), _window(ocp, stats=False)
    assert full.success and lean.success and lean.solver == "fatrop" == full.solver
    assert np.array_equal(full.primal, lean.primal) and full.cost == lean.cost
    assert full.iterations > 0 and lean.iterations == -1


def test_a_failed_fatrop_solve_without_stats_is_flagged_with_its_status():
    ocp = WalkerOCP(OCPShape(20, max_iter=2))  # a start-goal problem fatrop cannot solve in 2 iterations
    args = ((-3.0, -2.0, 0.0), (0.0, 0.0, np.pi / 2), weights_vector(PRESETS["walking-2021"]), 4.0)
    sol = ocp.solve(*args, fallback=False, stats=False)
    assert not sol.success and sol.solver == "fatrop"
    assert sol.iterations >= 2 and sol.status != "Solve_Succeeded"  # its stats were read
    # the fallback: IPOPT (not built with error_on_fail: its stats are always read) fails too, in its 4 iterations
    again = ocp.solve(*args, stats=False)
    assert again.solver == "ipopt" and not again.success and again.iterations == 4
    assert again.status == "Maximum_Iterations_Exceeded"
    # and fatrop's buffer still works after the failure it raised: an easy tracking window converges
    easy = ocp.solve(MEASURED[0], (1e3, 1e3, 0.0), W, 0.2, start_velocity=(1.0, 0.0, 0.0), track=MEASURED[:21],
                     guess="rest", fallback=False, stats=False)
    assert easy.success and easy.solver == "fatrop" and easy.iterations == -1


def test_predictions_equal_those_of_solves_with_stats(monkeypatch):
    """The predictor asks for no stats; forcing them gives bit-identical predictions."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.2, 121)
    poses = np.c_[t + 0.002 * rng.standard_normal(t.size), 0.2 * np.sin(2 * t), np.full_like(t, np.nan)]  # positions only
    lean = OCPredictor(20, 40, 0.01).predict_offline(poses)
    solve = WalkerOCP.solve
    monkeypatch.setattr(WalkerOCP, "solve", lambda self, *a, **kw: solve(self, *a, **{**kw, "stats": True}))
    full = OCPredictor(20, 40, 0.01).predict_offline(poses)
    assert np.isfinite(lean[..., :2]).all() and np.array_equal(lean, full)
