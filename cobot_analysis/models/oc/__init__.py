"""The optimal-control problem of the walking-path models (docs/methods.md sec. 5.3-5.6): the
parametric NLP (``problem``), the duration rules (``duration``), the coupled two-walker problem
(``coupled``) and the crocoddyl cross-check backend (``crocoddyl_backend``).

``solve_model`` solves one start/goal with a model's duration rule; ``resample`` puts a solution on
N samples equally spaced in time.
"""

from __future__ import annotations

import numpy as np

OC_MODELS = ("unicycle", "mombaur", "improved", "table")

#: duration method of each OC model when none is given (see duration.py).
DEFAULT_DURATION = {"unicycle": "free", "mombaur": "grid", "improved": "free", "table": "free"}


def solve_model(model: str, start, goal, weights, *, n_intervals: int = 100, duration: str | None = None,
                v_nominal: float = 1.0, solver: str = "fatrop", guess="rest", T=None, max_iter: int = 500):
    """Solve the OC model for one start/goal; returns an ``ocp.OCPSolution`` (check ``success``).

    ``weights``: the 11-vector (a0..a6, b0..b3); ``guess``: "rest", "line", a previous primal vector
    (warm start) or a sequence of those (the best converged solution is kept).
    """
    from cobot_analysis.models.oc.duration import grid_duration, initial_duration, search_duration
    from cobot_analysis.models.oc.problem import OCPShape, get_ocp

    if model not in OC_MODELS:
        raise ValueError(f"{model!r} is not an OC model ({', '.join(OC_MODELS)})")
    dyn = "unicycle" if model == "unicycle" else "walker"
    duration = duration or DEFAULT_DURATION[model]
    T0 = initial_duration(start, goal, v_nominal) if T is None else T
    guesses = [guess] if isinstance(guess, str | np.ndarray) else list(guess)
    best = None
    for g in guesses:
        if duration == "free":
            sol = get_ocp(OCPShape(n_intervals, dyn, free_time=True, solver=solver, max_iter=max_iter)).solve(start, goal, weights, T0, guess=g)
        else:
            ocp = get_ocp(OCPShape(n_intervals, dyn, free_time=False, solver=solver, max_iter=max_iter))
            if duration == "search":
                sol = search_duration(ocp, start, goal, weights, T0, guess=g)
            elif duration == "grid":
                sol = grid_duration(ocp, start, goal, weights, T0, guess=g)
            elif duration == "fixed":
                sol = ocp.solve(start, goal, weights, T0, guess=g)
            else:
                raise ValueError(f"unknown duration method {duration!r}")
        if best is None or (sol.success and (not best.success or sol.cost < best.cost)):
            best = sol
    return best


def resample(sol, n_samples: int = 500, kind: str = "walker") -> dict[str, np.ndarray]:
    """Resample an OC solution to ``n_samples`` equally spaced in time (cubic Hermite on x, y, theta)."""
    from scipy.interpolate import CubicHermiteSpline

    from cobot_analysis.models.dynamics import world_velocity

    X, U = sol.X, sol.U
    t = sol.t
    tt = np.linspace(0.0, sol.T, n_samples)
    vx, vy = world_velocity(X[:, 2], X[:, 3], X[:, 4], kind)
    out = {"time": tt,
           "x": CubicHermiteSpline(t, X[:, 0], vx)(tt),
           "y": CubicHermiteSpline(t, X[:, 1], vy)(tt),
           "theta": CubicHermiteSpline(t, X[:, 2], X[:, 5])(tt)}
    for i, name in enumerate(("v_forw", "v_orth", "omega")):
        out[name] = np.interp(tt, t, X[:, 3 + i])
    if kind == "unicycle":
        out["v_orth"] = np.zeros(n_samples)
    out["vx"], out["vy"] = world_velocity(out["theta"], out["v_forw"], out["v_orth"], kind)
    idx = np.minimum(np.searchsorted(t, tt, side="right") - 1, U.shape[0] - 1)  # zero-order hold
    for i, name in enumerate(("u1", "u2", "u3")):
        out[name] = U[idx, i]
    return out
