"""Second OC backend on crocoddyl (the DDP library of the published studies), to cross-check the
casadi solver. Optional extra: ``pip install cobot-analysis[crocoddyl]``; imported lazily.

The same discrete problem as ``ocp.py`` with a fixed duration T: N intervals, the dynamics of
``dynamics.step``, running cost dt L(x, u) and terminal cost L_f(x) (no tracking term). The model
is a Python ``ActionModelAbstract`` whose values and derivatives come from casadi functions of
the same expressions (so both backends solve exactly the same problem); crocoddyl's FDDP solver
uses the cost Hessian and first-order dynamics (Gauss-Newton on the dynamics).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from cobot_analysis.models.dynamics import N_CONTROL, N_STATE, step
from cobot_analysis.models.oc.problem import N_WEIGHTS


def available() -> bool:
    try:
        import crocoddyl  # noqa: F401
    except ImportError:
        return False
    return True


@lru_cache(maxsize=4)
def _functions(kind: str = "walker", psi_eps: float = 0.05):
    """casadi functions: running (x, u, w, goal, dt) -> values and derivatives; terminal likewise."""
    import casadi as ca

    x, u, w, g, dt = ca.SX.sym("x", N_STATE), ca.SX.sym("u", N_CONTROL), ca.SX.sym("w", N_WEIGHTS), ca.SX.sym("g", 3), ca.SX.sym("dt")
    dxg, dyg = g[0] - x[0], g[1] - x[1]
    r2 = dxg**2 + dyg**2
    psi = ca.atan2(-ca.sin(x[2]) * dxg + ca.cos(x[2]) * dyg, ca.cos(x[2]) * dxg + ca.sin(x[2]) * dyg)
    dth = g[2] - x[2]
    L = dt * (w[0] + w[1] * u[0]**2 + w[2] * u[1]**2 + w[3] * u[2]**2 + w[4] * psi**2 * r2 / (r2 + psi_eps**2)
              + w[5] * r2 + w[6] * dth**2)
    F = step(x, u, dt, kind)
    Lf = w[7] * r2 + w[8] * dth**2 + w[9] * (x[3]**2 + x[4]**2) + w[10] * x[5]**2
    z = ca.vertcat(x, u)
    Hz = ca.hessian(L, z)[0]
    running = ca.Function("running", [x, u, w, g, dt], [F, ca.jacobian(F, x), ca.jacobian(F, u), L, ca.gradient(L, x),
                                                         ca.gradient(L, u), Hz[:N_STATE, :N_STATE], Hz[N_STATE:, N_STATE:],
                                                         Hz[:N_STATE, N_STATE:]])
    terminal = ca.Function("terminal", [x, w, g], [Lf, ca.gradient(Lf, x), ca.hessian(Lf, x)[0]])
    return running, terminal


def _action_class():
    import crocoddyl

    class WalkerAction(crocoddyl.ActionModelAbstract):
        """One node of the walker OC problem (running if ``dt`` is given, else terminal)."""

        def __init__(self, weights, goal, dt=None, kind="walker"):
            crocoddyl.ActionModelAbstract.__init__(self, crocoddyl.StateVector(N_STATE), N_CONTROL, 1)
            self.w, self.g, self.dt = np.asarray(weights, float), np.asarray(goal, float), dt
            self.running, self.terminal = _functions(kind)

        def calc(self, data, x, u=None):
            if self.dt is None or u is None:
                data.cost = float(self.terminal(x, self.w, self.g)[0])
                data.xnext[:] = x
            else:
                out = self.running(x, u, self.w, self.g, self.dt)
                data.xnext[:] = np.asarray(out[0]).ravel()
                data.cost = float(out[3])

        def calcDiff(self, data, x, u=None):
            if self.dt is None or u is None:
                _, lx, lxx = self.terminal(x, self.w, self.g)
                data.Lx[:] = np.asarray(lx).ravel()
                data.Lxx[:, :] = np.asarray(lxx)
                return
            out = self.running(x, u, self.w, self.g, self.dt)
            data.Fx[:, :] = np.asarray(out[1])
            data.Fu[:, :] = np.asarray(out[2])
            data.Lx[:] = np.asarray(out[4]).ravel()
            data.Lu[:] = np.asarray(out[5]).ravel()
            data.Lxx[:, :] = np.asarray(out[6])
            data.Luu[:, :] = np.asarray(out[7])
            data.Lxu[:, :] = np.asarray(out[8])

    return WalkerAction


def solve(start, goal, weights, T: float, *, n_intervals: int = 100, kind: str = "walker", max_iter: int = 1000,
          tol: float = 1e-10, init=None):
    """Solve the fixed-T problem with crocoddyl FDDP: ``(X (N+1, 6), U (N, 3), cost, converged, iterations)``.

    ``init``: optional ``(X, U)`` initial guess; default: at rest on the start pose, zero controls.
    """
    import crocoddyl

    Action = _action_class()
    dt = T / n_intervals
    running = [Action(weights, goal, dt, kind) for _ in range(n_intervals)]
    terminal = Action(weights, goal, None, kind)
    x0 = np.r_[np.asarray(start, float)[:3], np.zeros(3)]
    problem = crocoddyl.ShootingProblem(x0, running, terminal)
    solver = crocoddyl.SolverFDDP(problem)
    solver.th_stop = tol
    if init is None:
        xs = [x0.copy() for _ in range(n_intervals + 1)]
        us = [np.zeros(N_CONTROL) for _ in range(n_intervals)]
    else:
        xs, us = [np.asarray(v, float) for v in init[0]], [np.asarray(v, float) for v in init[1]]
    converged = solver.solve(xs, us, max_iter, False)
    return np.array(solver.xs), np.array(solver.us), float(solver.cost), bool(converged), int(solver.iter)
