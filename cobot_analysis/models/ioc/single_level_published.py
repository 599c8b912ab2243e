"""Single-level IOC under the published convention (docs/methods.md sec. 6.1), at held horizons.

The published lower level has an integer horizon T_n (nodes of the fixed step dt) chosen by the
authors' duration rule, a search on J/T over horizons with no first-order condition. As the
bi-level fit does (``fit.fit``, ``IOCSpec.hold_duration``), each target's horizon is held at the one
the rule chooses at the start weights; the lower level is then an equality-constrained NLP (fixed
T_n and dt, explicit-Euler dynamics, start state; goal as the b0..b3 terminal cost): the problem
``duration.HorizonSolver`` solves, ``capacity(T_n)`` intervals with those after T_n frozen. Its KKT
conditions F_n(v_n; w) = [grad_z L_n; g_n] = 0, v_n = (z_n, lambda_n), are the constraints of the
single-level NLP

    min_{w, v}  (1/N_traj) sum_n D_n(z_n)   s.t.  F_n(v_n; w) = 0,  w_i in [1e-7, 1e3],

solved by a feasible path as ``single_level.fit_feasible_path``: every iterate holds each
F_n = 0 (Newton's method on the KKT matrix K_n = [[hess L, A'], [A, 0]] of the lower level's own
NLP functions, started from the linear predictor v_n + S_n dw, S_n = -K_n^-1 dF_n/dw).
D_n is the published distance itself (``fit.distances``: arc-length resampling by an interpolating
spline, d_xy + 0.5 d_gamma with the data's gamma), not a smoothed copy: its gradient in
y = log10 w along the KKT manifold is dD/dy_i = grad_z D . S_i w_i ln 10, computed by central
differences of D on the linear predictor z + S_i dw_i (exact to O(h^2): the predictor is the
manifold to first order). The trust-region model's Hessian is the finite-difference Jacobian of
that gradient over corrected branches at the start, updated by damped BFGS after each accepted
step. Afterwards, as the bi-level fit: the lower levels re-solved at the fitted weights on the
held horizons (``held_objective``), then the duration rule run again there (``objective``,
``horizons_changed``) as a check of the held horizon, the held solution its solve there: kept when the
rule's criterion J/T is no lower one node either side (one or two solves), else the rule's search started
there (the search from the authors' T_guess, as at the start, gave the same horizons and D to 6e-12 on the
walking means).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import replace

import numpy as np

from cobot_analysis.models.ioc.fit import (LOG_BOUNDS, IOCResult, IOCSpec, distances, evaluate_chunk, longest_first,
                                          reference_chunk, rule_check_chunk)
from cobot_analysis.models.ioc.targets import Target
from cobot_analysis.models.presets import names_for

GRADIENT_STEP = 1e-2  # log10 units: the central differences of D on the linear predictor (the published D's spline
# resampling makes it rough at smaller scales)
HESSIAN_STEP = 0.02  # log10 units: the forward differences of the gradient for the first model Hessian


def held_shape(spec: IOCSpec, horizon: int):
    """The ``OCPShape`` on which ``oc._solve_published`` solves ``horizon`` nodes (same NLP, same compiled library)."""
    from cobot_analysis import conventions
    from cobot_analysis.models.oc.duration import capacity
    from cobot_analysis.models.oc.problem import OCPShape

    rule = conventions.PUBLISHED.oc_rule("table" if spec.model == "table" else "improved")
    return OCPShape(capacity(int(horizon)), "walker", scheme="euler", psi=rule.psi, heading=rule.heading,
                    psi_eps=rule.psi_eps, terminal_running=rule.duration == "last-node", solver="fatrop",
                    max_iter=spec.max_iter)


@functools.lru_cache(maxsize=8)
def _functions(shape):
    """(ocp, nlp_hess_l, nlp_jac_g, nlp_grad_f): the lower level's own NLP functions (``WalkerOCP._nlp_functions``),
    from the compiled library the solver loads when there is one (``problem.compiled_library``)."""
    import casadi as ca

    from cobot_analysis.models.oc.problem import compiled_library, get_ocp

    ocp = get_ocp(shape)
    names = ("nlp_hess_l", "nlp_jac_g", "nlp_grad_f")
    library = compiled_library(ocp)
    if library is not None:
        return (ocp, *(ca.external(n, str(library)) for n in names))
    fs = ocp._nlp_functions()
    return (ocp, *(fs[n] for n in names))


def _pattern(sp):
    """A casadi sparsity as a CSC matrix of ones."""
    from scipy.sparse import csc_matrix

    colind, row = sp.get_ccs()
    return csc_matrix((np.ones(len(row)), row, colind), shape=sp.shape)


@functools.lru_cache(maxsize=8)
def _ordering(shape) -> np.ndarray:
    """A reverse Cuthill-McKee ordering of the KKT matrix of ``shape`` (each stage's variables and multipliers
    together: a band, factorised with little fill)."""
    from scipy.sparse import bmat
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    _, hess_l, jac_g, _ = _functions(shape)
    H, A = (_pattern(f.sparsity_out(1)) for f in (hess_l, jac_g))
    K = bmat([[H, A.T], [A, None]], format="csr")
    return np.asarray(reverse_cuthill_mckee((K + K.T).tocsr(), symmetric_mode=True))


class _Factor:
    """LU of the KKT matrix already permuted into the band order (``_kkt_function``; no further column ordering:
    the band has no fill to avoid), solving K x = b."""

    def __init__(self, K_perm, order: np.ndarray):
        from scipy.sparse.linalg import splu

        self.order = order
        self.lu = splu(K_perm, permc_spec="NATURAL")

    def solve(self, b):
        b = np.asarray(b, float)
        x = np.empty_like(b)
        x[self.order] = self.lu.solve(np.ascontiguousarray(b[self.order]))
        return x


def _kkt_function(shape):
    """The casadi Function (z, p, lambda) -> (F, K[order][:, order]): F = [grad_z L; g] and K = dF/dv permuted by
    ``_ordering``, from the lower level's own NLP functions."""
    import casadi as ca

    ocp, hess_l, jac_g, _ = _functions(shape)
    z, p, lam = ca.MX.sym("z", ocp.n_vars), ca.MX.sym("p", ocp.n_params), ca.MX.sym("lam", ocp.n_cons)
    gL, HL = hess_l(z, p, 1.0, lam)
    g, A = jac_g(z, p)
    K = ca.blockcat([[HL, A.T], [A, ca.MX(ocp.n_cons, ocp.n_cons)]])
    order = [int(i) for i in _ordering(shape)]
    return ca.Function("kkt", [z, p, lam], [ca.vertcat(gL, g), K[order, order]])


def _weights_function(shape, fitted: tuple[int, ...]):
    """The casadi Function (z, p) -> dF/dw of the fitted weights: grad_z J is linear in w, so each column is the
    unit difference grad_f(z, p with w_i + 1) - grad_f(z, p) (exact); g has no w."""
    import casadi as ca

    from cobot_analysis.models.ioc.single_level import weight_slots

    ocp, _, _, grad_f = _functions(shape)
    z, p = ca.MX.sym("z", ocp.n_vars), ca.MX.sym("p", ocp.n_params)
    base, slots = grad_f(z, p), weight_slots(ocp)
    cols = []
    for i in fitted:
        k = int(slots[i])
        cols.append(grad_f(z, ca.vertcat(p[:k], p[k] + 1.0, p[k + 1:])) - base)
    return ca.Function("kkt_w", [z, p], [ca.horzcat(*cols)])


@functools.lru_cache(maxsize=16)
def _calls(shape, fitted: tuple[int, ...]):
    """(kkt, kkt_w): ``_kkt_function`` and ``_weights_function`` called through their buffers."""
    from cobot_analysis.models.ioc.buffered import BufferedCall

    return BufferedCall(_kkt_function(shape)), BufferedCall(_weights_function(shape, fitted))


class HeldBranch:
    """One target's lower level at its held horizon: parameters, the KKT residual and matrix, the
    exact published D of a primal vector (``fit.distances``)."""

    def __init__(self, spec: IOCSpec, target: Target, horizon: int, fitted: list[int]):
        from cobot_analysis import conventions
        from cobot_analysis.distances import resample_arclength

        self.spec, self.t, self.T, self.fi = spec, target, int(horizon), list(fitted)
        self.shape = held_shape(spec, horizon)
        self.ocp = _functions(self.shape)[0]
        self.dt = conventions.PUBLISHED.oc_rule("table" if spec.model == "table" else "improved").dt
        s, g = target.start, target.goal
        self.origin = (s[0], s[1])  # the published problem is solved with the start moved to the origin
        self.start0, self.goal0 = (0.0, 0.0, s[2]), (g[0] - s[0], g[1] - s[1], g[2])
        self.nz = self.ocp.n_vars
        self.order = _ordering(self.shape)
        # the measured path resampled by arc length once (the published D resamples both paths): D is evaluated
        # 2k + 1 times per correction
        both = conventions.PUBLISHED.comparison.both_resampled
        self.measured = resample_arclength(target.x, target.y, len(target.x)) if both else None

    def p(self, w) -> np.ndarray:
        return self.ocp.parameters(self.start0, self.goal0, np.asarray(w, float), self.dt, n_active=self.T)

    def kkt(self, v, p):
        """F = [grad_z L; g] and K = dF/dv, permuted by ``self.order`` (``_kkt_function``; K is shared: factorise it
        before the next call)."""
        return _calls(self.shape, tuple(self.fi))[0](v[:self.nz], p, v[self.nz:])

    def F_w(self, v, w) -> np.ndarray:
        """dF/dw of the fitted weights (``_weights_function``)."""
        (Gw,) = _calls(self.shape, tuple(self.fi))[1](v[:self.nz], self.p(w))
        return np.vstack([Gw.reshape(self.nz, len(self.fi)), np.zeros((len(v) - self.nz, len(self.fi)))])

    def path(self, z):
        X = z[self.ocp._xi[:self.T + 1, :3]]
        return X[:, 0] + self.origin[0], X[:, 1] + self.origin[1], X[:, 2]

    def terms(self, z) -> dict:
        """The published distances of the path z (as ``fit.solve_target`` computes them) and D."""
        d = distances(self.t, *self.path(z), "published", measured_resampled=self.measured)
        d["D"] = d["d_xy"] + self.spec.angle_weight * d[f"d_{self.spec.angle}"]
        return d

    def D(self, z) -> float:
        return self.terms(z)["D"]

    def solution(self, z, w):
        """The branch's path as an ``OCPSolution`` in the world frame (a seed of ``fit.solve_target``)."""
        from cobot_analysis.models.oc.problem import OCPSolution

        X = z[self.ocp._xi[:self.T + 1, :6]].copy()
        X[:, 0] += self.origin[0]
        X[:, 1] += self.origin[1]
        return OCPSolution(X=X, U=z[self.ocp._ui[:self.T]].copy(), T=self.T * self.dt, cost=math.nan, success=True,
                           status="single-level", solver="newton", iterations=0, primal=z.copy())

    def newton(self, v, w, tol: float, max_newton: int = 12):
        """Newton's method on F(v; w) = 0 from v: (v, LU of K, max |F|), or None (diverging, singular K)."""
        p, v, last = self.p(w), np.array(v, float), math.inf
        for _ in range(max_newton):
            F, K = self.kkt(v, p)
            res = float(np.max(np.abs(F)))
            if not res < last:
                return None
            last = res
            try:
                lu = _Factor(K, self.order)
            except RuntimeError:
                return None
            if res <= tol:
                return v, lu, res
            v = v - lu.solve(F)
        return None

    def correct(self, v, w, tol: float, jump: bool) -> dict | None:
        """The KKT point near v = (z, lambda) at w (``newton``; ``jump``: if it fails, from the lower level solved
        at w warm from v's path), its sensitivity S = -K^-1 F_w, D and dD/dy (module docstring). v = z alone: lambda
        from 0 (F is linear in lambda: the first Newton step finds it)."""
        if len(v) == self.nz:
            v = np.concatenate([v, np.zeros(self.ocp.n_cons)])
        out = self.newton(v, w, tol)
        if out is None and jump:
            sol = self.ocp.solve(self.start0, self.goal0, np.asarray(w, float), self.dt, guess=np.asarray(v[:self.nz]),
                                 n_active=self.T, fallback=False)
            if sol.success:
                out = self.newton(np.concatenate([sol.primal, np.zeros(len(v) - self.nz)]), w, tol)
        if out is None:
            return None
        v, lu, res = out
        S = -lu.solve(self.F_w(v, w))
        z, h = v[:self.nz], GRADIENT_STEP
        dy = np.asarray(w, float)[self.fi] * math.log(10.0) * h  # dw of a step h in log10 w
        g = np.array([(self.D(z + S[:self.nz, j] * dy[j]) - self.D(z - S[:self.nz, j] * dy[j])) / (2 * h)
                      for j in range(len(self.fi))])
        return {"v": v, "S": S, "D": self.D(z), "g": g, "residual": res}


def correct_chunk(task) -> list:
    """Worker task (top-level, picklable): task = (spec, fitted, tol, jump, w, [(target, horizon, v), ...]);
    per item the corrected branch (``HeldBranch.correct``) or None."""
    spec, fitted, tol, jump, w, items = task
    return [HeldBranch(spec, t, T, fitted).correct(v, w, tol, jump) for t, T, v in items]


def fit_held_horizons(spec: IOCSpec, targets: list[Target], *, pool=None, radius: float = 0.3,
                      max_steps: int = 40, tol: float = 1e-8, xtol: float = 1e-3, gtol: float = 1e-5,
                      on_step=None, warn_kept: bool = True) -> IOCResult:
    """The single-level fit under the published convention (module docstring): the start weights' lower
    levels by the duration rule (``fit.reference_chunk``), their horizons held, the feasible-path
    trust-region steps in log10 of the fitted weights (the step of ``single_level.trust_region_step``,
    projected on the search box), then the lower levels re-solved at the fitted weights on the held
    horizons and the duration rule run again there; when the rule's D there is not below the start's, the start
    is kept (its weights, D and solutions; the message says so, and a warning with ``warn_kept``). Stops when an accepted step is below
    ``xtol`` or lowers D by less than ``spec.ftol`` (relative, as the bi-level search), the radius falls below
    ``xtol`` (a rejected step is not tried again: ``single_level.shrunk_radius``), the projected gradient below
    ``gtol``, or after ``max_steps`` steps.
    ``on_step(step, D at the step, least D)`` reports progress. ``pool``: one task per path, the longest
    first (the rule's horizons grow with the start-goal distance), so the workers end together."""
    from cobot_analysis.console import warn
    from cobot_analysis.models.ioc.single_level import box_step, check_spec, free_weights, run_chunks, shrunk_radius
    from cobot_analysis.parallel import InlineExecutor

    t0 = time.perf_counter()
    check_spec(spec, len(targets))
    names = names_for(spec.model)
    fi = [names.index(n) for n in spec.fitted]
    w = np.array(spec.start_weights, float)
    w[fi] = np.clip(w[fi], 10.0 ** LOG_BOUNDS[0], 10.0 ** LOG_BOUNDS[1])
    w_start = w.copy()
    pool, n = pool or InlineExecutor(), len(targets)
    parts = longest_first(targets)

    def run(fn, make_task) -> list:
        return run_chunks(pool, fn, parts, make_task, n)

    held = replace(spec, hold_duration=True)
    ref = run(reference_chunk, lambda p: (held, w, [targets[i] for i in p]))
    if any(sol is None for _, sol in ref):
        raise RuntimeError("single-level (published): a lower level did not converge at the start weights")
    start_terms = [d for d, _ in ref]
    horizons = [sol.U.shape[0] for _, sol in ref]

    def correct(w, V, jump: bool = False) -> list | None:
        out = run(correct_chunk, lambda p: (held, tuple(fi), tol, jump, w, [(targets[i], horizons[i], V[i]) for i in p]))
        return None if any(b is None for b in out) else out

    # the primal vectors (the origin-frame NLP's) alone: lambda from one Newton step (``HeldBranch.correct``)
    branches = correct(w, [sol.primal for _, sol in ref])
    if branches is None:
        raise RuntimeError("single-level (published): a lower-level solution at the start weights is not a regular KKT point")
    timing = {"start": time.perf_counter() - t0}
    y = np.log10(w[fi])
    D = float(np.mean([b["D"] for b in branches]))
    g = np.mean([b["g"] for b in branches], axis=0)

    def at(y_new, base, jump=False):
        w_new = w.copy()
        w_new[fi] = 10.0 ** y_new
        dw = w_new[fi] - 10.0 ** y
        return w_new, correct(w_new, [b["v"] + b["S"] @ dw for b in base], jump=jump)

    # the first model Hessian: forward differences of the exact gradient over corrected branches
    H = np.zeros((len(fi), len(fi)))
    for j in range(len(fi)):
        yj = y.copy()
        yj[j] += HESSIAN_STEP if y[j] + HESSIAN_STEP <= LOG_BOUNDS[1] else -HESSIAN_STEP
        _, bj = at(yj, branches, jump=True)
        if bj is not None:
            H[:, j] = (np.mean([b["g"] for b in bj], axis=0) - g) / (yj[j] - y[j])
    H = 0.5 * (H + H.T)
    steps = accepted = fails = 0
    while steps < max_steps and radius >= xtol:
        free = free_weights(g, y)
        if not free.any() or np.linalg.norm(g[free]) < gtol:
            break
        s = box_step(g, H, y, radius)
        pred = -(g @ s + 0.5 * s @ H @ s)
        steps += 1
        new, D_new = None, math.inf
        if pred > 0:  # else rejected whatever the corrected paths give (a step projected onto the box): not corrected
            w_new, new = at(y + s, branches, jump=True)
            D_new = float(np.mean([b["D"] for b in new])) if new is not None else math.inf
            fails += new is None
        if on_step:
            on_step(steps, D_new, min(D, D_new))
        if new is not None and D - D_new >= 0.1 * pred:
            accepted += 1
            g_new = np.mean([b["g"] for b in new], axis=0)
            H = _damped_bfgs(H, s, g_new - g)
            if D - D_new >= 0.75 * pred and np.linalg.norm(s) >= 0.99 * radius:
                radius = min(2 * radius, 1.0)
            flat = 2 * (D - D_new) <= spec.ftol * (D + D_new)  # the bi-level search's relative tolerance
            w, y, D, g, branches = w_new, y + s, D_new, g_new, new
            if np.linalg.norm(s) < xtol or flat:
                break
        else:  # from the same point the same step would be rejected again: not tried again
            radius = shrunk_radius(lambda r: box_step(g, H, y, r), s, radius, xtol)
    timing["steps"] = time.perf_counter() - t0 - timing["start"]
    # as the bi-level fit: the lower levels re-solved at the fitted weights on the held horizons (warm from the
    # branches' paths), then the duration rule again there as a check of the held horizons (``fit.rule_check_chunk``)
    seeds = run(_seed_chunk, lambda p: (held, tuple(fi), w, [(targets[i], horizons[i], branches[i]["v"]) for i in p]))
    resolved = run(evaluate_chunk, lambda p: (held, w, [targets[i] for i in p], [seeds[i] for i in p]))
    held_terms = [d for d, _ in resolved]
    held_objective = float(np.mean([d["D"] for d in held_terms]))
    ruled = run(rule_check_chunk, lambda p: (spec, w, [(targets[i], resolved[i][1]) for i in p]))
    terms, solutions = [d for d, _ in ruled], [sol for _, sol in ruled]
    changed = sum(1 for a, b in zip(held_terms, terms) if a["success"] and b["success"] and abs(a["T"] - b["T"]) > 1e-9)
    timing["resolve"] = time.perf_counter() - t0 - timing["start"] - timing["steps"]
    residual = float(max(b["residual"] for b in branches))
    objective, start_objective = float(np.mean([d["D"] for d in terms])), float(np.mean([d["D"] for d in start_terms]))
    message = (f"single-level (published, held horizons): {accepted} of {steps} feasible-path steps accepted"
               f"{f', {fails} Newton corrections failed' if fails else ''}; D on the branches {D:.4f}, max |KKT| "
               f"{residual:.1e}; {time.perf_counter() - t0:.1f} s (start {timing['start']:.1f}, steps {timing['steps']:.1f}, "
               f"re-solves {timing['resolve']:.1f})")
    if not objective < start_objective:  # the re-solves left the branches (another least-cost lower level, another
        # horizon by the rule): the fit never reports weights that fit worse than its start, it keeps the start
        if warn_kept:
            warn(f"single-level IOC (published): D {objective:.4f} by the duration rule at the fitted weights against "
                 f"{start_objective:.4f} at the start: the start weights are kept, not a fit to report (use --method bilevel)")
        message += f"; the rule's D at the fitted weights {objective:.4f}, not below the start's: the start's weights are kept"
        w, objective, held_objective, changed = w_start, start_objective, start_objective, 0
        terms, solutions = start_terms, [sol for _, sol in ref]
    return IOCResult(spec=spec, weights=dict(zip(names, map(float, w))), objective=objective,
                     start_objective=start_objective, evaluations=0, iterations=steps,
                     failed=sum(not d["success"] for d in terms), per_target=terms, message=message,
                     held_objective=held_objective, horizons_changed=changed, solutions=solutions)


def continued_from(spec: IOCSpec, targets: list[Target], weights: dict[str, float], *, pool=None,
                   max_steps: int = 40) -> dict:
    """The single-level steps under the published convention (``fit_held_horizons``)
    started at another fit's ``weights`` (the bi-level fit's end) instead of the spec's start. Its start D is the
    other fit's own D: the duration rule from the authors' guess solves each lower level the same way in both
    fits (a continuous lower level keeps the least cost of candidates that differ between fits:
    ``single_level.cross_check`` compares those). A D below it says the other fit stopped short of a minimum of D;
    when the steps find none lower, the result keeps ``weights``. Returns {"objective", "start_objective" (D at
    ``weights``), "weights", "seconds", "message"}; where the steps cannot start there (a lower level that does not
    converge at ``weights``, or is no regular KKT point), NaN D and the reason in "message": a check beside the fit,
    not a reason to lose it."""
    from cobot_analysis.models.presets import weights_vector

    if spec.convention != "published":
        raise ValueError("continued_from is the published convention's; continuous: cross_check")
    t0 = time.perf_counter()
    start = replace(spec, start_weights=tuple(map(float, weights_vector(weights, spec.model))))
    try:
        r = fit_held_horizons(start, targets, pool=pool, max_steps=max_steps, warn_kept=False)
    except RuntimeError as exc:
        return {"objective": math.nan, "start_objective": math.nan, "weights": dict(weights),
                "seconds": time.perf_counter() - t0, "message": f"not run: {exc}"}
    return {"objective": float(r.objective), "start_objective": float(r.start_objective),
            "weights": {k: float(v) for k, v in r.weights.items()}, "seconds": time.perf_counter() - t0, "message": r.message}


def _seed_chunk(task) -> list:
    """Worker task: the branches' paths as world-frame ``OCPSolution`` seeds (``HeldBranch.solution``)."""
    spec, fitted, w, items = task
    out = []
    for t, T, v in items:
        b = HeldBranch(spec, t, T, fitted)
        out.append(b.solution(v[:b.nz], w))
    return out


def _damped_bfgs(H: np.ndarray, s: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Powell's damped BFGS update of H with the step s and gradient change r (H stays positive definite
    when it is: r is moved towards H s until s'r >= 0.2 s'Hs)."""
    Hs = H @ s
    sHs = float(s @ Hs)
    if sHs <= 0:
        return H
    sr = float(s @ r)
    theta = 1.0 if sr >= 0.2 * sHs else 0.8 * sHs / (sHs - sr)
    r = theta * r + (1 - theta) * Hs
    return H - np.outer(Hs, Hs) / sHs + np.outer(r, r) / float(s @ r)
