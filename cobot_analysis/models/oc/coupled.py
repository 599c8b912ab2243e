"""Coupled OC model of two carriers (docs/methods.md 5.6), solved like the single walker (``ocp.py``).

Two holonomic walkers (12 states, 6 controls), both starting at rest, with

  phi_r = a0 + a1 u11^2 + a2 u12^2 + a3 u13^2 + a4 u21^2 + a5 u22^2 + a6 u23^2
        + a7 psi1^2 + a8 psi2^2 + a9 chi + a10 (xi1 + xi2)
  phi_t = b0 (|p1 - p1f|^2 + |p2 - p2f|^2) + b1 ((th1f - th1)^2 + (th2f - th2)^2)
        + b2 (|v1|^2 + |v2|^2) + b3 (omega1^2 + omega2^2)

  chi  = 0 if 1.6 < d < 2.1 else exp(min(|d - 2.1|, |d - 1.6|)) - 1   (d = distance between carriers)
  xi_i = 0 if g_i < pi/3 else exp(g_i - pi/3) - 1,  g_i = |bearing of the other carrier seen from i|

psi_i is regularised at the goal as in ``ocp.py``. chi and xi have kinks (at the band edges, and
where the facing angle g_i crosses pi/3); an optimum that sits on a kink (carriers held exactly at
1.6 or 2.1 m) stops interior-point solvers from converging (measured: fatrop and IPOPT hit their
iteration limits on 2 of the first 6 published scenario-3 means). They are therefore written
exactly, without kinks, with three slack controls per interval (s, t1, t2 >= 0):

  chi = exp(s) - 1,  s >= d - 2.1,  s >= 1.6 - d
  xi_i = exp(t_i) - 1,  t_i >= beta_i - pi/3,  t_i >= -beta_i - pi/3   (beta_i: signed bearing, g_i = |beta_i|)

exp(.) - 1 increases, so at the optimum s = max(0, d - 2.1, 1.6 - d) and t_i = max(0, g_i - pi/3):
the published chi and xi (when a9, a10 > 0). T is a decision variable (free duration), bounded to
[0.4, 2.5] x T0. With ``OCPShape.goal == "constraint"`` (the continuous convention) both carriers
end on their goal poses at rest (12 terminal equalities) and phi_t, zero there, is left out. For return paths the roles of the subjects are swapped by the caller (Subject 2
is carrier 1).
"""

from __future__ import annotations

import math
import threading
from functools import lru_cache

import numpy as np

from cobot_analysis.models.dynamics import N_CONTROL, N_STATE, step
from cobot_analysis.models.oc.problem import OCPShape, OCPSolution, WalkerOCP

N_COUPLED_WEIGHTS = 15  # a0..a10, b0..b3 (presets.COUPLED_WEIGHTS)
BAND = (1.6, 2.1)  # m, comfortable distance between the carriers
FACING = math.pi / 3


class CoupledOCP(WalkerOCP):
    """Parametric NLP of the two-carrier problem (free duration); ``X`` has 12 columns
    (carrier 1 then carrier 2), ``U`` 6 (the slacks of chi and xi are kept out of the solution)."""

    N_SLACK = 3  # s (chi), t1, t2 (xi)
    N_PATH = 6  # inequalities per interval, each written as expression >= 0

    def __init__(self, shape: OCPShape = OCPShape(free_time=True)):
        import casadi as ca

        self.shape = shape
        N = shape.n_intervals
        ns, nc = 2 * N_STATE, 2 * N_CONTROL
        nx, nu = ns + 1, nc + self.N_SLACK  # + log T; + slacks
        self.nx, self.nu, self.N = nx, nu, N
        X0, goal, Tp, W = ca.SX.sym("X0", ns), ca.SX.sym("goal", 6), ca.SX.sym("T"), ca.SX.sym("W", N_COUPLED_WEIGHTS)
        p = ca.vertcat(X0, goal, Tp, W)
        self.n_params = p.shape[0]
        self._T_index = ns + 6

        xs, us, gl, ws = ca.SX.sym("x", ns), ca.SX.sym("u", nu), ca.SX.sym("g", 6), ca.SX.sym("w", N_COUPLED_WEIGHTS)
        eps2 = shape.psi_eps**2

        def bearing(xi, tx, ty):
            dx, dy = tx - xi[0], ty - xi[1]
            return ca.atan2(-ca.sin(xi[2]) * dx + ca.cos(xi[2]) * dy, ca.cos(xi[2]) * dx + ca.sin(xi[2]) * dy), dx**2 + dy**2

        x1, x2 = xs[:N_STATE], xs[N_STATE:]
        s, t1, t2 = us[nc], us[nc + 1], us[nc + 2]
        psi1, r1 = bearing(x1, gl[0], gl[1])
        psi2, r2 = bearing(x2, gl[3], gl[4])
        d = ca.sqrt((x1[0] - x2[0])**2 + (x1[1] - x2[1])**2 + 1e-12)
        beta1, beta2 = bearing(x1, x2[0], x2[1])[0], bearing(x2, x1[0], x1[1])[0]
        running = (ws[0] + ws[1] * us[0]**2 + ws[2] * us[1]**2 + ws[3] * us[2]**2 + ws[4] * us[3]**2 + ws[5] * us[4]**2
                   + ws[6] * us[5]**2 + ws[7] * psi1**2 * r1 / (r1 + eps2) + ws[8] * psi2**2 * r2 / (r2 + eps2)
                   + ws[9] * (ca.exp(s) - 1) + ws[10] * (ca.exp(t1) - 1 + ca.exp(t2) - 1))
        path = ca.vertcat(s - (d - BAND[1]), s - (BAND[0] - d), t1 - (beta1 - FACING), t1 - (-beta1 - FACING),
                          t2 - (beta2 - FACING), t2 - (-beta2 - FACING))
        terminal = (ws[11] * (r1 + r2) + ws[12] * ((gl[2] - x1[2])**2 + (gl[5] - x2[2])**2)
                    + ws[13] * (x1[3]**2 + x1[4]**2 + x2[3]**2 + x2[4]**2) + ws[14] * (x1[5]**2 + x2[5]**2))
        L = ca.Function("L", [xs, us, ws, gl], [running])
        G = ca.Function("G", [xs, us], [path])
        Lf = ca.Function("Lf", [xs, ws, gl], [terminal])
        dts = ca.SX.sym("dt")
        F = ca.Function("F", [xs, us, dts], [ca.vertcat(step(x1, us[:N_CONTROL], dts), step(x2, us[N_CONTROL:nc], dts))])

        Xk = [ca.SX.sym(f"x{k}", nx) for k in range(N + 1)]
        Uk = [ca.SX.sym(f"u{k}", nu) for k in range(N)]
        J = 0
        g, equality = [Xk[0][:ns] - X0], [True] * ns
        for k in range(N):
            dt = ca.exp(Xk[k][ns]) / N
            J += dt * L(Xk[k][:ns], Uk[k], W, goal)
            g += [Xk[k + 1] - ca.vertcat(F(Xk[k][:ns], Uk[k], dt), Xk[k][ns]), G(Xk[k][:ns], Uk[k])]
            equality += [True] * nx + [False] * self.N_PATH
        if shape.goal == "constraint":  # both carriers end on their goal poses at rest; the b terms are 0 there
            zero = ca.SX.zeros(3)
            g.append(Xk[N][:ns] - ca.vertcat(goal[:3], zero, goal[3:], zero))
            equality += [True] * ns
        else:
            J += Lf(Xk[N][:ns], W, goal)
        w = ca.vertcat(*[v for k in range(N) for v in (Xk[k], Uk[k])], Xk[N])
        g = ca.vertcat(*g)
        self._nlp = {"x": w, "p": p, "f": J, "g": g}
        self.n_vars, self.n_cons = w.shape[0], g.shape[0]
        self._equality = equality
        self._ubg = np.where(equality, 0.0, np.inf)
        stride = nx + nu
        self._xi = np.array([[k * stride + i for i in range(nx)] for k in range(N + 1)])
        self._ui = np.array([[k * stride + nx + i for i in range(nc)] for k in range(N)])
        self._si = np.array([[k * stride + nx + nc + i for i in range(self.N_SLACK)] for k in range(N)])
        self._solvers = {}
        self._lock = threading.Lock()
        self._solver(shape.solver)

    def _solver(self, name: str):
        """As ``WalkerOCP._solver``, with the path inequalities declared to fatrop."""
        import casadi as ca

        if name == "fatrop" and name not in self._solvers:
            opts = {"structure_detection": "auto", "expand": True, "equality": self._equality,
                    "print_time": False, "show_eval_warnings": False,
                    "fatrop": {"print_level": 0, "tol": self.shape.tol, "max_iter": self.shape.max_iter}}
            self._solvers[name] = ca.nlpsol(f"coupled_{name}", name, self._nlp, opts)
        return super()._solver(name)

    def _run(self, w0, p, lbx, ubx, fallback: bool, n_active: int | None = None) -> OCPSolution:
        """The primary solver, then IPOPT if it failed; path inequalities 0 <= g (dynamics g = 0)."""
        names = [self.shape.solver] + (["ipopt"] if fallback and self.shape.solver != "ipopt" else [])
        sol = None
        for name in names:
            with self._lock:
                solver = self._solver(name)
                res = solver(x0=w0, p=p, lbg=0.0, ubg=self._ubg, lbx=lbx, ubx=ubx)
                st = solver.stats()
            sol = self._unpack(np.asarray(res["x"]).ravel(), float(res["f"]), p, name, st, self.N)
            if sol.success:
                break
        return sol

    def solve(self, start, goal, weights, T, *, guess="rest", fallback: bool = True,
              T_bounds: tuple[float, float] = (0.4, 2.5)) -> OCPSolution:
        """``start``, ``goal``: the two carriers' poses, shape (2, 3); ``weights``: the 15-vector."""
        start, goal = np.asarray(start, float).reshape(2, 3), np.asarray(goal, float).reshape(2, 3)
        X0 = np.r_[start[0], np.zeros(3), start[1], np.zeros(3)]
        p = np.r_[X0, goal.ravel(), float(T), np.asarray(weights, float)]
        if isinstance(guess, str):
            w0 = np.zeros(self.n_vars)
            for k in range(self.N + 1):
                a = k / self.N if guess == "line" else 0.0
                s = (1 - a) * start + a * goal
                w0[self._xi[k, :-1]] = np.r_[s[0], np.zeros(3), s[1], np.zeros(3)]
            w0[self._si] = 0.1  # slacks: strictly inside their bounds
        else:
            w0 = np.asarray(guess, float).copy()
        lbx, ubx = np.full(self.n_vars, -np.inf), np.full(self.n_vars, np.inf)
        lbx[self._si] = 0.0
        lbx[self._xi[:, -1]] = math.log(T_bounds[0] * T)
        ubx[self._xi[:, -1]] = math.log(T_bounds[1] * T)
        w0[self._xi[:, -1]] = np.clip(w0[self._xi[:, -1]] if not isinstance(guess, str) else math.log(T),
                                      lbx[self._xi[0, -1]], ubx[self._xi[0, -1]])
        return self._run(w0, p, lbx, ubx, fallback)


@lru_cache(maxsize=4)
def get_coupled_ocp(shape: OCPShape = OCPShape(free_time=True)) -> CoupledOCP:
    return CoupledOCP(shape)


def initial_pair_duration(start, goal, v_nominal: float = 1.0) -> float:
    """T0 = (longest start-goal distance of the two carriers) / v_nominal + 1 s."""
    start, goal = np.asarray(start, float).reshape(2, 3), np.asarray(goal, float).reshape(2, 3)
    return max(math.hypot(*(goal[i, :2] - start[i, :2])) for i in range(2)) / v_nominal + 1.0


def solve_pair(start, goal, weights, *, n_intervals: int = 100, v_nominal: float = 1.0, guess=("rest", "line"),
               solver: str = "auto", max_iter: int = 500) -> OCPSolution:
    """Best converged solution over the initial guesses; T bounded to [0.4, 2.5] x T0 (``initial_pair_duration``);
    the goal rule of the continuous convention (``OCRule.goal``: both carriers end on their goal at rest).

    ``solver="auto"``: IPOPT from the cold guesses ('rest', 'line'), fatrop (IPOPT as fallback) from a
    warm start. Measured: from a cold 'line' guess fatrop 1.1.8 looped without end inside one iteration
    (growing regularisation) on a published scenario-3 mean, where IPOPT converged in 33 iterations
    (0.35 s); warm-started fatrop solves (37 000 in two fits) all terminated, in about 30 ms.
    """
    from cobot_analysis.conventions import CONTINUOUS

    rule = CONTINUOUS.oc_rule("coupled")
    start, goal = np.asarray(start, float).reshape(2, 3), np.asarray(goal, float).reshape(2, 3)
    T0 = initial_pair_duration(start, goal, v_nominal)
    best = None
    for g in [guess] if isinstance(guess, str | np.ndarray) else guess:
        name = solver if solver != "auto" else ("ipopt" if isinstance(g, str) else "fatrop")
        s = get_coupled_ocp(OCPShape(n_intervals, free_time=True, solver=name, max_iter=max_iter, goal=rule.goal)).solve(
            start, goal, weights, T0, guess=g)
        if best is None or (s.success and (not best.success or s.cost < best.cost)):
            best = s
    return best
