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


@pytest.mark.parametrize("start", [(-1.5, -3.4, 0.0), (-4.0, 0.6, math.pi), (-4.0, -3.4, math.pi / 2)])
def test_casadi_and_crocoddyl_reach_the_same_optimum(start):
    """Same discrete problem (fixed T at the casadi free-time optimum), both from rest on the start pose."""
    T = solve_model("improved", start, GOAL, W, n_intervals=N).check().T
    ours = get_ocp(OCPShape(N)).solve(start, GOAL, W, T, guess="rest").check()
    X, U, cost, converged, _ = crocoddyl_backend.solve(start, GOAL, W, T, n_intervals=N)
    assert converged
    assert cost == pytest.approx(ours.cost, rel=1e-6)
    assert np.hypot(X[:, 0] - ours.X[:, 0], X[:, 1] - ours.X[:, 1]).max() < 1e-3  # m


def test_both_backends_agree_from_the_same_guess_where_the_problem_has_two_local_minima():
    """Start facing away from the goal: the 'rest' guess leads the two backends to different local
    minima; from the same (casadi free-time) solution both stay at the lower one."""
    start = (-0.6, -1.5, -math.pi / 2)
    free = solve_model("improved", start, GOAL, W, n_intervals=N).check()
    ours = get_ocp(OCPShape(N)).solve(start, GOAL, W, free.T, guess=free.primal[np.arange(len(free.primal)) % 10 != 6]).check()
    X, U, cost, converged, _ = crocoddyl_backend.solve(start, GOAL, W, free.T, n_intervals=N, init=(ours.X, ours.U))
    assert converged and cost == pytest.approx(ours.cost, rel=1e-6)
    assert np.hypot(X[:, 0] - ours.X[:, 0], X[:, 1] - ours.X[:, 1]).max() < 1e-3
