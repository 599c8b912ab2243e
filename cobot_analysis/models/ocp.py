"""The single-walker optimal-control problem as one parametric casadi NLP (METHODS.md 5.3-5.5, 7).

Built once per problem *shape* (number of intervals, dynamics, free or fixed duration) and reused
for every solve: the start state, the goal, the duration, the weights and an optional tracking
reference are NLP parameters, so a new start/goal/weights costs a solve, not a rebuild.

Cost (multiple shooting, N intervals of dt = T / N, ``dynamics.step``, controls piecewise constant):

    J = sum_{k<N} dt [a0 + a1 u1^2 + a2 u2^2 + a3 u3^2 + a4 psi_k^2 r_k^2 / (r_k^2 + eps^2)
                      + a5 r_k^2 + a6 (thf - theta_k)^2]
      + sum_{k<=N} dt m_k [g0 ((cx_k - x_k)^2 + (cy_k - y_k)^2) + g1 (ctheta_k - theta_k)^2]
      + b0 r_N^2 + b1 (thf - theta_N)^2 + b2 (v_forw_N^2 + v_orth_N^2) + b3 omega_N^2

with r = distance to the goal and psi = atan2 of the goal direction in the walker frame (the
bearing of METHODS.md 5.3, wrapped to (-pi, pi]). psi is undefined at the goal: the factor
r^2 / (r^2 + eps^2) (eps = 5 cm by default) leaves the term unchanged away from the goal
(>= 0.99 beyond 0.5 m) and keeps its gradient bounded at it. Headings are not wrapped in the
heading terms (theta is unwrapped; pass the goal heading on the branch you mean).

- Mombaur model (5.4): a5, a6 > 0, b = 0.  Improved model (5.5): a5 = a6 = 0, b > 0.
- Prediction (7): m_k = 1 on the measured nodes (the first N0), 0 after; b = 0 and a4 = 0 give
  a free end; the start state (pose *and* velocities) is a parameter.
- Free duration (``free_time=True``): T becomes a decision variable (log T carried as a constant
  extra state so the stage structure is kept). At a solution this is the minimum over T of the
  fixed-T optimum, i.e. what the 1-D search of ``duration.py`` finds, in one solve.

Solver: fatrop (structure-exploiting interior point; variables ordered stage by stage,
``structure_detection='auto'``) with IPOPT (exact Hessian) on the same NLP as fallback; a solve
that neither converges is returned with ``success=False`` and callers must not use it silently.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from cobot_analysis.errors import SolverError
from cobot_analysis.models.dynamics import N_CONTROL, N_STATE, step

N_WEIGHTS = 11  # a0..a6, b0..b3 (presets.WALKER_WEIGHTS)
SOLVERS = ("fatrop", "ipopt")


@dataclass(frozen=True)
class OCPShape:
    """What fixes the NLP's structure (everything else is a parameter)."""

    n_intervals: int = 100
    dynamics: str = "walker"  # "walker" (holonomic) or "unicycle"
    free_time: bool = False
    psi_eps: float = 0.05  # m, regularisation of psi at the goal
    solver: str = "fatrop"  # first solver tried; IPOPT is the fallback
    tol: float = 1e-8
    max_iter: int = 500


@dataclass
class OCPSolution:
    X: np.ndarray  # (N+1, 6) states at the nodes
    U: np.ndarray  # (N, 3) controls on the intervals
    T: float  # duration (s)
    cost: float
    success: bool
    status: str  # solver return status
    solver: str  # which solver produced it
    iterations: int
    primal: np.ndarray = field(repr=False)  # raw NLP variables, for warm starts

    @property
    def t(self) -> np.ndarray:
        return np.linspace(0.0, self.T, self.X.shape[0])

    def check(self, what: str = "OC solve") -> "OCPSolution":
        """Raise ``SolverError`` unless converged."""
        if not self.success:
            raise SolverError(f"{what} did not converge ({self.solver}: {self.status})")
        return self


class WalkerOCP:
    """Parametric NLP for one walker; build once per ``OCPShape`` (see ``get_ocp``), solve many times."""

    def __init__(self, shape: OCPShape = OCPShape()):
        import casadi as ca

        self.shape = shape
        N, free = shape.n_intervals, shape.free_time
        nx, nu = N_STATE + (1 if free else 0), N_CONTROL
        self.nx, self.nu, self.N = nx, nu, N

        X0 = ca.SX.sym("X0", N_STATE)
        goal = ca.SX.sym("goal", 3)
        Tp = ca.SX.sym("T")
        W = ca.SX.sym("W", N_WEIGHTS)
        G = ca.SX.sym("g", 2)
        ref = ca.SX.sym("ref", 3, N + 1)
        mask = ca.SX.sym("mask", N + 1)
        self.n_params = N_STATE + 3 + 1 + N_WEIGHTS + 2 + 4 * (N + 1)
        p = ca.vertcat(X0, goal, Tp, W, G, ca.vec(ref), mask)

        # Per-stage functions (one expression graph each, called N times).
        xs, us, dts = ca.SX.sym("x", N_STATE), ca.SX.sym("u", nu), ca.SX.sym("dt")
        ws, gs, gl, rs = ca.SX.sym("w", N_WEIGHTS), ca.SX.sym("gw", 2), ca.SX.sym("goal", 3), ca.SX.sym("r", 3)
        dxg, dyg = gl[0] - xs[0], gl[1] - xs[1]
        r2 = dxg**2 + dyg**2
        ex = ca.cos(xs[2]) * dxg + ca.sin(xs[2]) * dyg
        ey = -ca.sin(xs[2]) * dxg + ca.cos(xs[2]) * dyg
        psi = ca.atan2(ey, ex)
        dth = gl[2] - xs[2]
        running = (ws[0] + ws[1] * us[0]**2 + ws[2] * us[1]**2 + ws[3] * us[2]**2
                   + ws[4] * psi**2 * r2 / (r2 + shape.psi_eps**2) + ws[5] * r2 + ws[6] * dth**2)
        L = ca.Function("L", [xs, us, ws, gl], [running])
        track = gs[0] * ((rs[0] - xs[0])**2 + (rs[1] - xs[1])**2) + gs[1] * (rs[2] - xs[2])**2
        Ltr = ca.Function("Ltr", [xs, gs, rs], [track])
        terminal = ws[7] * r2 + ws[8] * dth**2 + ws[9] * (xs[3]**2 + xs[4]**2) + ws[10] * xs[5]**2
        Lf = ca.Function("Lf", [xs, ws, gl], [terminal])
        F = ca.Function("F", [xs, us, dts], [step(xs, us, dts, shape.dynamics)])

        Xk = [ca.SX.sym(f"x{k}", nx) for k in range(N + 1)]
        Uk = [ca.SX.sym(f"u{k}", nu) for k in range(N)]
        J = 0
        g = [Xk[0][:N_STATE] - X0]
        for k in range(N):
            T = ca.exp(Xk[k][N_STATE]) if free else Tp
            dt = T / N
            J += dt * (L(Xk[k][:N_STATE], Uk[k], W, goal) + mask[k] * Ltr(Xk[k][:N_STATE], G, ref[:, k]))
            nxt = F(Xk[k][:N_STATE], Uk[k], dt)
            g.append(Xk[k + 1] - (ca.vertcat(nxt, Xk[k][N_STATE]) if free else nxt))
        T_end = ca.exp(Xk[N][N_STATE]) if free else Tp
        J += T_end / N * mask[N] * Ltr(Xk[N][:N_STATE], G, ref[:, N]) + Lf(Xk[N][:N_STATE], W, goal)
        w = ca.vertcat(*[v for k in range(N) for v in (Xk[k], Uk[k])], Xk[N])
        g = ca.vertcat(*g)
        self._nlp = {"x": w, "p": p, "f": J, "g": g}
        self._T_index = N_STATE + 3
        self.n_vars, self.n_cons = w.shape[0], g.shape[0]
        # index of state k / control k in the primal vector
        stride = nx + nu
        self._xi = np.array([[k * stride + i for i in range(nx)] for k in range(N + 1)])
        self._ui = np.array([[k * stride + nx + i for i in range(nu)] for k in range(N)])
        self._solvers: dict[str, object] = {}
        self._lock = threading.Lock()  # a casadi solver object must not run two solves at once
        self._solver(shape.solver)  # build the primary solver now

    # -- solvers ---------------------------------------------------------------------------------
    def _solver(self, name: str):
        import casadi as ca

        if name not in self._solvers:
            if name == "fatrop":
                opts = {"structure_detection": "auto", "expand": True, "equality": [True] * self.n_cons,
                        "print_time": False, "show_eval_warnings": False,
                        "fatrop": {"print_level": 0, "tol": self.shape.tol, "max_iter": self.shape.max_iter}}
            elif name == "ipopt":
                opts = {"expand": True, "print_time": False, "show_eval_warnings": False,
                        "ipopt": {"print_level": 0, "sb": "yes", "tol": self.shape.tol, "max_iter": 2 * self.shape.max_iter}}
            else:
                raise ValueError(f"unknown solver {name!r}; expected one of {SOLVERS}")
            self._solvers[name] = ca.nlpsol(f"walker_{name}", name, self._nlp, opts)
        return self._solvers[name]

    # -- parameters and guesses ------------------------------------------------------------------
    def parameters(self, start, goal, weights, T, *, start_velocity=(0.0, 0.0, 0.0), track=None,
                   track_weights=(10.0, 10.0), n_track: int | None = None) -> np.ndarray:
        """The NLP parameter vector. ``track``: (M, 3) measured poses for nodes 0..M-1 (M <= N+1)."""
        N = self.N
        weights = np.asarray(weights, dtype=float)
        if weights.shape != (N_WEIGHTS,):
            raise ValueError(f"expected {N_WEIGHTS} weights (a0..a6, b0..b3), got {weights.shape}")
        ref = np.zeros((N + 1, 3))
        mask = np.zeros(N + 1)
        if track is not None:
            track = np.asarray(track, dtype=float)
            m = track.shape[0] if n_track is None else n_track
            ref[:m] = track[:m]
            mask[:m] = 1.0
        return np.concatenate([np.asarray(start, float)[:3], np.asarray(start_velocity, float), np.asarray(goal, float),
                               [float(T)], weights, np.asarray(track_weights, float), ref.ravel(), mask])

    def guess(self, start, goal, T, kind: str = "rest", start_velocity=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Initial guess: ``rest`` (every node at the start state, zero controls) or ``line``
        (poses interpolated linearly from start to goal, at rest)."""
        w = np.zeros(self.n_vars)
        s = np.concatenate([np.asarray(start, float)[:3], np.asarray(start_velocity, float)])
        for k in range(self.N + 1):
            if kind == "line":
                a = k / self.N
                s = np.concatenate([(1 - a) * np.asarray(start, float)[:3] + a * np.asarray(goal, float), np.zeros(3)])
            w[self._xi[k, :N_STATE]] = s
            if self.shape.free_time:
                w[self._xi[k, N_STATE]] = math.log(T)
        return w

    # -- solve -----------------------------------------------------------------------------------
    def solve(self, start, goal, weights, T, *, guess: np.ndarray | str = "rest", start_velocity=(0.0, 0.0, 0.0),
              track=None, track_weights=(10.0, 10.0), n_track=None, fallback: bool = True,
              T_bounds: tuple[float, float] = (0.4, 2.5)) -> OCPSolution:
        """Solve for one start/goal/weights/duration (``T`` is the initial guess when ``free_time``).

        With ``free_time``, T is bounded to ``T_bounds`` x T: without a lower bound a start facing
        away from the goal has a degenerate local minimum at T -> 0 (stand still, pay the terminal cost).

        ``guess``: a previous ``OCPSolution.primal`` (warm start), or ``"rest"`` / ``"line"``.
        If the primary solver fails and ``fallback``, IPOPT is tried from the same guess.
        """
        p = self.parameters(start, goal, weights, T, start_velocity=start_velocity, track=track,
                            track_weights=track_weights, n_track=n_track)
        w0 = self.guess(start, goal, T, guess, start_velocity) if isinstance(guess, str) else np.asarray(guess, float)
        lbx, ubx = -np.inf, np.inf
        if self.shape.free_time:
            lbx, ubx = np.full(self.n_vars, -np.inf), np.full(self.n_vars, np.inf)
            lbx[self._xi[:, N_STATE]] = math.log(T_bounds[0] * T)
            ubx[self._xi[:, N_STATE]] = math.log(T_bounds[1] * T)
            w0 = w0.copy()
            w0[self._xi[:, N_STATE]] = np.clip(w0[self._xi[:, N_STATE]], lbx[self._xi[0, N_STATE]], ubx[self._xi[0, N_STATE]])
        return self._run(w0, p, lbx, ubx, fallback)

    def _run(self, w0, p, lbx, ubx, fallback: bool) -> OCPSolution:
        """The primary solver, then IPOPT on the same NLP if it failed and ``fallback``."""
        names = [self.shape.solver] + (["ipopt"] if fallback and self.shape.solver != "ipopt" else [])
        sol = None
        for name in names:
            with self._lock:
                solver = self._solver(name)
                res = solver(x0=w0, p=p, lbg=0.0, ubg=0.0, lbx=lbx, ubx=ubx)
                st = solver.stats()
            sol = self._unpack(np.asarray(res["x"]).ravel(), float(res["f"]), p, name, st)
            if sol.success:
                break
        return sol

    def _unpack(self, w, f, p, name, st) -> OCPSolution:
        X = w[self._xi]
        U = w[self._ui]
        ns = self.nx - (1 if self.shape.free_time else 0)
        T = float(np.exp(X[0, ns])) if self.shape.free_time else float(p[self._T_index])
        ok = bool(st.get("success", False)) and bool(np.isfinite(f)) and bool(np.all(np.isfinite(w)))
        return OCPSolution(X=X[:, :ns].copy(), U=U.copy(), T=T, cost=f, success=ok,
                           status=str(st.get("return_status", st.get("unified_return_status", "?"))), solver=name,
                           iterations=int(st.get("iter_count", -1)), primal=w.copy())


@lru_cache(maxsize=16)
def get_ocp(shape: OCPShape = OCPShape()) -> WalkerOCP:
    """The NLP for ``shape``, built once per process and reused (cache)."""
    return WalkerOCP(shape)
