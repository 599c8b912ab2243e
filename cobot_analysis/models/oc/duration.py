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

The published convention's rules (docs/methods.md sec. 11), on the explicit-Euler problem with a
fixed node step and a variable horizon of T intervals (``horizon_solver``):
- ``nelder_mead_duration`` (improved and table models): scipy Nelder-Mead (xatol 0.01, fatol 0.001)
  on f(T) = J*(T) / T, T cast to an integer, started at T_guess = int(2/3 * 100 d); f = 10 J / T
  when the solver stopped unconverged before 50 iterations, 1e4 after, 1e8 outside 0 < T < 200 d.
- ``last_node_duration`` (Mombaur form): T on the grid 250, 255, ..., 495; the first T is kept,
  then a T replaces it when |phi_r(X_T, U_{T-1})| (the running cost at the last node) is smaller
  and the solver needed fewer than 80 iterations.
Every T is solved from rest on the start pose (the authors' DDP started at rest), or, with
``warm=True``, from the solution at the nearest T already solved, its middle stretched in time
(``stretched``: the start turn and the final approach kept node for node).
"""

from __future__ import annotations

import math

import numpy as np

from cobot_analysis.models.oc.problem import OCPSolution, WalkerOCP

DURATION_METHODS = ("free", "search", "grid")
NODES_PER_METRE = 100  # the authors' T_guess = int(2/3 * 100 d) and bound 0 < T < 2 * 100 d (nodes, d in m)
HORIZON_GRID = tuple(range(250, 500, 5))  # the authors' Mombaur-form horizons (nodes of 0.01 s)


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


# ---- the published convention: integer horizons on the explicit-Euler problem ---------------------------
def capacity(T: int) -> int:
    """Intervals of the NLP that solves horizon ``T``: the smallest 16 * 1.5^k >= T (few shapes to
    compile, at most a third of the intervals frozen)."""
    n = 16
    while n < T:
        n = int(math.ceil(n * 1.5))
    return n


def _warp(k: np.ndarray, n: int, T: int) -> tuple[np.ndarray, np.ndarray]:
    """Node positions ``k`` of horizon ``T`` mapped onto horizon ``n``, and the time-scale ratio at
    each: the first and last B = min(n, T) // 4 nodes kept node for node (s = k, s = n - (T - k)),
    the middle mapped linearly, s = B + (k - B) (n - 2B) / (T - 2B)."""
    B = min(n, T) // 4
    r = (n - 2 * B) / (T - 2 * B)
    middle = (k > B) & (k < T - B)
    s = np.where(k <= B, k, np.where(k >= T - B, n - (T - k), B + (k - B) * r))
    return s, np.where(middle, r, 1.0)


def stretched(ocp: WalkerOCP, sol: OCPSolution, T: int) -> np.ndarray:
    """A guess of horizon ``T`` on ``ocp`` from a solution of another horizon n (``_warp``): the start
    turn and the final approach have their own time scale, independent of the horizon, so the first
    and last quarter are kept node for node and only the middle is resampled, its velocities scaled
    by n_middle / T_middle and its controls by the square; frozen nodes at rest on the last pose.
    (A uniform stretch of the whole path needed about 2.5 times the solver iterations, measured: those
    boundary layers come out too slow or too fast.)"""
    n = sol.U.shape[0]
    w = np.zeros(ocp.n_vars)
    k = np.arange(T + 1, dtype=float)
    s, r = _warp(k, n, T)
    X = np.column_stack([np.interp(s, np.arange(n + 1), sol.X[:, i]) for i in range(6)])
    X[:, 3:] *= r[:, None]
    w[ocp._xi[:T + 1, :6]] = X
    w[ocp._xi[T + 1:, :3]] = X[-1, :3]
    s, r = _warp(k[:-1] + 0.5, n, T)  # interval midpoints
    w[ocp._ui[:T]] = np.column_stack([np.interp(s, np.arange(n) + 0.5, sol.U[:, i]) for i in range(3)]) * r[:, None]**2
    return w


class HorizonSolver:
    """Solves the published problem for integer horizons T (intervals of ``dt``), each on the NLP of
    ``capacity(T)`` intervals, from rest, or (``warm``) from the nearest horizon already solved, or
    from ``seed`` (a solution of the same start and goal with other weights, in an IOC), stretched
    in time; keeps every solution (``solved``)."""

    def __init__(self, shape, start, goal, weights, dt: float, *, warm: bool = False, seed: OCPSolution | None = None,
                 fallback: bool = True):
        from dataclasses import replace

        self.shape, self.start, self.goal, self.w, self.dt, self.warm = shape, start, goal, weights, dt, warm
        self.seed = seed if seed is not None and seed.success else None
        self.fallback = fallback  # IPOPT when fatrop fails (see problem.WalkerOCP.solve)
        self._replace = replace
        self.solved: dict[int, OCPSolution] = {}

    def __call__(self, T: int) -> OCPSolution:
        from cobot_analysis.models.oc.problem import get_ocp

        if T not in self.solved:
            ocp = get_ocp(self._replace(self.shape, n_intervals=capacity(T)))
            guess = "rest"
            ok = {t: s for t, s in self.solved.items() if s.success} if self.warm else {}
            if self.seed is not None:
                ok.setdefault(-1, self.seed)  # a solution of other weights (IOC), stretched to T
            if ok:
                near = min(ok, key=lambda t: abs((ok[t].U.shape[0] if t < 0 else t) - T))
                guess = stretched(ocp, ok[near], T)
            self.solved[T] = ocp.solve(self.start, self.goal, self.w, self.dt, guess=guess, n_active=T, fallback=self.fallback)
        return self.solved[T]


def nelder_mead_duration(solve: HorizonSolver, start: int | None = None) -> OCPSolution:
    """The improved model's published duration rule (module docstring); returns the solution at
    the chosen T (check ``success``). ``start``: a check of a horizon chosen before (e.g. at other
    weights): kept when the rule's criterion f is no lower at start - 1 and start + 1 (one or two
    solves), else the search started there instead of at the authors' T_guess."""
    from scipy.optimize import minimize

    d = math.hypot(solve.goal[0] - solve.start[0], solve.goal[1] - solve.start[1])
    T_guess = int(d * NODES_PER_METRE * 2 / 3) if start is None else int(start)

    def f(z: np.ndarray) -> float:
        T = int(z[0])
        if not 0 < T < 2 * d * NODES_PER_METRE:
            return 1e8
        s = solve(T)
        if s.success:
            return s.cost / T
        return s.cost / T * 10 if 0 <= s.iterations < 50 else 1e4

    if start is not None and f(np.array([T_guess])) <= min(f(np.array([T_guess + k])) for k in (-1, 1)):
        return solve(T_guess)
    res = minimize(f, np.array([float(max(T_guess, 1))]), method="Nelder-Mead", options={"xatol": 0.01, "fatol": 0.001})
    return solve(max(int(res.x[0]), 1))


def last_node_cost(sol: OCPSolution, goal, weights, psi_eps: float) -> float:
    """|phi_r(X_T, U_{T-1})|: the Mombaur-form running cost at the last node with the last control
    (raw psi, fmod-pi heading error), the authors' selection criterion."""
    x, u, w = sol.X[-1], sol.U[-1], np.asarray(weights, float)
    dxg, dyg = goal[0] - x[0], goal[1] - x[1]
    r2 = dxg**2 + dyg**2
    psi = math.atan2(dyg, dxg) - x[2]
    e = math.fmod(goal[2], math.pi) - math.fmod(x[2], math.pi)
    e = e - 2 * math.pi if e > math.pi else (e + 2 * math.pi if e < -math.pi else e)
    return abs(w[0] + w[1] * u[0]**2 + w[2] * u[1]**2 + w[3] * u[2]**2 + w[4] * psi**2 * r2 / (r2 + psi_eps**2)
               + w[5] * r2 + w[6] * e**2)


def last_node_duration(solve: HorizonSolver, psi_eps: float, grid=HORIZON_GRID) -> OCPSolution:
    """The Mombaur form's published duration rule (module docstring)."""
    best, best_cost = None, -1.0
    for T in grid:
        s = solve(T)
        cost = last_node_cost(s, solve.goal, solve.w, psi_eps)
        if best_cost < 0 or (best_cost > cost and s.iterations < 80):
            best, best_cost = s, cost
    return best
