"""The optimal-control problem of the walking-path models (docs/methods.md sec. 5.3-5.6): the
parametric NLP (``problem``), the duration rules (``duration``), the coupled two-walker problem
(``coupled``) and the crocoddyl cross-check backend (``crocoddyl_backend``).

``solve_model`` solves one start/goal with a model's duration rule under a convention
(``cobot_analysis.conventions``); ``resample`` puts a solution on N samples equally spaced in time
(continuous convention), ``node_arrays`` gives it at its nodes (published convention).
"""

from __future__ import annotations

import numpy as np

OC_MODELS = ("unicycle", "mombaur", "improved", "table")

def solve_model(model: str, start, goal, weights, *, convention="continuous", n_intervals: int = 100,
                duration: str | None = None, v_nominal: float = 1.0, solver: str = "fatrop", guess="rest", T=None,
                max_iter: int = 500, warm: bool = False, seed=None, horizon: int | None = None, fallback: bool = True,
                start_horizon: int | None = None):
    """Solve the OC model for one start/goal under a convention (``conventions.get``); returns an
    ``problem.OCPSolution`` (check ``success``).

    ``weights``: the 11-vector (a0..a6, b0..b3). Continuous convention: the goal pose at rest is a
    terminal constraint (``OCRule.goal``; b0..b3 unused), ``n_intervals`` intervals,
    ``duration`` (default the convention's rule: free within ``rule.T_bounds`` x T0, grid for the Mombaur form, or "search" /
    "fixed" at ``T``), ``guess``: "rest", "line", a previous primal vector (warm start) or a sequence of
    those (the best converged solution is kept). Published convention: the authors' node step and
    duration rule (``duration.nelder_mead_duration`` / ``last_node_duration``), every horizon from
    rest unless ``warm`` (then from the nearest horizon solved) or ``seed`` (a solution of other
    weights, see ``duration.HorizonSolver``); ``horizon``: solve that number of steps only, instead of
    the duration rule (the IOC holds the rule's horizon between evaluations); ``start_horizon``: a check
    that a horizon chosen before is still the rule's (``duration.nelder_mead_duration``'s ``start``: kept
    when the rule's criterion is no lower one node either side, else the search from there), ``seed``
    taken as its solution there when it has that horizon;
    ``fallback``: IPOPT when fatrop fails. The solution has one node per step.
    """
    from cobot_analysis import conventions
    from cobot_analysis.models.oc.duration import grid_duration, initial_duration, search_duration
    from cobot_analysis.models.oc.problem import OCPShape, get_ocp

    if model not in OC_MODELS:
        raise ValueError(f"{model!r} is not an OC model ({', '.join(OC_MODELS)})")
    conv = conventions.get(convention)
    rule = conv.oc_rule(model)
    dyn = "unicycle" if model == "unicycle" else "walker"
    if rule.scheme == "euler":
        return _solve_published(rule, dyn, start, goal, weights, solver=solver, max_iter=max_iter, warm=warm, seed=seed,
                                horizon=horizon, fallback=fallback, start_horizon=start_horizon)
    duration = duration or rule.duration
    T0 = initial_duration(start, goal, v_nominal) if T is None else T
    guesses = [guess] if isinstance(guess, str | np.ndarray) else list(guess)
    best = None
    for g in guesses:
        if duration == "free":
            sol = get_ocp(OCPShape(n_intervals, dyn, free_time=True, solver=solver, max_iter=max_iter, goal=rule.goal)).solve(
                start, goal, weights, T0, guess=g, T_bounds=rule.T_bounds)
        else:
            ocp = get_ocp(OCPShape(n_intervals, dyn, free_time=False, solver=solver, max_iter=max_iter, goal=rule.goal))
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


def _solve_published(rule, dyn: str, start, goal, weights, *, solver: str, max_iter: int, warm: bool, seed=None,
                     horizon: int | None = None, fallback: bool = True, start_horizon: int | None = None):
    """The published convention: the start moved to the origin at rest, the goal with it, the
    authors' duration rule on the explicit-Euler problem; the solution moved back."""
    from dataclasses import replace

    from cobot_analysis.models.oc.duration import HorizonSolver, last_node_duration, nelder_mead_duration
    from cobot_analysis.models.oc.problem import OCPShape

    x0, y0 = float(start[0]), float(start[1])
    shape = OCPShape(16, dyn, scheme="euler", psi=rule.psi, heading=rule.heading, psi_eps=rule.psi_eps,
                     terminal_running=rule.duration == "last-node", solver=solver, max_iter=max_iter)
    if seed is not None:  # in the origin frame
        X = seed.X.copy()
        X[:, :2] -= X[0, :2]
        seed = replace(seed, X=X)
    solve = HorizonSolver(shape, (0.0, 0.0, float(start[2])), (goal[0] - x0, goal[1] - y0, goal[2]),
                          np.asarray(weights, float), rule.dt, warm=warm, seed=seed, fallback=fallback)
    if horizon is not None:
        sol = solve(int(horizon))
    elif rule.duration == "nelder-mead":
        if start_horizon is not None and solve.seed is not None and solve.seed.U.shape[0] == start_horizon:
            solve.solved[int(start_horizon)] = solve.seed  # a solution at these weights and that horizon
        sol = nelder_mead_duration(solve, start=start_horizon)
    else:
        sol = last_node_duration(solve, rule.psi_eps)
    X = sol.X.copy()
    X[:, 0] += x0
    X[:, 1] += y0
    return replace(sol, X=X)


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


def node_arrays(sol, kind: str = "walker") -> dict[str, np.ndarray]:
    """The solution at its nodes (published convention: the path is the node sequence), with the
    columns of ``resample``; controls zero-order hold, the last one repeated."""
    from cobot_analysis.models.dynamics import world_velocity

    X, U = sol.X, sol.U
    out = {"time": sol.t, "x": X[:, 0], "y": X[:, 1], "theta": X[:, 2], "v_forw": X[:, 3],
           "v_orth": X[:, 4] if kind != "unicycle" else np.zeros(len(X)), "omega": X[:, 5]}
    out["vx"], out["vy"] = world_velocity(out["theta"], out["v_forw"], out["v_orth"], kind)
    Uh = np.vstack([U, U[-1:]])
    for i, name in enumerate(("u1", "u2", "u3")):
        out[name] = Uh[:, i]
    return out
