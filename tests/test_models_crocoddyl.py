"""Cross-check of the casadi OC solver against the crocoddyl backend (optional extra)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cobot_analysis.models.oc import crocoddyl_backend, solve_model
from cobot_analysis.models.oc.problem import OCPShape, get_ocp
from cobot_analysis.models.presets import PRESETS, weights_vector

pytestmark = pytest.mark.skipif(not crocoddyl_backend.available(),
                                reason="crocoddyl not installed (optional extra: pip install cobot-analysis[crocoddyl])")
GOAL = (0.0, 0.0, math.pi / 2)
W = weights_vector(PRESETS["walking-2021"])
N = 50


@pytest.mark.parametrize("start", [(-1.5, -3.4, 0.0), (-4.0, -3.4, math.pi / 2)])
def test_casadi_and_crocoddyl_reach_the_same_optimum(start):
    """Same discrete problem (fixed T at the casadi free-time optimum), both from rest on the start pose."""
    T = solve_model("improved", start, GOAL, W, n_intervals=N).check().T
    ours = get_ocp(OCPShape(N)).solve(start, GOAL, W, T, guess="rest").check()
    X, U, cost, converged, _ = crocoddyl_backend.solve(start, GOAL, W, T, n_intervals=N)
    assert converged
    assert cost == pytest.approx(ours.cost, rel=1e-6)
    assert np.hypot(X[:, 0] - ours.X[:, 0], X[:, 1] - ours.X[:, 1]).max() < 1e-3  # m


def test_from_rest_the_backends_may_stop_at_two_nearby_local_minima_and_each_confirms_the_other():
    """Start 4 m behind the goal, facing away: from rest fatrop (and IPOPT) stop at J = 39.5504, crocoddyl's
    DDP at 39.5493, paths about 1 mm apart; started at the other's solution, each stays there: both are
    local minima of the same discrete problem, not a disagreement of the backends."""
    start = (-4.0, 0.6, math.pi)
    T = solve_model("improved", start, GOAL, W, n_intervals=N).check().T
    ocp = get_ocp(OCPShape(N))
    ours = ocp.solve(start, GOAL, W, T, guess="rest").check()
    X, U, cost, converged, _ = crocoddyl_backend.solve(start, GOAL, W, T, n_intervals=N)
    assert converged and abs(cost - ours.cost) < 1e-4 * ours.cost
    guess = np.zeros(ocp.n_vars)
    guess[ocp._xi], guess[ocp._ui] = X, U
    again = ocp.solve(start, GOAL, W, T, guess=guess).check()  # ours from crocoddyl's minimum stays there
    assert again.cost == pytest.approx(cost, rel=1e-7) and np.abs(again.X - X).max() < 1e-3
    Xc, _, cost_c, _, _ = crocoddyl_backend.solve(start, GOAL, W, T, n_intervals=N, init=(ours.X, ours.U))
    assert cost_c == pytest.approx(ours.cost, rel=1e-7) and np.abs(Xc - ours.X).max() < 1e-3


def test_both_backends_agree_from_the_same_guess_where_the_problem_has_two_local_minima():
    """Start facing away from the goal: the 'rest' guess leads the two backends to different local
    minima; from the same (casadi free-time) solution both stay at the lower one."""
    start = (-0.6, -1.5, -math.pi / 2)
    free = solve_model("improved", start, GOAL, W, n_intervals=N).check()
    ours = get_ocp(OCPShape(N)).solve(start, GOAL, W, free.T, guess=free.primal[np.arange(len(free.primal)) % 10 != 6]).check()
    X, U, cost, converged, _ = crocoddyl_backend.solve(start, GOAL, W, free.T, n_intervals=N, init=(ours.X, ours.U))
    assert converged and cost == pytest.approx(ours.cost, rel=1e-6)
    assert np.hypot(X[:, 0] - ours.X[:, 0], X[:, 1] - ours.X[:, 1]).max() < 1e-3
