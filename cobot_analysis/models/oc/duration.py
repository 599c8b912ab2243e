"""Duration T of the walking OC problems (docs/methods.md 5.4 and 5.5).

- ``initial_duration``: T0 = d / v_nominal + t_rest (d = start-goal distance). The optimal T of
  the improved model came out at 0.56-0.77 x (d / 1 m/s + 1 s) in the reference runs, so the
  search interval [0.4, 2.0] x T0 brackets it from 0.6 m to 5.5 m.
- ``search_duration``: 1-D bounded derivative-free search (Brent, scipy ``minimize_scalar``
  'bounded') of T -> J*(T), each inner solve warm-started from the solution at the nearest T
  already solved (cold inner solves fell into worse local minima in the reference runs).
- ``grid_duration``: the Mombaur model's procedure: solve for T = T0, T0 (1 + step), ... upward and
  keep the minimum-cost T (fidelity to the original; slower). It is the default of the Mombaur
  model, whose running position/heading terms make a free T collapse towards 0 (the original had
  terminal constraints, which the unconstrained adaptation replaces by the grid's lower end T0).
- ``free``: T as a decision variable of the NLP (``OCPShape(free_time=True)``): the same optimum
  as the search, in one solve.
"""

from __future__ import annotations

import math

import numpy as np

from cobot_analysis.models.oc.problem import OCPSolution, WalkerOCP

DURATION_METHODS = ("free", "search", "grid")


def initial_duration(start, goal, v_nominal: float = 1.0, t_rest: float = 1.0) -> float:
    """``T0 = d / v_nominal + t_rest`` with d the start-goal distance (m, m/s, s)."""
    return math.hypot(goal[0] - start[0], goal[1] - start[1]) / v_nominal + t_rest


def _nearest(solved: dict[float, OCPSolution], T: float):
    if not solved:
        return "rest"
    best = min(solved, key=lambda t: abs(t - T))
    return solved[best].primal


def search_duration(ocp: WalkerOCP, start, goal, weights, T0: float, *, bounds=(0.4, 2.0), xatol: float = 1e-3,
                    guess="rest", **kw) -> OCPSolution:
    """Brent's bounded search of T in ``bounds`` x T0 minimising the optimal cost (fixed-T NLP)."""
    from scipy.optimize import minimize_scalar

    solved: dict[float, OCPSolution] = {}
    first = ocp.solve(start, goal, weights, T0, guess=guess, **kw)
    solved[T0] = first

    def cost(T: float) -> float:
        if T not in solved:
            solved[T] = ocp.solve(start, goal, weights, T, guess=_nearest(solved, T), **kw)
        s = solved[T]
        return s.cost if s.success else np.inf

    minimize_scalar(cost, bounds=(bounds[0] * T0, bounds[1] * T0), method="bounded",
                    options={"xatol": xatol * T0})
    ok = {T: s for T, s in solved.items() if s.success}
    if not ok:
        return first
    return ok[min(ok, key=lambda T: ok[T].cost)]


def grid_duration(ocp: WalkerOCP, start, goal, weights, T0: float, *, step: float = 0.05, n: int = 21,
                  first: float = 1.0, guess="rest", **kw) -> OCPSolution:
    """Mombaur's grid: T = T0 (first + step i), i < n (from T0 upward), keep the minimum-cost converged solve.

    Each solve is warm-started from the previous T's solution.
    """
    best, prev = None, guess
    for i in range(n):
        s = ocp.solve(start, goal, weights, T0 * (first + step * i), guess=prev, **kw)
        if s.success:
            prev = s.primal
            if best is None or s.cost < best.cost:
                best = s
    return best if best is not None else s
