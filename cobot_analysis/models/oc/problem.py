"""The single-walker optimal-control problem as one parametric casadi NLP (docs/methods.md 5.3-5.5, 7).

Built once per problem *shape* (number of intervals, dynamics, free or fixed duration) and reused
for every solve: the start state, the goal, the duration, the weights and an optional tracking
reference are NLP parameters, so a new start/goal/weights costs a solve, not a rebuild.

Cost (multiple shooting, N intervals, ``dynamics.step``, controls piecewise constant), in one of
two schemes (``OCPShape.scheme``, docs/methods.md sec. 11):

    J = sum_{k<N} s [a0 + a1 u1^2 + a2 u2^2 + a3 u3^2 + a4 psi_k^2 r_k^2 / (r_k^2 + eps^2)
                     + a5 r_k^2 + a6 e(thf, theta_k)^2]
      + sum_{k<=N} s m_k [g0 ((cx_k - x_k)^2 + (cy_k - y_k)^2) + g1 (ctheta_k - theta_k)^2]
      + b0 r_N^2 + b1 e(thf, theta_N)^2 + b2 (v_forw_N^2 + v_orth_N^2) + b3 omega_N^2  [+ phi_r(X_N, 0)]

- ``midpoint`` (continuous convention): the exact-in-time step, dt = T / N and s = dt (integrated
  running cost);
- ``euler`` (published convention): explicit Euler with the fixed node step dt = T (the parameter
  is the step), s = 1 (running cost summed per node, as the authors' crocoddyl action models).
  ``terminal_running`` adds the running cost at X_N with zero control to the terminal cost (the
  authors' Mombaur-form problem used its running model as terminal model).

r = distance to the goal. psi (``OCPShape.psi``): ``wrapped``, atan2 of the goal direction in the
walker frame, in (-pi, pi] (docs/methods.md sec. 5.3); ``raw``, atan2(yf - y, xf - x) - theta as
computed, theta unwrapped (the authors' form). psi is undefined at the goal: the factor
r^2 / (r^2 + eps^2) leaves the term unchanged away from the goal (>= 0.99 beyond 10 eps) and keeps
its gradient bounded at it. The heading error e (``OCPShape.heading``): ``raw`` thf - theta (pass
the goal heading on the branch you mean); ``wrap-once`` thf - theta moved by 2 pi once if outside
[-pi, pi]; ``fmod-pi`` fmod(thf, pi) - fmod(theta, pi) moved likewise (the authors' Mombaur form).

Variable horizon: an interval k whose active flag a_k (a parameter) is 0 is frozen,
X_{k+1} = X_k, and costs |u_k|^2 (so u_k = 0). With the frozen intervals after the active ones,
one NLP of N intervals solves every horizon T <= N with the optimum of the T-interval NLP (the
authors' duration rules try many integer horizons, see ``duration.py``).

- Mombaur model (5.4): a5, a6 > 0, b = 0.  Improved model (5.5): a5 = a6 = 0, b > 0.
- Prediction (7): m_k = 1 on the measured nodes (the first N0), 0 after; b = 0 and a4 = 0 give
  a free end; the start state (pose *and* velocities) is a parameter.
- Free duration (``free_time=True``): T becomes a decision variable (log T carried as a constant
  extra state so the stage structure is kept). At a solution this is the minimum over T of the
  fixed-T optimum, i.e. what the 1-D search of ``duration.py`` finds, in one solve.

Solver: fatrop (structure-exploiting interior point; variables ordered stage by stage,
``structure_detection='auto'``) with IPOPT (exact Hessian) on the same NLP as fallback; a solve
that neither converges is returned with ``success=False`` and callers must not use it silently.
``max_iter`` does not bound a fatrop solve: its inertia correction (fatrop's ``compute_search_dir``) loops
``while (!solved)`` without a cap, and a Jacobian still rank-deficient after its delta_c regularisation
is factorised again with the same delta_c for ever (seen warm-started in the goal-inferred predictor,
from cold guesses in ``coupled.py``, and in a single-level IOC fit's re-solve). So every fatrop solve runs
on a thread of its own (``_Runner``; casadi releases the GIL while it solves) and the caller stops waiting
when that thread has spent ``FATROP_CPU_LIMIT`` seconds of CPU on it: the solve is abandoned (its thread
left spinning until the process ends, its buffers with it), returned as failed with status
``CpuTime_Exceeded``, and IPOPT tried as for any failure. IPOPT's inertia correction is capped
(``max_hessian_perturbation``) and ``max_cpu_time`` bounds its CPU time: a caller that must always get
an answer uses ``solver="ipopt"`` with ``max_cpu_time``; a solve stopped by it returns ``success=False``,
status ``Maximum_CpuTime_Exceeded``.

Evaluation (``compiled_library``): the problem is written once, per stage (``_stage_functions``:
stage cost c_k(z_k), step F(z_k), terminal cost c_N(x_N), z_k = (x_k, u_k)), and the functions
fatrop calls are assembled from ``map`` of the stage functions and of their exact derivatives:

    grad f = [grad c_0; ...; grad c_N],   jac g = [I 0 ...; -dF/dz_0  I ...; ...],
    hess L = blockdiag_k(hess_z (sigma c_k - lambda_{k+1}' F(z_k)), sigma hess c_N),

then generated as C (a loop over the stages, not the unrolled NLP), compiled once per machine
with the system C compiler and cached on disk (``cache_dir()``, keyed by a hash of the C source;
loaded only from a private directory and when it matches its recorded digest: ``cache.py``).
Without a compiler, or with ``COBOT_ANALYSIS_OCP_COMPILE=0``, the same NLP is expanded into
casadi's SX virtual machine (about 2x slower per solve, the same iterates).
"""

from __future__ import annotations

import hashlib
import math
import os
import queue
import shutil
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass, field, replace
from functools import lru_cache, partial
from pathlib import Path

import numpy as np

from cobot_analysis.errors import SolverError
from cobot_analysis.models.dynamics import N_CONTROL, N_STATE, step

N_WEIGHTS = 11  # a0..a6, b0..b3 (presets.WALKER_WEIGHTS)
SOLVERS = ("fatrop", "ipopt")
COARSE_INTERVALS = 50  # grid of the first solve of guess="coarse"


@dataclass(frozen=True)
class OCPShape:
    """What fixes the NLP's structure (everything else is a parameter)."""

    n_intervals: int = 100
    dynamics: str = "walker"  # "walker" (holonomic) or "unicycle"
    free_time: bool = False
    psi_eps: float = 0.05  # m, regularisation of psi at the goal
    scheme: str = "midpoint"  # "midpoint" (dt = T / N, integrated costs) or "euler" (dt = T per node, summed costs)
    psi: str = "wrapped"  # "wrapped" (body-frame bearing) or "raw" (atan2 - theta)
    heading: str = "raw"  # heading error of the a6 and b1 terms: "raw", "wrap-once" or "fmod-pi"
    terminal_running: bool = False  # the terminal cost also holds the running cost at X_N with zero control
    goal: str = "cost"  # "cost": the b0..b3 terminal cost | "constraint": X_N = (goal pose, at rest), b0..b3 unused
    solver: str = "fatrop"  # first solver tried; IPOPT is the fallback
    tol: float = 1e-8
    max_iter: int = 500
    max_cpu_time: float = 0.0  # s of CPU per IPOPT solve (0: no limit); fatrop has no such bound (module docstring)


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
        self.shape = shape
        N, free = shape.n_intervals, shape.free_time
        nx, nu = N_STATE + (1 if free else 0), N_CONTROL
        self.nx, self.nu, self.N = nx, nu, N
        self.n_params = N_STATE + _N_COMMON + 4 * (N + 1) + N
        self._T_index = N_STATE + 3
        self.n_goal = N_STATE if shape.goal == "constraint" else 0  # terminal equalities X_N = (goal, 0, 0, 0)
        self.n_vars, self.n_cons = N * (nx + nu) + nx, N_STATE + N * nx + self.n_goal
        # index of state k / control k in the primal vector
        stride = nx + nu
        self._xi = np.array([[k * stride + i for i in range(nx)] for k in range(N + 1)])
        self._ui = np.array([[k * stride + nx + i for i in range(nu)] for k in range(N)])
        self._solvers: dict[str, object] = {}
        self._lock = threading.Lock()  # a casadi solver object must not run two solves at once
        self._solver(shape.solver)  # build the primary solver now

    # -- the NLP ---------------------------------------------------------------------------------
    def _nlp_functions(self) -> dict[str, object]:
        """The functions fatrop calls (names and signatures of casadi's ``nlpsol`` oracle), built
        from ``map`` of the stage functions over the N intervals (see the module docstring).

        Variables w = [z_0; ...; z_{N-1}; x_N], z_k = (x_k, u_k); constraints
        g = [x_0 - X0; x_1 - F(z_0); ...; x_N - F(z_{N-1})] and, with ``goal="constraint"``, the
        terminal equalities [x_N - (goal, 0, 0, 0)] (linear: no term in the Hessian); parameters as
        ``parameters``.
        """
        import casadi as ca

        N, nx, nu = self.N, self.nx, self.nu
        nz = nx + nu
        st = _stage_functions(self.shape)
        mapped = lambda f, bcast, red=(): f.map(f.name() + "_map", "serial", N, list(bcast), list(red))  # noqa: E731
        Mc, MF, Mgc = mapped(st["c"], [1], [0]), mapped(st["F"], [1]), mapped(st["grad_c"], [1])
        MJ, MH = mapped(st["jac_F"], [1]), mapped(st["hess_L"], [1, 5])

        w, p = ca.MX.sym("x", self.n_vars), ca.MX.sym("p", self.n_params)
        lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", self.n_cons)
        X0, Pc = p[:N_STATE], p[N_STATE:N_STATE + _N_COMMON]
        o = N_STATE + _N_COMMON
        ref, mask = ca.reshape(p[o:o + 3 * (N + 1)], 3, N + 1), p[o + 3 * (N + 1):o + 4 * (N + 1)]
        ak = p[o + 4 * (N + 1):].T  # active flags of the N intervals
        Z, xN = ca.reshape(w[:N * nz], nz, N), w[N * nz:]
        Xs = Z[:nx, :]
        Xnext = ca.horzcat(Xs[:, 1:], xN)
        rk, mk, rN, mN = ref[:, :N], mask[:N].T, ref[:, N], mask[N]

        f = Mc(Z, Pc, rk, mk, ak) + st["c_N"](xN, Pc, rN, mN)
        ng = self.n_goal
        g_goal = xN[:N_STATE] - ca.vertcat(Pc[:3], ca.MX.zeros(3)) if ng else ca.MX(0, 1)
        g = ca.vertcat(Xs[:N_STATE, 0] - X0, ca.vec(Xnext - MF(Z, Pc, ak)), g_goal)
        grad_f = ca.vertcat(ca.vec(Mgc(Z, Pc, rk, mk, ak)), st["grad_c_N"](xN, Pc, rN, mN))
        # Jacobian of g: nonzeros listed stage by stage, then permuted to casadi's column-major order
        Fk, JF = MJ(Z, Pc, ak)
        g_again = ca.vertcat(Xs[:N_STATE, 0] - X0, ca.vec(Xnext - Fk), g_goal)  # g from the same stage calls
        jr, jc = st["jac_F_sp"].get_triplet()
        n_dyn = N_STATE + N * nx
        rows = [*range(N_STATE)] + [N_STATE + k * nx + i for k in range(N) for i in jr] + \
               [N_STATE + k * nx + i for k in range(N) for i in range(nx)] + [n_dyn + i for i in range(ng)]
        cols = [*range(N_STATE)] + [k * nz + j for k in range(N) for j in jc] + \
               [(k + 1) * nz + i for k in range(N) for i in range(nx)] + [N * nz + i for i in range(ng)]
        Asp = ca.Sparsity.triplet(self.n_cons, self.n_vars, rows, cols)
        order = np.lexsort((np.asarray(rows), np.asarray(cols)))
        values = ca.vertcat(ca.DM.ones(N_STATE), -ca.vec(JF), ca.DM.ones(N * nx), ca.DM.ones(ng))
        jac_g = ca.MX(Asp, values[order.tolist()])
        # Hessian of the Lagrangian sigma f + lambda' g: block diagonal (column-major = stage order)
        Lam = ca.reshape(lam_g[N_STATE:n_dyn], nx, N)  # multiplier of x_{k+1} - F(z_k)
        lam_goal = ca.vertcat(lam_g[n_dyn:], ca.MX.zeros(nx - ng)) if ng else ca.MX.zeros(nx)  # of x_N - goal
        gL, HL = MH(Z, Pc, rk, mk, ak, lam_f, Lam)
        lam_x = ca.horzcat(ca.vertcat(lam_g[:N_STATE], ca.MX.zeros(nx - N_STATE)), Lam[:, :N - 1])
        gLN, HLN = st["hess_L_N"](xN, Pc, rN, mN, lam_f)
        grad_L = ca.vertcat(ca.vec(gL + ca.vertcat(lam_x, ca.MX.zeros(nu, N))), gLN + Lam[:, N - 1] + lam_goal)
        Hb, HbN = st["hess_L_sp"], st["hess_L_N_sp"]
        Hsp = ca.diagcat(*([ca.DM(Hb, 1)] * N + [ca.DM(HbN, 1)])).sparsity()
        hess_L = ca.MX(Hsp, ca.vertcat(ca.vec(HL), HLN))

        xp, xpl = ["x", "p"], ["x", "p", "lam_f", "lam_g"]
        return {
            "nlp": ca.Function("nlp", [w, p], [f, g], xp, ["f", "g"]),
            "nlp_f": ca.Function("nlp_f", [w, p], [f], xp, ["f"]),
            "nlp_g": ca.Function("nlp_g", [w, p], [g], xp, ["g"]),
            "nlp_grad_f": ca.Function("nlp_grad_f", [w, p], [grad_f], xp, ["grad_f_x"]),
            "nlp_jac_g": ca.Function("nlp_jac_g", [w, p], [g_again, jac_g], xp, ["g", "jac_g_x"]),
            "nlp_hess_l": ca.Function("nlp_hess_l", [w, p, lam_f, lam_g], [grad_L, hess_L], xpl,
                                      ["grad_gamma_x", "hess_gamma_x_x"]),
            # multipliers of p (casadi builds nlpsol with it even when they are not computed)
            "nlp_grad": ca.Function("nlp_grad", [w, p, lam_f, lam_g],
                                    [f, g, grad_L, ca.gradient(lam_f * f + ca.dot(lam_g, g), p)],
                                    xpl, ["f", "g", "grad_gamma_x", "grad_gamma_p"]),
        }

    def _sx_nlp(self):
        """The NLP expanded into casadi SX (IPOPT, and fatrop without a C compiler)."""
        if getattr(self, "_nlp", None) is None:
            self._nlp = self._nlp_functions()["nlp"].expand()
        return self._nlp

    # -- solvers ---------------------------------------------------------------------------------
    def _solver(self, name: str):
        import casadi as ca

        if name not in self._solvers:
            if name == "fatrop":
                # error_on_fail: a failed solve raises, so a converged one needs no stats() (``_BufferedCall``)
                opts = {"structure_detection": "auto", "equality": [True] * self.n_cons, "error_on_fail": True,
                        "print_time": False, "show_eval_warnings": False,
                        "fatrop": {"print_level": 0, "tol": self.shape.tol, "max_iter": self.shape.max_iter}}
                library = compiled_library(self)
                if library is not None:
                    # only x and f are used: skip computing the multipliers and g after each solve
                    opts.update(calc_lam_p=False, calc_lam_x=False, calc_f=False, calc_g=False)
                    self._solvers[name] = _fatrop_solver(library, opts)
                else:
                    self._solvers[name] = ca.nlpsol(f"walker_{name}", name, self._sx_nlp(), {**opts, "expand": True})
            elif name == "ipopt":
                opts = {"expand": True, "print_time": False, "show_eval_warnings": False,
                        "ipopt": {"print_level": 0, "sb": "yes", "tol": self.shape.tol, "max_iter": 2 * self.shape.max_iter}}
                if self.shape.max_cpu_time > 0:
                    opts["ipopt"]["max_cpu_time"] = self.shape.max_cpu_time
                self._solvers[name] = ca.nlpsol(f"walker_{name}", name, self._sx_nlp(), opts)
            else:
                raise ValueError(f"unknown solver {name!r}; expected one of {SOLVERS}")
        return self._solvers[name]

    # -- parameters and guesses ------------------------------------------------------------------
    def parameters(self, start, goal, weights, T, *, start_velocity=(0.0, 0.0, 0.0), track=None,
                   track_weights=(10.0, 10.0), n_track: int | None = None, n_active: int | None = None) -> np.ndarray:
        """The NLP parameter vector. ``track``: (M, 3) measured poses for nodes 0..M-1 (M <= N+1);
        ``n_active``: intervals of the horizon (the others frozen; default all N)."""
        N = self.N
        n_active = N if n_active is None else int(n_active)
        if not 1 <= n_active <= N:
            raise ValueError(f"n_active must be in 1..{N}, got {n_active}")
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
                               [float(T)], weights, np.asarray(track_weights, float), ref.ravel(), mask,
                               np.arange(N) < n_active])

    def guess(self, start, goal, T, kind: str = "rest", start_velocity=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Initial guess: ``rest`` (every node at the start state, zero controls) or ``line``
        (poses interpolated linearly from start to goal, at rest)."""
        w = np.zeros(self.n_vars)
        start, goal = np.asarray(start, float)[:3], np.asarray(goal, float)
        if kind == "line":
            a = np.arange(self.N + 1)[:, None] / self.N
            w[self._xi[:, :3]] = (1 - a) * start + a * goal
        else:
            w[self._xi[:, :N_STATE]] = np.concatenate([start, np.asarray(start_velocity, float)])
        if self.shape.free_time:
            w[self._xi[:, N_STATE]] = math.log(T)
        return w

    def coarse_guess(self, start, goal, weights, T, *, start_velocity=(0.0, 0.0, 0.0), T_bounds=(0.4, 2.5)) -> np.ndarray:
        """The solution of the same problem on ``COARSE_INTERVALS`` intervals (cold, from rest),
        interpolated linearly in time onto this grid (controls at the interval midpoints)."""
        nc = COARSE_INTERVALS
        if nc >= self.N:
            return self.guess(start, goal, T, "rest", start_velocity)
        c = get_ocp(replace(self.shape, n_intervals=nc)).solve(start, goal, weights, T, guess="rest",
                                                                start_velocity=start_velocity, T_bounds=T_bounds)
        w = np.zeros(self.n_vars)
        t, tc = np.linspace(0.0, 1.0, self.N + 1), np.linspace(0.0, 1.0, nc + 1)
        w[self._xi[:, :N_STATE]] = np.column_stack([np.interp(t, tc, c.X[:, i]) for i in range(N_STATE)])
        t, tc = (t[:-1] + t[1:]) / 2, (tc[:-1] + tc[1:]) / 2
        w[self._ui] = np.column_stack([np.interp(t, tc, c.U[:, i]) for i in range(self.nu)])
        if self.shape.free_time:
            w[self._xi[:, N_STATE]] = math.log(c.T)
        return w if np.all(np.isfinite(w)) else self.guess(start, goal, T, "rest", start_velocity)

    # -- solve -----------------------------------------------------------------------------------
    def solve(self, start, goal, weights, T, *, guess: np.ndarray | str = "rest", start_velocity=(0.0, 0.0, 0.0),
              track=None, track_weights=(10.0, 10.0), n_track=None, fallback: bool = True,
              T_bounds: tuple[float, float] = (0.4, 2.5), n_active: int | None = None, stats: bool = True) -> OCPSolution:
        """Solve for one start/goal/weights/duration (``T`` is the initial guess when ``free_time``;
        the node step with the euler scheme); ``n_active``: horizon in intervals (default N), the
        returned solution holds its n_active + 1 nodes only.

        With ``free_time``, T is bounded to ``T_bounds`` x T: without a lower bound a start facing
        away from the goal has a degenerate local minimum at T -> 0 (stand still, pay the terminal cost).

        ``guess``: a previous ``OCPSolution.primal`` (warm start), ``"rest"`` / ``"line"``, or
        ``"coarse"``: the same problem solved from rest on ``COARSE_INTERVALS`` intervals first and
        interpolated (``coarse_guess``; without tracking only). Still a cold solve for the caller, about
        3.8x faster at 500 nodes (8.6 against 32.4 ms, docs/benchmarks.md, OC solver), but the problem has several local minima and it
        need not end in the one the rest guess ends in (1 of the 6 benchmark starts: a lower-cost one).
        If the primary solver fails and ``fallback``, IPOPT is tried from the same guess.
        ``stats=False``: a converged fatrop solve does not read the solver's statistics (about 0.1 ms of a
        0.6 ms solve at 50 nodes): its ``iterations`` is -1 and its status ``"Solve_Succeeded"``; a failed
        one reads them as usual.
        """
        p = self.parameters(start, goal, weights, T, start_velocity=start_velocity, track=track,
                            track_weights=track_weights, n_track=n_track, n_active=n_active)
        if isinstance(guess, str) and guess == "coarse":
            if track is not None:
                raise ValueError("guess='coarse' is for problems without a tracking reference")
            w0 = self.coarse_guess(start, goal, weights, T, start_velocity=start_velocity, T_bounds=T_bounds)
        elif isinstance(guess, str):
            w0 = self.guess(start, goal, T, guess, start_velocity)
        else:
            w0 = np.asarray(guess, float)
        lbx, ubx = -np.inf, np.inf
        if self.shape.free_time:
            lbx, ubx = np.full(self.n_vars, -np.inf), np.full(self.n_vars, np.inf)
            lbx[self._xi[:, N_STATE]] = math.log(T_bounds[0] * T)
            ubx[self._xi[:, N_STATE]] = math.log(T_bounds[1] * T)
            w0 = w0.copy()
            w0[self._xi[:, N_STATE]] = np.clip(w0[self._xi[:, N_STATE]], lbx[self._xi[0, N_STATE]], ubx[self._xi[0, N_STATE]])
        return self._run(w0, p, lbx, ubx, fallback, self.N if n_active is None else int(n_active), stats)

    def _run(self, w0, p, lbx, ubx, fallback: bool, n_active: int, stats: bool = True) -> OCPSolution:
        """The primary solver, then IPOPT on the same NLP if it failed and ``fallback``."""
        names = [self.shape.solver] + (["ipopt"] if fallback and self.shape.solver != "ipopt" else [])
        sol = None
        for name in names:
            with self._lock:
                w, f, st = self._call(name)(w0, p, lbx, ubx, stats)
            sol = self._unpack(w, f, p, name, st, n_active)
            if sol.success:
                break
        return sol

    def _call(self, name: str) -> "_BufferedCall":
        calls = self.__dict__.setdefault("_calls", {})
        if name not in calls or calls[name].abandoned:  # an abandoned solve keeps its buffers: new ones
            # fatrop is built with error_on_fail (``_solver``): only its failures raise
            calls[name] = _BufferedCall(self._solver(name), self.n_vars, self.n_params, self.n_cons, raises=name == "fatrop")
        return calls[name]

    def _unpack(self, w, f, p, name, st, n_active: int) -> OCPSolution:
        X = w[self._xi[:n_active + 1]]
        U = w[self._ui[:n_active]]
        ns = self.nx - (1 if self.shape.free_time else 0)
        T = float(np.exp(X[0, ns])) if self.shape.free_time else float(p[self._T_index])
        if self.shape.scheme == "euler":
            T *= n_active  # the parameter is the node step
        elif n_active < self.N:
            T *= n_active / self.N
        ok = bool(st.get("success", False)) and bool(np.isfinite(f)) and bool(np.all(np.isfinite(w)))
        return OCPSolution(X=X[:, :ns].copy(), U=U, T=T, cost=f, success=ok,
                           status=str(st.get("return_status", st.get("unified_return_status", "?"))), solver=name,
                           iterations=int(st.get("iter_count", -1)), primal=w)  # X, U, w: fresh arrays already


class _BufferedCall:
    """Calls an ``nlpsol`` solver with lbg = ubg = 0 through casadi's ``FunctionBuffer``: inputs and
    outputs are numpy arrays casadi reads and writes in place (no conversion to and from DM, which
    costs about 1 ms per call at 500 nodes). Not thread-safe: callers hold ``WalkerOCP._lock``."""

    def __init__(self, solver, n_vars: int, n_params: int, n_cons: int, raises: bool = False):
        self.buffer, self.run = solver.buffer()
        self.raises = raises  # the solver was built with error_on_fail: a solve that returns has converged
        self.x0, self.p = np.zeros(n_vars), np.zeros(n_params)
        self.lbx, self.ubx = np.full(n_vars, -np.inf), np.full(n_vars, np.inf)
        args = (self.x0, self.p, self.lbx, self.ubx, np.zeros(n_cons), np.zeros(n_cons), np.zeros(n_vars), np.zeros(n_cons))
        self._args = args  # x0, p, lbx, ubx, lbg, ubg, lam_x0, lam_g0: kept alive while casadi points to them
        for i, a in enumerate(args):
            self.buffer.set_arg(i, memoryview(a))
        self.x, self.f = np.zeros(n_vars), np.zeros(1)
        self.buffer.set_res(0, memoryview(self.x))
        self.buffer.set_res(1, memoryview(self.f))  # g and the multipliers are not requested
        self.abandoned = False  # a solve past FATROP_CPU_LIMIT still holds the buffers: never call again

    def __call__(self, w0, p, lbx, ubx, stats: bool = True) -> tuple[np.ndarray, float, dict]:
        """Solve from ``w0``; returns the primal solution, the cost and the solver's stats. A solver built
        with ``error_on_fail`` (``raises``: fatrop) raises when it fails: its stats are then read whatever
        ``stats``; without ``stats`` its converged solves return ``_CONVERGED`` instead of reading them.
        fatrop solves run on ``_Runner``'s thread, abandoned past ``FATROP_CPU_LIMIT`` (module docstring)."""
        self.x0[:], self.p[:], self.lbx[:], self.ubx[:] = w0, p, lbx, ubx
        try:
            if not self.raises:
                self.run()
            elif not self._run_bounded():
                return np.array(w0, dtype=float), math.nan, {"success": False, "return_status": "CpuTime_Exceeded",
                                                             "iter_count": -1}
        except RuntimeError as e:
            if "nlpsol process failed" not in str(e):  # casadi's error_on_fail message; anything else is not a failed solve
                raise
            return self.x.copy(), float(self.f[0]), self.buffer.stats()
        return self.x.copy(), float(self.f[0]), _CONVERGED if self.raises and not stats else self.buffer.stats()


    def _run_bounded(self) -> bool:
        """The solve on ``_Runner``'s thread; False if abandoned. Abandoned, or left by an interrupt while it
        runs, the solve may still write into this call's buffers: it is never used again."""
        runner = _Runner.get()
        try:
            done = runner.run(self.run, FATROP_CPU_LIMIT)
        except BaseException:
            self.abandoned = runner.running
            raise
        self.abandoned = not done
        return done


_CONVERGED = {"success": True, "return_status": "Solve_Succeeded", "iter_count": -1}  # stats not read (``solve(stats=False)``)

# s of CPU: one fatrop solve past it is abandoned (module docstring). A solve that fails at its 500-iteration cap
# took 0.12-0.13 s on average on the Mombaur grids of the walking and table means (docs/benchmarks.md); a
# converged one milliseconds.
FATROP_CPU_LIMIT = 60.0


class _Runner:
    """The thread that makes this process's fatrop solves, one at a time, and the CPU time it spends on each."""

    _current: "_Runner | None" = None
    _guard = threading.Lock()

    def __init__(self):
        self.pid = os.getpid()
        self._todo: queue.SimpleQueue = queue.SimpleQueue()
        self._done: queue.SimpleQueue = queue.SimpleQueue()  # None, or the call's exception
        self._busy = threading.Lock()
        self.running = False  # a call is on the thread
        self.thread = threading.Thread(target=self._loop, name="fatrop", daemon=True)
        self.thread.start()
        try:
            clock = time.pthread_getcpuclockid(self.thread.ident)
        except (AttributeError, OSError):  # no per-thread CPU clock here (macOS): the limit in wall time
            self.elapsed = time.monotonic
        else:
            self.elapsed = partial(time.clock_gettime, clock)

    @classmethod
    def get(cls) -> "_Runner":
        """This process's runner (a forked pool worker makes its own: threads do not survive a fork)."""
        with cls._guard:
            if cls._current is None or cls._current.pid != os.getpid():
                cls._current = _Runner()
            return cls._current

    def _loop(self) -> None:
        while True:
            fn = self._todo.get()
            try:
                fn()
            except BaseException as exc:  # noqa: BLE001 - re-raised in the caller's thread
                self._done.put(exc)
            else:
                self._done.put(None)

    def run(self, fn, limit: float) -> bool:
        """``fn()`` on the thread; False if the thread spent ``limit`` s of CPU before it returned: the call is
        then abandoned with the thread, and the next ``get()`` starts another."""
        with self._busy:
            start = self.elapsed()
            self.running = True
            self._todo.put(fn)
            try:
                while True:
                    try:
                        error = self._done.get(timeout=0.25)
                        break
                    except queue.Empty:
                        if self.elapsed() - start > limit:
                            self._retire()
                            return False
            except BaseException:  # an interrupt while the call runs: it goes on, on a thread nobody waits for
                self._retire()
                raise
            self.running = False
            if error is not None:
                raise error
            return True

    def _retire(self) -> None:
        with _Runner._guard:
            if _Runner._current is self:
                _Runner._current = None


_N_COMMON = 3 + 1 + N_WEIGHTS + 2  # goal, T, a0..b3, tracking weights: the parameters every stage sees
# m^2: closer to the goal than this, the bearing term psi^2 is 0 (undefined there): 1e-15 m with the wrapped
# psi (continuous convention). A long horizon's last nodes wait within 1e-12 to 1e-7 m of the goal; the term's
# gradient jumps by 2 dt a4 psi^2 r / eps^2 at the cut-off (3e-5 at 1e-8 m: the solver cycles there), which
# must stay well below the solver's tolerance (3e-12 at 1e-15 m; docs/methods.md 5.3). The published
# convention keeps 1e-8 m.
_R2_GOAL, _R2_GOAL_RAW = 1e-30, 1e-16


def _stage_functions(shape: OCPShape) -> dict[str, object]:
    """Cost and dynamics of one interval and of the last node, with their exact derivatives
    (casadi SX). z = (x, u); P = (goal, T, weights, tracking weights); r, m = tracking reference
    and mask of the node; a = active flag of the interval; sigma, lam = multipliers of the cost and
    of x_{k+1} - F(z)."""
    import casadi as ca

    N, free = shape.n_intervals, shape.free_time
    nx = N_STATE + (1 if free else 0)
    z, xN = ca.SX.sym("z", nx + N_CONTROL), ca.SX.sym("xN", nx)
    gl, Tp, ws, gs = ca.SX.sym("goal", 3), ca.SX.sym("T"), ca.SX.sym("w", N_WEIGHTS), ca.SX.sym("gw", 2)
    P = ca.vertcat(gl, Tp, ws, gs)
    r, m, a = ca.SX.sym("r", 3), ca.SX.sym("m"), ca.SX.sym("a")
    sigma, lam = ca.SX.sym("sigma"), ca.SX.sym("lam", nx)
    euler = shape.scheme == "euler"
    r2_cut = _R2_GOAL if shape.psi == "wrapped" else _R2_GOAL_RAW  # the bearing term is 0 closer to the goal
    if euler and free:
        raise ValueError("the euler scheme has a fixed node step: no free duration")

    def heading_error(th):
        e = gl[2] - th
        if shape.heading == "fmod-pi":
            e = ca.fmod(gl[2], ca.pi) - ca.fmod(th, ca.pi)
        elif shape.heading != "wrap-once":
            return e
        return ca.if_else(e > ca.pi, e - 2 * ca.pi, ca.if_else(e < -ca.pi, e + 2 * ca.pi, e))

    def terms(x):
        dxg, dyg = gl[0] - x[0], gl[1] - x[1]
        r2 = dxg**2 + dyg**2
        if shape.psi == "raw":
            psi = ca.atan2(dyg, dxg) - x[2]
        else:
            psi = ca.atan2(-ca.sin(x[2]) * dxg + ca.cos(x[2]) * dyg, ca.cos(x[2]) * dxg + ca.sin(x[2]) * dyg)
        track = gs[0] * ((r[0] - x[0])**2 + (r[1] - x[1])**2) + gs[1] * (r[2] - x[2])**2
        dt = Tp if euler else (ca.exp(x[N_STATE]) if free else Tp) / N
        return r2, psi, heading_error(x[2]), track, dt

    def running(x, u):
        r2, psi, dth, _, _ = terms(x)
        # psi and its derivatives are undefined at the goal (0/0): the term is 0 there, exactly (if_else
        # selects, it does not multiply, so no NaN reaches the solver; fatrop 1.1.8 never returns from a NaN)
        bearing = ca.if_else(r2 > r2_cut, psi**2 * r2 / (r2 + shape.psi_eps**2), 0)
        return (ws[0] + ws[1] * u[0]**2 + ws[2] * u[1]**2 + ws[3] * u[2]**2
                + ws[4] * bearing + ws[5] * r2 + ws[6] * dth**2)

    x, u = z[:nx], z[nx:]
    _, _, _, track, dt = terms(x)
    scale = 1 if euler else dt  # summed per node (euler) or integrated (midpoint)
    c = scale * (ca.if_else(a > 0.5, running(x, u), 0) + m * track) + (1 - a) * ca.sumsqr(u)
    F = x[:N_STATE] + a * (step(x[:N_STATE], u, dt, shape.dynamics, shape.scheme) - x[:N_STATE])
    if free:
        F = ca.vertcat(F, x[N_STATE])  # log T is carried along
    r2, _, dth, track, dt = terms(xN)
    c_N = (1 if euler else dt) * m * track
    if shape.goal == "cost":  # with goal="constraint" X_N is the goal at rest: these terms are 0 and left out
        c_N = c_N + ws[7] * r2 + ws[8] * dth**2 + ws[9] * (xN[3]**2 + xN[4]**2) + ws[10] * xN[5]**2
    if shape.terminal_running:
        c_N = c_N + running(xN, ca.DM.zeros(N_CONTROL))
    H, gL = ca.hessian(sigma * c - ca.dot(lam, F), z)
    HN, gLN = ca.hessian(sigma * c_N, xN)
    J = ca.jacobian(F, z)
    # derivative matrices are returned as their structural nonzeros (column-major), patterns apart
    return {
        "jac_F_sp": J.sparsity(), "hess_L_sp": H.sparsity(), "hess_L_N_sp": HN.sparsity(),
        "c": ca.Function("c", [z, P, r, m, a], [c]),
        "F": ca.Function("F", [z, P, a], [F]),
        "grad_c": ca.Function("grad_c", [z, P, r, m, a], [ca.gradient(c, z)]),
        "jac_F": ca.Function("jac_F", [z, P, a], [F, J.nz[:]]),
        "hess_L": ca.Function("hess_L", [z, P, r, m, a, sigma, lam], [gL, H.nz[:]]),
        "c_N": ca.Function("c_N", [xN, P, r, m], [c_N]),
        "grad_c_N": ca.Function("grad_c_N", [xN, P, r, m], [ca.gradient(c_N, xN)]),
        "hess_L_N": ca.Function("hess_L_N", [xN, P, r, m, sigma], [gLN, HN.nz[:]]),
    }


def cache_dir() -> Path:
    """Where compiled NLP libraries are kept: ``$COBOT_ANALYSIS_CACHE`` or ``~/.cache/cobot-analysis``."""
    default = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "cobot-analysis"
    return Path(os.environ.get("COBOT_ANALYSIS_CACHE", default)) / "ocp"


_CFLAGS = ("-O2", "-fPIC", "-shared")
_compile_failed: set[tuple[str, Path]] = set()  # (compiler, cache) pairs that failed in this process: not retried
_untrusted_warned: set[Path] = set()  # caches refused in this process (warned once)


def _trusted_cache() -> Path | None:
    """``cache_dir()`` when it may hold code to load (``cache.untrusted_reason``), else None (warned once)."""
    from cobot_analysis.models.oc.cache import untrusted_reason

    directory = cache_dir()
    reason = untrusted_reason(directory)
    if reason is None:
        return directory
    if directory not in _untrusted_warned:
        from cobot_analysis.console import warn

        _untrusted_warned.add(directory)
        warn(f"the solver cache {directory} is not used: {reason}, so another user could plant code in it; solving with "
             f"casadi's virtual machine (about 2x slower). Make it private (chmod 700, owned by you) or set "
             f"COBOT_ANALYSIS_CACHE to a private directory (docs/cache.md)")
    return None


def compiled_library(ocp: WalkerOCP) -> Path | None:
    """Path of the shared library with ``ocp``'s NLP functions, compiled on first use and cached
    (file name = hash of the C source, compiler and flags). A cached library is returned only from a
    private cache and when it matches the digest recorded when it was built (``cache.py``); else it
    is rebuilt. None when compilation is disabled (``COBOT_ANALYSIS_OCP_COMPILE=0``), no C compiler
    is found, it failed, or the cache is not private."""
    import casadi as ca

    from cobot_analysis.models.oc import cache

    if os.environ.get("COBOT_ANALYSIS_OCP_COMPILE", "1") == "0":
        return None
    cc = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if cc is None or (cc, cache_dir()) in _compile_failed or _trusted_cache() is None:
        return None
    gen = ca.CodeGenerator("walker_ocp.c", {"with_header": False})
    for f in ocp._nlp_functions().values():
        gen.add(f)
    source = gen.dump()
    key = hashlib.sha256("\n".join([source, cc, *_CFLAGS, ca.__version__]).encode()).hexdigest()[:24]
    target = cache_dir() / f"walker_ocp_{key}.so"
    if cache.verified(target):
        return target
    try:
        with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
            c_file, so_file = Path(tmp) / "walker_ocp.c", Path(tmp) / "walker_ocp.so"
            c_file.write_text(source)
            run = subprocess.run([cc, *_CFLAGS, c_file.name, "-o", so_file.name, "-lm"], capture_output=True, text=True, cwd=tmp)
            if run.returncode != 0:
                raise OSError(run.stderr.strip().splitlines()[-1] if run.stderr.strip() else f"exit code {run.returncode}")
            cache.install(so_file, target)  # atomic; a library planted or damaged at ``target`` is replaced
    except OSError as e:
        from cobot_analysis.console import warn

        _compile_failed.add((cc, cache_dir()))
        warn(f"compiling the OC solver's functions with {cc} into {target.parent} failed ({e}); "
             "using casadi's virtual machine (about 2x slower)")
        return None
    return target


def _fatrop_solver(library: Path, opts: dict):
    """casadi's fatrop ``nlpsol`` on the compiled ``library``, kept serialised beside it.

    Building it sets up fatrop's block structure, which in casadi's interface costs about N^2
    (0.6 s at 930 intervals, 1.4 s at 1395, in every process that needs the shape); loading the
    serialised solver (``Function.serialize`` / ``deserialize``) takes about 0.04 s. It is loaded
    only when it matches the digest recorded when it was written (``cache.verified``, a file
    outside it; ``library`` was verified by ``compiled_library``): an absent, damaged, planted or
    unreadable file is ignored and rewritten (atomically), never loaded.
    """
    import casadi as ca

    from cobot_analysis.models.oc import cache

    key = hashlib.sha256(repr(sorted(opts.items())).encode()).hexdigest()[:16]
    path = library.with_name(f"{library.stem}_fatrop_{key}.casadi")
    try:
        if cache.verified(path):
            return ca.Function.deserialize(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, RuntimeError):
        pass  # damaged or from a library that is gone: rebuilt below
    solver = ca.nlpsol("walker_fatrop", "fatrop", str(library), opts)
    text = solver.serialize()
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        cache.install(tmp, path)  # atomic: concurrent writers of the same key write the same file
    except OSError:
        tmp.unlink(missing_ok=True)  # a read-only or full cache: the solver is built again next time
    return solver


@lru_cache(maxsize=16)
def get_ocp(shape: OCPShape = OCPShape()) -> WalkerOCP:
    """The NLP for ``shape``, built once per process and reused (cache)."""
    return WalkerOCP(shape)
